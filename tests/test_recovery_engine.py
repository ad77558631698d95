"""The episode engine: a `RecoveryTask` works on the backend it is handed and never closes it; tasks import no simulator."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from frbench.backends import make_backend
from frbench.robots import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.tasks.recovery import SETTLE_STEPS, RecoveryTask, open_backend, settle_params
from frbench.terrains import make_terrain


def _rollout(task, starts, steps=10):
    obs = [task.reset(starts)]
    for k in range(steps):
        obs.append(task.step(np.tile(task.default_pose, (task.num_envs, 1)) + 0.05 * k))
    return obs


def test_the_task_runs_on_the_backend_it_is_given_and_leaves_closing_it_to_its_builder():
    spec, terrain = get_robot("go2"), make_terrain("stairs", 5, 0)
    starts = draw_starts(spec, terrain, "stairs", 5, 0, range(2))
    closed = []
    with open_backend("mujoco", spec, 2, terrain) as physics, open_backend("mujoco", spec, 2, terrain) as again:
        free = physics.close
        physics.close = lambda: (closed.append("closed"), free())  # counts, then frees the simulator
        first, second = RecoveryTask(spec, physics, terrain, 2), RecoveryTask(spec, again, terrain, 2)
        assert first.backend is physics and not hasattr(first, "close")
        for a, b in zip(_rollout(first, starts), _rollout(second, starts)):
            for key in a:
                np.testing.assert_array_equal(a[key], b[key])
        np.testing.assert_array_equal(first.metrics.energy, second.metrics.energy)
        assert first.t == second.t == 10 and first.metrics.energy.min() > 0.0
        assert first.signals.height.shape == (2,) and first.alive.all()
        assert closed == []  # ten steps and a reset: the task never closed its physics
    assert closed == ["closed"]  # the builder (open_backend) did, once
    with pytest.raises(TypeError, match="expected a built backend"):
        RecoveryTask(spec, "mujoco", terrain, 2)


def test_a_restart_moves_displacement_to_the_new_start_and_a_custom_ground_is_read():
    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    starts = draw_starts(spec, terrain, "flat", 1, 0, range(2))
    task = RecoveryTask(spec, make_backend("mujoco", spec, 2, terrain=terrain), terrain, 2,
                        ground_height=lambda xy: np.full(len(xy), -1.0),
                        track_metrics=False)
    try:
        task.reset(starts, settle_steps=2)
        assert task.metrics is None
        moved = task.state.take([1])
        moved.base_pos = moved.base_pos + np.array([[1.0, 2.0, 0.0]])
        task.restart(np.array([1]), moved)
        np.testing.assert_allclose(task.start_xy[1], moved.base_pos[0, :2])
        task.step(task.state.q)
        np.testing.assert_allclose(task.signals.height, task.state.base_pos[:, 2] + 1.0)  # ground at -1 m
    finally:
        task.backend.close()


def test_the_settle_holds_the_joints_on_scaled_gains_without_motor_friction():
    from frbench.backends.base import PhysicsParams

    spec = get_robot("go2")
    params = PhysicsParams.nominal(spec, 2)
    params.motor_friction = np.ones((2, spec.n_joints))
    soft = settle_params(params)
    np.testing.assert_array_equal(soft.kp, params.kp * 0.3)
    np.testing.assert_array_equal(soft.kd, params.kd * 0.3)
    assert soft.motor_friction is None and SETTLE_STEPS == 50


def test_the_tasks_import_no_simulator():
    code = ("import sys; import frbench.tasks.recovery, frbench.tasks.initial_states; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('mujoco', 'pybullet')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
