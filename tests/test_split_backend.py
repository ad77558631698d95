"""The ``mujoco+pybullet`` split batch: each part simulates exactly what its backend does alone."""

from __future__ import annotations

import json

import numpy as np
import pytest

from frbench.backends import make_backend
from frbench.backends.base import PhysicsParams, RobotState
from frbench.backends.split import SplitBackend, split_sizes
from frbench.errors import UnknownNameError
from frbench.robots import get_robot


def _fallen(spec, n: int) -> RobotState:
    """n robots dropped from 0.3-0.5 m, tilted differently, joints at the default pose (all differ)."""
    pos = np.column_stack([np.zeros(n), np.zeros(n), np.linspace(0.3, 0.5, n)])
    angles = np.linspace(0.2, 1.2, n)
    quat = np.column_stack([np.cos(angles / 2), np.sin(angles / 2), np.zeros(n), np.zeros(n)])
    return RobotState.at_rest(pos, quat, np.tile(spec.default_pose, (n, 1)))


def test_split_sizes_put_the_odd_simulation_in_the_first_part():
    assert split_sizes(5) == [3, 2]
    assert split_sizes(128) == [64, 64]
    assert split_sizes(2) == [1, 1]
    with pytest.raises(ValueError, match="at least 2 simulations"):
        split_sizes(1)


def test_each_part_of_the_split_matches_its_backend_run_alone():
    spec = get_robot("go2")
    state = _fallen(spec, 3)
    split = make_backend("mujoco+pybullet", spec, 3)
    assert isinstance(split, SplitBackend) and [p.name for p in split.parts] == ["mujoco", "pybullet"]
    alone = [make_backend("mujoco", spec, 2), make_backend("pybullet", spec, 1)]
    # reset with ids out of order: rows follow ids, each routed to its part
    split.reset(np.array([2, 0, 1]), state.take([2, 0, 1]))
    alone[0].reset(np.arange(2), state.take([0, 1]))
    alone[1].reset(np.arange(1), state.take([2]))
    params = PhysicsParams.nominal(spec, 3, friction=0.8)
    params.payload = np.array([0.0, 1.5, 3.0])
    split.set_params(params)
    alone[0].set_params(PhysicsParams(params.kp[:2], params.kd[:2], params.motor_strength[:2], params.friction[:2],
                                      params.payload[:2]))
    alone[1].set_params(PhysicsParams(params.kp[2:], params.kd[2:], params.motor_strength[2:], params.friction[2:],
                                      params.payload[2:]))
    force = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 30.0], [5.0, 0.0, 60.0]])
    split.set_base_force(force)
    alone[0].set_base_force(force[:2])
    alone[1].set_base_force(force[2:])
    targets = np.tile(spec.default_pose, (3, 1)) + 0.1
    for _ in range(15):
        split.step(targets)
        alone[0].step(targets[:2])
        alone[1].step(targets[2:])
    got, want = split.state(), [b.state() for b in alone]
    for name in ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd"):
        np.testing.assert_array_equal(getattr(got, name), np.concatenate([getattr(w, name) for w in want]))
    contacts, wanted = split.contacts(), [b.contacts() for b in alone]
    np.testing.assert_array_equal(contacts.link_force, np.concatenate([c.link_force for c in wanted]))
    np.testing.assert_array_equal(contacts.foot_contact, np.concatenate([c.foot_contact for c in wanted]))
    mass, com = split.mass_properties()
    np.testing.assert_allclose(mass, np.concatenate([b.mass_properties()[0] for b in alone]))
    assert mass[2] - mass[0] == pytest.approx(3.0)  # the payload reached the PyBullet part
    assert com.shape == (3, 3) and split.diverged.tolist() == [False, False, False]
    assert got.base_pos[1, 2] != got.base_pos[0, 2]  # the parts' robots really moved differently
    with pytest.raises(ValueError, match="joint_targets must have 3 rows"):
        split.step(targets[:2])
    with pytest.raises(ValueError, match=r"force must have shape \(3, 3\)"):
        split.set_base_force(force[:2])
    with pytest.raises(IndexError, match=r"ids must lie in \[0, 3\)"):
        split.reset(np.array([3]), state.take([0]))
    for b in (split, *alone):
        b.close()


def test_an_unknown_backend_names_the_split_among_the_choices():
    with pytest.raises(UnknownNameError, match=r"known: mujoco, mujoco\+pybullet, mujoco-warp, physx, pybullet"):
        make_backend("mujoco+bullet", get_robot("go2"), 2)


def test_a_mujoco_run_can_continue_in_both_simulators_as_a_stage(tmp_path):
    from frbench.training.env import TrainEnvConfig
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    TrainingRun(tmp_path / "run", "ppo", cfg, total_steps=4 * 24, checkpoint_every=1).train(progress_bar=False)
    staged = TrainingRun(tmp_path / "run", total_steps=4 * 24 * 2, resume=True, checkpoint_every=1,
                         command="frbench train --resume run --backend mujoco+pybullet",
                         backend_stage="mujoco+pybullet")
    assert isinstance(staged.env.backend, SplitBackend)
    assert [p.num_envs for p in staged.env.backend.parts] == [2, 2]
    staged.train(progress_bar=False)
    assert staged.env_steps == 4 * 24 * 2
    logged = json.loads((tmp_path / "run" / "progress.json").read_text())
    assert "success_in_mujoco" not in logged[0]  # the MuJoCo-only iterations
    assert 0.0 <= logged[-1]["success_in_mujoco"] <= 1.0 and 0.0 <= logged[-1]["success_in_pybullet"] <= 1.0
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["env"]["backend"] == "mujoco+pybullet"
    assert config["stages"] == [{"from_env_steps": 96, "weights": {}, "backend": "mujoco+pybullet",
                                 "command": "frbench train --resume run --backend mujoco+pybullet"}]
    again = TrainingRun(tmp_path / "run", resume=True, backend_stage="mujoco+pybullet")  # same backend: no new stage
    assert isinstance(again.env.backend, SplitBackend)
    assert len(json.loads((tmp_path / "run" / "config.json").read_text())["stages"]) == 1


def test_the_train_command_refuses_an_unknown_backend_before_writing_anything(tmp_path, capsys):
    from frbench.cli import main

    assert main(["train", "--robots", "g1", "--backend", "mujoco+bullet", "--out", str(tmp_path / "bad")]) == 2
    assert "unknown backend 'mujoco+bullet'" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_a_runs_policy_and_zero_actions_are_scored_in_its_training_env_per_simulator(tmp_path, capsys):
    from frbench.analysis.training_env import training_env_success
    from frbench.cli import main
    from frbench.errors import FrbenchError
    from frbench.training.env import TrainEnvConfig
    from frbench.training.run import TrainingRun

    cfg = TrainEnvConfig(num_envs=4, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat",))
    TrainingRun(tmp_path / "run", "ppo", cfg, total_steps=4 * 24, checkpoint_every=1).train(progress_bar=False)
    split = training_env_success(tmp_path / "run", 2, backend="mujoco+pybullet")
    assert set(split) == {"success_all", "success_flat", "success_in_mujoco", "success_in_pybullet"}
    assert all(0.0 <= v <= 1.0 for v in split.values())
    # deterministic: same seed, same numbers; the run's own backend has no per-simulator rates
    assert training_env_success(tmp_path / "run" / "policy.pt", 2, backend="mujoco+pybullet") == split
    assert set(training_env_success(tmp_path / "run", 1, zero=True)) == {"success_all", "success_flat"}
    with pytest.raises(FrbenchError, match="no training run's policy.pt"):
        training_env_success(tmp_path / "nothing", 1)
    assert main(["analyze-training-env", "--policy", str(tmp_path / "run"), "--episodes", "1", "--envs", "2"]) == 0
    out = capsys.readouterr().out
    assert "zero actions" in out and "success_flat" in out
