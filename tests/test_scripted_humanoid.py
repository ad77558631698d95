"""The built-in ``scripted-humanoid`` getting-up controller: poses, phase logic, and one real episode."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.policies.registry import load_policy
from frbench.policies.scripted_humanoid import HOLD, LIE, PUSH_A, ROLL, HumanoidScriptedPolicy
from frbench.robots import get_robot
from tests.test_scripted import _obs

UPRIGHT = (0.0, 0.0, -1.0)
PRONE = (1.0, 0.0, 0.0)  # face down: gravity along the body's front (+x)
SUPINE = (-1.0, 0.0, 0.0)
LEFT_SIDE = (0.0, 1.0, 0.0)
RIGHT_SIDE = (0.0, -1.0, 0.0)


def test_registered_and_supports_the_g1_only():
    policy = load_policy("scripted-humanoid")
    assert isinstance(policy, HumanoidScriptedPolicy)
    assert policy.name == "scripted-humanoid" and policy.checkpoint is None
    assert policy.supports(get_robot("g1"))
    assert not policy.supports(get_robot("go2"))


def test_key_poses_stay_within_the_joint_limits():
    spec = get_robot("g1")
    lower, upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    policy = HumanoidScriptedPolicy()
    policy.reset(spec, 1)
    poses = dict(policy.key_poses())
    poses["roll_left"], poses["roll_right"] = policy.roll_pose(1), policy.roll_pose(-1)
    for name, q in poses.items():
        assert q.shape == (spec.n_joints,), name
        assert (q >= lower).all() and (q <= upper).all(), name


def test_actions_finite_right_shape_smooth_and_within_limits():
    spec = get_robot("g1")
    lower, upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    rng = np.random.default_rng(0)
    sequences = [
        [PRONE] * 250,
        [SUPINE] * 60 + [LEFT_SIDE] * 30 + [PRONE] * 160,
        [RIGHT_SIDE] * 250,
        [UPRIGHT] * 250,
        [PRONE] * 150 + [SUPINE] * 100,  # falls over while getting up: starts again
    ]
    n = len(sequences)
    policy = HumanoidScriptedPolicy()
    policy.reset(spec, n)
    q = rng.uniform(lower, upper, size=(n, spec.n_joints))
    previous, visited = None, set()
    for t in range(250):
        targets = policy.act(_obs(spec, [seq[t] for seq in sequences], q=q))
        assert targets.shape == (n, spec.n_joints)
        assert np.isfinite(targets).all()
        assert (targets >= lower - 1e-9).all() and (targets <= upper + 1e-9).all()
        if previous is not None:
            assert np.abs(targets - previous).max() < 0.5
        previous, q = targets, targets
        visited.update(policy.phase.tolist())
    assert {LIE, ROLL, PUSH_A, HOLD} <= visited


def test_acts_on_gravity_and_joint_angles_alone():
    # frbench.training.demo_starts drives the controller with just these two keys
    spec = get_robot("g1")
    policy = HumanoidScriptedPolicy()
    policy.reset(spec, 2)
    obs = {"projected_gravity": np.array([PRONE, SUPINE]), "joint_pos": np.zeros((2, spec.n_joints))}
    for _ in range(20):
        targets = policy.act(obs)
    assert targets.shape == (2, spec.n_joints) and np.isfinite(targets).all()


def test_phase_choice_from_projected_gravity():
    spec = get_robot("g1")
    policy = HumanoidScriptedPolicy()
    policy.reset(spec, 4)
    for _ in range(30):
        policy.act(_obs(spec, [PRONE, SUPINE, LEFT_SIDE, RIGHT_SIDE]))
    assert policy.phase[0] not in (LIE, ROLL)  # prone: pushing up
    assert list(policy.phase[1:]) == [ROLL, ROLL, ROLL]
    assert policy.direction[2] == 1 and policy.direction[3] == -1  # rolls on over the lower side


def test_prone_episode_in_mujoco_through_the_evaluator():
    from frbench.evaluation.runner import Cell, run_cell

    # seed 1, episode 0 of g1/flat/level 1 is a prone start
    (record,) = run_cell(Cell("g1", "mujoco", "flat", 1, 1, 1), "scripted-humanoid")
    assert record["initial_pose"] == "prone"
    assert not record["diverged"]
    assert record["success"] is PRONE_EPISODE_SUCCESS


#: The measured outcome of the episode above: the controller pushes up onto hands and knees but does not
#: yet get onto its feet (see the policy's module docstring). Flip this when it does.
PRONE_EPISODE_SUCCESS = False


@pytest.mark.slow
def test_prone_and_supine_episodes_in_mujoco():
    from frbench.evaluation.runner import Cell, run_cell

    records = run_cell(Cell("g1", "mujoco", "flat", 1, 0, 8), "scripted-humanoid")
    assert {r["initial_pose"] for r in records} >= {"prone", "supine"}
    assert all(not r["diverged"] for r in records)
