"""Episodes begun at recorded states (`RecordedStarts`, `RecoveryTask.begin`) through the episode runner: t = 0 is
the recorded state itself (velocities included, no settle), the previous action the one given, the success test
and the metrics fresh."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.backends.base import RobotState
from frbench.evaluation.episodes import run_episodes
from frbench.policies.zero import ZeroPolicy
from frbench.robots import get_robot
from frbench.tasks.initial_states import RecordedStarts, draw_starts
from frbench.tasks.recovery import RecoveryTask, open_backend
from frbench.terrains import make_terrain

FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")


def _recorded(backend: str, spec, terrain, steps: int = 6) -> tuple[RobotState, np.ndarray]:
    """(state, targets) of two go2 episodes ``steps`` control steps after their settled fallen starts."""
    seen = {}

    def record(task, targets):
        seen["state"], seen["targets"] = task.state.copy(), targets.copy()

    run_episodes(spec, backend, terrain, draw_starts(spec, terrain, "flat", 1, 0, range(2)), ZeroPolicy(),
                 steps=steps, on_step=record)
    return seen["state"], seen["targets"]


@pytest.mark.parametrize("backend", ["mujoco", "pybullet"])
def test_runner_begins_episodes_at_the_recorded_states(backend):
    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    state, targets = _recorded(backend, spec, terrain)
    assert np.abs(state.qd).max() > 0.05 and np.abs(state.base_linvel).max() > 1e-3  # moving: velocities matter
    previous = targets + 0.01
    first = {}

    def on_reset(task):
        first.update(obs=task.observation(), state=task.state.copy(), t=task.t, success=task.success,
                     energy=task.metrics.energy.copy(), settle_diverged=task.settle_diverged.copy(),
                     start_xy=task.start_xy.copy(), kinds=list(task.starts.kinds))

    starts = RecordedStarts(state, previous)
    task = run_episodes(spec, backend, terrain, starts, ZeroPolicy(), steps=3, on_reset=on_reset)
    for name in FIELDS:  # the simulator holds the recorded state at t = 0 (no settle moved it)
        np.testing.assert_allclose(getattr(first["state"], name), getattr(state, name), rtol=0, atol=1e-6,
                                   err_msg=name)
    obs = first["obs"]
    np.testing.assert_array_equal(obs["previous_action"], previous)
    np.testing.assert_array_equal(obs["joint_pos"], first["state"].q)
    np.testing.assert_allclose(obs["joint_vel"], state.qd, rtol=0, atol=1e-6)
    np.testing.assert_allclose(obs["base_angvel"], state.base_angvel, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(first["start_xy"], first["state"].base_pos[:, :2])
    assert first["t"] == 0 and first["kinds"] == ["recorded", "recorded"]
    assert not first["settle_diverged"].any()
    assert not first["success"].success.any() and np.isnan(first["success"].time_to_recover).all()
    np.testing.assert_array_equal(first["energy"], np.zeros(2))
    assert task.t == 3 and task.metrics.energy.min() > 0.0  # then the episodes ran from there


def test_begin_starts_fresh_episodes_on_a_task_that_ran_one():
    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    state, _ = _recorded("mujoco", spec, terrain, steps=4)
    with open_backend("mujoco", spec, 2, terrain) as physics:
        task = RecoveryTask(spec, physics, terrain, 2)
        task.reset(draw_starts(spec, terrain, "flat", 1, 1, range(2)))
        for _ in range(5):
            task.step(np.tile(task.default_pose, (2, 1)))
        assert task.t == 5 and task.metrics.energy.min() > 0.0
        obs = task.begin(RecordedStarts(state))  # no previous action given: the placed joint angles
        np.testing.assert_array_equal(obs["previous_action"], task.state.q)
        np.testing.assert_allclose(task.state.q, state.q, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(task.metrics.energy, np.zeros(2))
        assert task.t == 0 and not task.success.success.any() and np.isnan(task.success.time_to_recover).all()
        np.testing.assert_array_equal(task.params.kp, task.nominal.kp)
        with pytest.raises(ValueError, match="3 recorded states for 2 episodes"):
            task.begin(RecordedStarts(RobotState(**{k: np.concatenate([getattr(state, k), getattr(state, k)[:1]])
                                                    for k in FIELDS})))
