"""The canonical joint frame of a robot (`frbench.robots.joint_frame`): signs, offsets and knees read from the
kinematics, the maps in both directions, and the robots that have none."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.robots import get_robot
from frbench.robots.joint_frame import JointFrameError, joint_frame
from frbench.tasks.protocol import STANDARD_ROBOTS, unseen_quadrupeds


@pytest.mark.parametrize("name", STANDARD_ROBOTS + ("a1", "b1", "laikago"))
def test_training_robots_and_unitree_files_have_the_identity_frame(name):
    frame = joint_frame(get_robot(name))
    assert frame.is_identity and frame.knees == ("backward",) * 4


def test_solo12_and_mini_cheetah_flip_thigh_and_calf():
    for name in ("solo12", "mini_cheetah"):
        frame = joint_frame(get_robot(name))
        np.testing.assert_array_equal(np.reshape(frame.sign, (4, 3))[:, 1:], -1.0)
        assert not any(frame.offset)
    assert joint_frame(get_robot("mini_cheetah")).knees == ("backward",) * 4
    assert not joint_frame(get_robot("mini_cheetah")).turned


def test_a_robot_whose_four_knees_point_forward_is_turned_around():
    """Solo12 as frbench stands it: seen from behind, canonical FL is the robot's RR (and FR its RL), every hip,
    thigh and calf turns the other way, and the body's x and y flip; without turning, each leg is mirrored."""
    spec = get_robot("solo12")
    frame, mirrored = joint_frame(spec), joint_frame(spec, turn=False)
    assert frame.turned and frame.knees == ("forward",) * 4 and not mirrored.turned
    assert frame.order == (9, 10, 11, 6, 7, 8, 3, 4, 5, 0, 1, 2)
    np.testing.assert_array_equal(frame.sign, [-1.0, -1.0, -1.0] * 4)
    np.testing.assert_array_equal(mirrored.sign, [1.0, -1.0, -1.0] * 4)
    q = np.random.default_rng(3).uniform(spec.joint_lower, spec.joint_upper, size=(4, 12))
    np.testing.assert_array_equal(frame.to_canonical(q)[:, :3], -q[:, 9:12])
    np.testing.assert_allclose(frame.to_joints(frame.to_canonical(q)), q, atol=1e-12)
    # the canonical default pose: the hind legs' pose, hips mirrored left-right
    default = np.reshape(frame.canonical_spec(spec).default_pose, (4, 3))
    np.testing.assert_allclose(default[0], -np.asarray(spec.default_pose[9:12]))
    assert frame.canonical_spec(spec).joint_names[:3] == spec.joint_names[9:12]
    obs = {"projected_gravity": np.array([[0.3, -0.4, -0.866]]), "base_angvel": np.array([[1.0, 2.0, 3.0]])}
    mapped = frame.observation(obs)
    np.testing.assert_array_equal(mapped["projected_gravity"], [[-0.3, 0.4, -0.866]])
    np.testing.assert_array_equal(mapped["base_angvel"], [[-1.0, -2.0, 3.0]])


def test_spirit40_folds_its_legs_at_zero_and_turns_its_thighs_the_other_way():
    frame = joint_frame(get_robot("spirit40"))
    np.testing.assert_allclose(frame.sign[:3], [1, -1, 1])
    np.testing.assert_allclose(frame.offset[:3], [0.0, np.pi / 2, -np.pi], atol=1e-4)


def test_anymal_c_mirrors_its_forward_knees_and_its_shank_is_15_degrees_off():
    frame = joint_frame(get_robot("anymal_c"), turn=False)
    np.testing.assert_allclose(frame.sign[:3], [1, -1, -1])
    assert frame.offset[1] == 0.0 and frame.offset[2] == pytest.approx(0.2548, abs=1e-3)
    assert joint_frame(get_robot("anymal_c")).turned


def test_laikago_toe_files_bend_the_legs_at_zero():
    from frbench.robots.infer import spec_from_path
    from frbench.robots.paths import pybullet_data_file

    frame = joint_frame(spec_from_path(pybullet_data_file("laikago/laikago_toes.urdf")))
    np.testing.assert_allclose(frame.offset[:3], [0.0, 0.5989, -0.5112], atol=1e-4)


@pytest.mark.parametrize("name", unseen_quadrupeds())
def test_every_unseen_quadruped_stands_with_thighs_back_and_knees_bent_back_in_the_canonical_frame(name):
    """The default pose in canonical leg angles: thighs swung back (> 0.3 rad), knees bent backwards (< -0.6 rad);
    the maps invert each other exactly on random angles."""
    spec = get_robot(name)
    frame = joint_frame(spec)
    canonical = frame.canonical_spec(spec)
    pose = np.reshape(canonical.default_pose, (4, 3))
    assert (pose[:, 1] > 0.3).all() and (pose[:, 2] < -0.6).all(), pose
    assert (np.asarray(canonical.joint_lower) <= np.asarray(canonical.joint_upper)).all()
    q = np.random.default_rng(0).uniform(spec.joint_lower, spec.joint_upper, size=(5, 12))
    np.testing.assert_allclose(frame.to_joints(frame.to_canonical(q)), q, atol=1e-12)


def test_the_observation_and_targets_map_through_the_frame_and_identity_returns_its_input():
    spec = get_robot("solo12")
    frame = joint_frame(spec)
    rng = np.random.default_rng(1)
    obs = {key: rng.normal(size=(2, 12)) for key in ("joint_pos", "joint_vel", "previous_action")}
    obs.update(projected_gravity=rng.normal(size=(2, 3)), base_angvel=rng.normal(size=(2, 3)))
    mapped = frame.observation(obs)
    sign, order = np.asarray(frame.sign), list(frame.order)
    np.testing.assert_array_equal(mapped["joint_pos"], sign * obs["joint_pos"][:, order])
    np.testing.assert_array_equal(mapped["joint_vel"], sign * obs["joint_vel"][:, order])
    # the relative observation a learned policy reads: (c - c̊) = sign (q - q̊), in canonical order
    default = np.asarray(spec.default_pose)
    np.testing.assert_allclose(mapped["joint_pos"] - frame.canonical_spec(spec).default_pose,
                               sign * (obs["joint_pos"] - default)[:, order], atol=1e-12)
    np.testing.assert_allclose(frame.targets(frame.to_canonical(obs["previous_action"])), obs["previous_action"])
    identity = joint_frame(get_robot("go2"))
    assert identity.observation(obs) is obs and identity.canonical_spec(spec) is spec
    assert identity.targets(obs["joint_pos"]) is obs["joint_pos"]


def test_the_torch_path_gives_the_numpy_numbers():
    import torch

    frame = joint_frame(get_robot("anymal_b"))  # turned, with offsets
    assert frame.turned and any(frame.offset)
    q = np.random.default_rng(2).normal(size=(3, 12))
    np.testing.assert_array_equal(frame.to_canonical(torch.as_tensor(q)).numpy(), frame.to_canonical(q))
    np.testing.assert_array_equal(frame.to_joints(torch.as_tensor(q)).numpy(), frame.to_joints(q))
    np.testing.assert_array_equal(frame.body_vectors(torch.as_tensor(q[:, :3])).numpy(), frame.body_vectors(q[:, :3]))


def test_a_humanoid_has_no_frame_and_says_why():
    with pytest.raises(JointFrameError, match="humanoid policies use the robot's own joint frame"):
        joint_frame(get_robot("g1"))
