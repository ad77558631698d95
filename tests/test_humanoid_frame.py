"""The G1 joint frame of a humanoid (`frbench.robots.humanoid_frame`): which joint is which on iCub and Talos, signs
and offsets that make the limbs' geometry agree with the G1's, the identity on the G1, and the humanoid controllers
driving every built-in humanoid through it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from frbench.robots.humanoid_frame import G1_JOINTS, HumanoidFrameError, humanoid_frame, reference_spec
from frbench.robots.kinematics import link_poses
from frbench.robots.registry import get_robot
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.urdf_tree import parse_urdf


def _mapped(robot: str) -> dict[str, tuple[str, float, float]]:
    spec = get_robot(robot)
    frame = humanoid_frame(spec)
    return {name: (spec.joint_names[i], s, o) for name, i, s, o in zip(G1_JOINTS, frame.index, frame.sign, frame.offset)
            if i >= 0}


def test_the_g1_is_its_own_frame():
    g1 = get_robot("g1")
    frame = humanoid_frame(g1)
    assert frame.is_identity and frame.unmapped == () and frame.index == tuple(range(29))
    q = np.random.default_rng(0).uniform(-1, 1, (4, 29))
    assert np.array_equal(frame.to_g1(q, np.zeros(29)), q) and np.array_equal(frame.to_joints(q, np.zeros(29)), q)
    lower, upper = frame.g1_limits(g1, reference_spec())
    assert np.array_equal(lower, g1.joint_lower) and np.array_equal(upper, g1.joint_upper)


def test_icub_joints_by_structure_with_the_signs_of_its_axes():
    icub = _mapped("icub")
    assert len(icub) == 23 and set(G1_JOINTS) - set(icub) == {f"{s}_wrist_{j}_joint" for s in ("left", "right")
                                                              for j in ("roll", "pitch", "yaw")}
    # iCub turns hip pitch and knee about -y (its default pose has hip +0.31, knee -0.63), ankle pitch about +y
    assert icub["left_hip_pitch_joint"] == ("l_hip_pitch", -1.0, 0.0)
    assert icub["left_knee_joint"] == ("l_knee", -1.0, 0.0)
    assert icub["left_ankle_pitch_joint"] == ("l_ankle_pitch", 1.0, 0.0)
    assert icub["right_hip_roll_joint"][:2] == ("r_hip_roll", -1.0) and icub["left_hip_roll_joint"][:2] == ("l_hip_roll", 1.0)
    assert icub["waist_yaw_joint"][:2] == ("torso_yaw", -1.0) and icub["waist_pitch_joint"][:2] == ("torso_pitch", 1.0)
    assert icub["left_shoulder_yaw_joint"][0] == "l_shoulder_yaw" and icub["left_elbow_joint"][:2] == ("l_elbow", -1.0)
    # the G1's elbow is a right angle at zero, iCub's nearly straight (its file bends it 0.066 rad)
    assert icub["left_elbow_joint"][2] == pytest.approx(np.pi / 2 + 0.066, abs=0.002)
    default = humanoid_frame(get_robot("icub")).to_g1(np.asarray(get_robot("icub").default_pose), np.zeros(29))
    index = {n: i for i, n in enumerate(G1_JOINTS)}
    assert default[index["left_knee_joint"]] == pytest.approx(0.63, abs=0.01)  # bent as the G1's +0.3 is
    assert default[index["left_hip_pitch_joint"]] == pytest.approx(-0.31, abs=0.01)


def test_talos_lacks_a_shoulder_pitch_and_a_waist_roll():
    talos = _mapped("talos")
    frame = humanoid_frame(get_robot("talos"))
    assert set(frame.unmapped) == {"waist_roll_joint", "left_shoulder_pitch_joint", "right_shoulder_pitch_joint",
                                   *(f"{s}_wrist_{j}_joint" for s in ("left", "right") for j in ("roll", "pitch", "yaw"))}
    assert [talos[f"left_{j}_joint"][0] for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch",
                                                   "ankle_roll")] == [f"leg_left_{k}_joint" for k in range(1, 7)]
    assert talos["left_shoulder_yaw_joint"][0] == "arm_left_3_joint"  # the twist about the upper arm, not arm_left_1
    assert talos["left_elbow_joint"] == ("arm_left_4_joint", 1.0, pytest.approx(1.586, abs=0.002))
    # a joint no G1 joint names holds the robot's default; a G1 joint the robot lacks takes the given fill
    spec = get_robot("talos")
    q = frame.to_joints(np.zeros(29), np.asarray(spec.default_pose))
    head = spec.joint_names.index("head_1_joint")
    assert q[head] == spec.default_pose[head]
    assert frame.to_g1(q, np.full(29, 7.0))[G1_JOINTS.index("waist_roll_joint")] == 7.0


def _segment_angle(robot: str, q: dict, joints: tuple[str, str, str]) -> float:
    """Angle [rad] in the sagittal (x-z) plane between the segments a→b and b→c of three joints' positions at the
    joint angles ``q`` (the G1's hip and shoulder pitch joints sit beside their limbs' line, so not in 3-D)."""
    spec = get_robot(robot)
    tree = parse_urdf(sim_robot_file(spec).path)
    poses = link_poses(tree, q)
    a, b, c = ((poses[tree.joints[j].parent] @ tree.joints[j].origin)[:3, 3] for j in joints)
    u, v = (b - a)[[0, 2]], (c - b)[[0, 2]]
    return float(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))


@settings(max_examples=20, deadline=None)
@given(knee=st.floats(0.0, 2.0), elbow=st.floats(-0.2, 1.5))
def test_a_g1_knee_and_elbow_bend_each_robot_alike(knee, elbow):
    g1 = np.zeros(29)
    g1[G1_JOINTS.index("left_knee_joint")], g1[G1_JOINTS.index("left_elbow_joint")] = knee, elbow
    leg = {"g1": ("left_hip_pitch_joint", "left_knee_joint", "left_ankle_pitch_joint"),
           "icub": ("l_hip_pitch", "l_knee", "l_ankle_pitch"),
           "talos": ("leg_left_3_joint", "leg_left_4_joint", "leg_left_5_joint")}
    arm = {"g1": ("left_shoulder_pitch_joint", "left_elbow_joint", "left_wrist_yaw_joint"),
           "icub": ("l_shoulder_pitch", "l_elbow", "l_wrist_pitch"),
           "talos": ("arm_left_2_joint", "arm_left_4_joint", "arm_left_7_joint")}
    angles = {}
    for robot in ("g1", "icub", "talos"):
        spec = get_robot(robot)
        q = humanoid_frame(spec).to_joints(g1, np.zeros(spec.n_joints))
        named = dict(zip(spec.joint_names, q))
        angles[robot] = (_segment_angle(robot, named, leg[robot]), _segment_angle(robot, named, arm[robot]))
    for robot in ("icub", "talos"):
        assert angles[robot][0] == pytest.approx(angles["g1"][0], abs=2e-4)  # up to the files' rounding
        # the wrist joints that end the forearm are not where the frame's hand point is on every file: 6 mrad
        assert angles[robot][1] == pytest.approx(angles["g1"][1], abs=0.01)


def test_not_a_humanoid_or_no_legs_is_a_one_line_error():
    with pytest.raises(HumanoidFrameError, match=r"^robot 'go2' is a quadruped: the G1 joint frame maps humanoids$"):
        humanoid_frame(get_robot("go2"))
    g1 = get_robot("g1")
    legless = g1.replace(name="legless", foot_links=("pelvis", "torso_link"))
    with pytest.raises(HumanoidFrameError, match=r"^robot 'legless': no joint found for left_hip_pitch_joint"):
        humanoid_frame(legless)


def test_the_humanoid_controllers_drive_every_built_in_humanoid():
    from frbench.policies.registry import load_policy

    for name in ("scripted-humanoid", "keyframe-humanoid"):
        policy = load_policy(name)
        assert [r for r in ("g1", "icub", "talos", "go2") if policy.supports(get_robot(r))] == ["g1", "icub", "talos"]
        spec = get_robot("icub")
        policy.reset(spec, 2)
        q = np.tile(np.asarray(spec.default_pose), (2, 1))
        obs = {"projected_gravity": np.tile([1.0, 0.0, 0.0], (2, 1)), "joint_pos": q, "joint_vel": np.zeros_like(q),
               "base_angvel": np.zeros((2, 3))}
        targets = policy.act(obs)
        assert targets.shape == (2, 32)
        assert np.all(targets >= np.asarray(spec.joint_lower) - 1e-9) and np.all(targets <= np.asarray(spec.joint_upper) + 1e-9)


def test_frbench_spec_shows_a_humanoids_g1_frame(capsys):
    from frbench.cli import main

    assert main(["spec", "--robot", "talos"]) == 0
    out = capsys.readouterr().out
    assert "  left_elbow_joint           = +1 * arm_left_4_joint      +1.586 rad" in out
    assert "  left_shoulder_pitch_joint  -" in out
    assert main(["spec", "--robot", "go2"]) == 0 and "G1 joint frame" not in capsys.readouterr().out
