"""The built-in ``scripted`` recovery controller: poses, phase logic, and one real episode."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.policies.scripted import BELLY, FOLD, HOLD, RAMP_STEPS, ROLL_A, ROLL_B, STAND, TOPPLE, ScriptedPolicy
from frbench.robots import get_robot
from frbench.tasks.protocol import STANDARD_ROBOTS
from frbench.backends import make_backend

QUADRUPEDS = STANDARD_ROBOTS  # go2, go1, aliengo, spot_like, lite3_like

UPRIGHT = (0.0, 0.0, -1.0)
SUPINE = (0.0, 0.0, 1.0)
LEFT_SIDE = (0.0, 1.0, 0.0)
RIGHT_SIDE = (0.0, -1.0, 0.0)
NOSE_DOWN = (1.0, 0.0, 0.0)


def _obs(spec, gravity, q=None, n=None):
    """A hand-made observation: every environment sees ``gravity`` (one row or one per environment)."""
    g = np.atleast_2d(np.asarray(gravity, dtype=float))
    n = n or len(g)
    g = np.broadcast_to(g, (n, 3)).copy()
    q = np.tile(np.asarray(spec.default_pose, dtype=float), (n, 1)) if q is None else np.asarray(q, dtype=float)
    zeros = np.zeros((n, spec.n_joints))
    return {
        "base_angvel": np.zeros((n, 3)),
        "projected_gravity": g,
        "joint_pos": q,
        "joint_vel": zeros,
        "previous_action": np.tile(np.asarray(spec.default_pose, dtype=float), (n, 1)),
    }


def _run(policy, spec, gravity, steps, n=1, q=None):
    """Feed the same observation ``steps`` times; return the last targets."""
    targets = None
    for _ in range(steps):
        targets = policy.act(_obs(spec, gravity, q=q, n=n))
    return targets


def test_supports_quadrupeds_only():
    policy = ScriptedPolicy()
    assert policy.name == "scripted" and policy.checkpoint is None
    for name in QUADRUPEDS:
        assert policy.supports(get_robot(name))
    assert not policy.supports(get_robot("g1"))


@pytest.mark.parametrize("name", QUADRUPEDS)
def test_targets_have_the_right_shape_and_stay_within_limits(name):
    spec = get_robot(name)
    lower, upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    rng = np.random.default_rng(0)
    n = 6
    policy = ScriptedPolicy()
    policy.reset(spec, n)
    # Every environment starts from random joint angles and sees its own sequence of orientations,
    # which walks the machine through all its phases.
    q = rng.uniform(lower, upper, size=(n, spec.n_joints))
    sequences = [
        [SUPINE] * 60 + [LEFT_SIDE] * 40 + [UPRIGHT] * 120,
        [SUPINE] * 60 + [RIGHT_SIDE] * 40 + [UPRIGHT] * 120,
        [LEFT_SIDE] * 100 + [UPRIGHT] * 120,
        [UPRIGHT] * 220,
        [NOSE_DOWN] * 60 + [UPRIGHT] * 160,
        [(0.3, -0.5, 0.81)] * 220,
    ]
    previous, visited = None, set()
    for t in range(220):
        gravity = np.array([seq[t] for seq in sequences])
        targets = policy.act(_obs(spec, gravity, q=q))
        assert targets.shape == (n, spec.n_joints)
        assert np.isfinite(targets).all()
        assert (targets >= lower - 1e-9).all() and (targets <= upper + 1e-9).all()
        if previous is not None:  # smooth: no target jumps the PD could not track
            assert np.abs(targets - previous).max() < 0.5
        previous = targets
        q = targets  # pretend the joints track perfectly
        visited.update(policy.phase.tolist())
    assert visited == {FOLD, ROLL_A, ROLL_B, BELLY, STAND, HOLD, TOPPLE}
    # the upright environments end holding the default pose
    assert np.allclose(targets[3], spec.default_pose, atol=1e-6)


def test_phases_chosen_from_projected_gravity():
    spec = get_robot("go2")
    fold_steps = int(RAMP_STEPS[FOLD]) + 1

    supine = ScriptedPolicy()
    supine.reset(spec, 1)
    _run(supine, spec, SUPINE, fold_steps)
    assert supine.phase[0] == ROLL_A

    # on the back but tilted towards the left: roll on towards the left (d = +1), and vice versa
    for gy, direction in ((0.3, 1), (-0.3, -1)):
        policy = ScriptedPolicy()
        policy.reset(spec, 1)
        _run(policy, spec, (0.0, gy, np.sqrt(1 - gy * gy)), fold_steps)
        assert policy.phase[0] == ROLL_A and policy.direction[0] == direction

    on_side = ScriptedPolicy()
    on_side.reset(spec, 2)
    _run(on_side, spec, [LEFT_SIDE, RIGHT_SIDE], fold_steps, n=2)
    assert list(on_side.phase) == [ROLL_B, ROLL_B] and list(on_side.direction) == [1, -1]

    nose = ScriptedPolicy()
    nose.reset(spec, 1)
    _run(nose, spec, NOSE_DOWN, fold_steps)
    assert nose.phase[0] == TOPPLE

    upright = ScriptedPolicy()
    upright.reset(spec, 1)
    _run(upright, spec, UPRIGHT, fold_steps)
    assert upright.phase[0] == BELLY
    targets = _run(upright, spec, UPRIGHT, 100)
    assert upright.phase[0] in (STAND, HOLD)
    targets = _run(upright, spec, UPRIGHT, 50)
    assert upright.phase[0] == HOLD
    assert np.allclose(targets[0], spec.default_pose)

    # standing, then knocked onto the back: start over
    _run(upright, spec, SUPINE, 1)
    assert upright.phase[0] == FOLD


def test_roll_poses_follow_the_unitree_convention():
    spec = get_robot("go2")
    policy = ScriptedPolicy()
    policy.reset(spec, 1)
    hip, thigh = policy.hip, policy.thigh
    left = np.array([True, False, True, False])  # FL, FR, RL, RR
    # rolling the left side down: the right legs lever (thighs swung back past vertical), left hips inwards
    pose = policy.roll_pose(+1, 0)
    assert (pose[thigh][~left] > np.pi / 2).all()
    assert (pose[hip][left] < 0).all()
    # ... then the right legs abduct outwards (negative for right legs), the left ones too (positive)
    pose = policy.roll_pose(+1, 1)
    assert (pose[hip][~left] < 0).all() and (pose[hip][left] > 0).all()
    # mirrored for the other direction
    mirrored = policy.roll_pose(-1, 1)
    assert np.allclose(mirrored[hip][left], -pose[hip][~left])


def _starts(spec, kind, n, seed=0):
    """``n`` fallen starts of one kind, joints uniform within their limits (as the protocol draws them)."""
    from frbench.tasks.initial_states import DROP_HEIGHT, FallenStarts, fall_orientation, lowest_offset_and_reach

    rng = np.random.default_rng(seed)
    pos, quats, qs = [], [], []
    for _ in range(n):
        quat = fall_orientation(kind, spec.kind, rng.uniform(-np.pi, np.pi), rng)
        q = rng.uniform(spec.joint_lower, spec.joint_upper)
        lowest, _ = lowest_offset_and_reach(spec, quat, q)
        pos.append([0.0, 0.0, DROP_HEIGHT - lowest])
        quats.append(quat)
        qs.append(q)
    return FallenStarts(np.array(pos), np.array(quats), np.array(qs), [kind] * n)


def _episode(policy, spec, starts):
    from frbench.tasks.recovery import EPISODE_STEPS, RecoveryTask
    from frbench.terrains import make_terrain

    terrain, n = make_terrain("flat", 1, 0), len(starts.kinds)
    task = RecoveryTask(spec, make_backend("mujoco", spec, n, terrain=terrain), terrain, n)
    try:
        obs = task.reset(starts)
        policy.reset(spec, len(starts.kinds))
        for _ in range(EPISODE_STEPS):
            obs = task.step(policy.act(obs))
        return task.success.success.copy()
    finally:
        task.backend.close()


def test_go2_gets_up_from_its_back_in_mujoco():
    from frbench.policies.zero import ZeroPolicy

    spec = get_robot("go2")
    starts = _starts(spec, "supine", 4)
    success = _episode(ScriptedPolicy(), spec, starts)
    assert success.sum() >= 3, success
    # holding the default pose does not get a robot off its back
    assert _episode(ZeroPolicy(), spec, starts).sum() == 0


# --- quadrupeds given by path: joint zeros read from the kinematics ----------------------------------------------


def _by_path(source: str, relative: str):
    from frbench.robots.infer import spec_from_path
    from frbench.robots.paths import example_robot_data, pybullet_data_file

    return spec_from_path((pybullet_data_file if source == "pb" else example_robot_data)(relative))


@pytest.mark.parametrize("source,relative", [("pb", "quadruped/spirit40.urdf"), ("pb", "quadruped/vision60.urdf"),
                                             ("pb", "laikago/laikago_toes.urdf")])
def test_poses_of_robots_with_offset_zeros_are_the_canonical_ones(source, relative):
    """Whatever the file's joint zeros, the default pose reads as thighs swung back and knees bent back, and the
    folded pose as a deep fold; targets map back to the robot's own angles exactly."""
    spec = _by_path(source, relative)
    policy = ScriptedPolicy()
    policy.reset(spec, 1)
    assert (policy.default[policy.thigh] > 0.6).all() and (policy.default[policy.thigh] < 1.0).all()
    assert (policy.default[policy.calf] < -1.5).all() and (policy.default[policy.calf] > -1.8).all()
    assert (policy.fold[policy.calf] < -2.5).all()
    np.testing.assert_allclose(policy.to_joints(policy.default), spec.default_pose, atol=1e-9)
    q = np.random.default_rng(0).uniform(spec.joint_lower, spec.joint_upper)
    np.testing.assert_allclose(policy.to_joints(policy.to_canonical(q)), q, atol=1e-12)


@pytest.mark.parametrize("source,relative", [("pb", "quadruped/spirit40.urdf"), ("erd", "solo_description/robots/solo12.urdf")])
def test_robots_given_by_path_get_up_from_their_backs_in_mujoco(source, relative):
    """Spirit40 (legs folded at zero angles: 0 of 8 before its joint zeros were read) and Solo12 (its file's
    1000 N·m efforts on 2.5 kg diverged in both simulators before the effort cap)."""
    spec = _by_path(source, relative)
    success = _episode(ScriptedPolicy(), spec, _starts(spec, "supine", 4))
    assert success.sum() >= 3, success
