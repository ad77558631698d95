"""Corpora of bad sidecars and bad URDFs: every one refused with its one-line message pinned, exit status 2."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from frbench.cli import main
from frbench.errors import RobotFileError
from frbench.robots import get_robot

MISSING = "missing FL_thigh_joint, FL_calf_joint, FR_hip_joint, FR_thigh_joint, FR_calf_joint, RL_hip_joint, ... (11 in all)"
STEPS = "expected one of 0.005, 0.004, 0.0025, 0.002, 0.001 s (the 0.02 s control period in 4 to 20 equal steps)"
LEGS = 'FL = ["FL_hip_joint", "FL_thigh_joint", "FL_calf_joint"]\nFR = ["FR_hip_joint", "FR_thigh_joint", "FR_calf_joint"]\nRL = ["RL_hip_joint", "RL_thigh_joint", "RL_calf_joint"]\n'

#: (sidecar text, the message after "<sidecar>: ")
BAD_SIDECARS = [
    ('kp = "sixty"\n', "kp = 'sixty': expected a number > 0"),
    ("kp = -5.0\n", "kp = -5.0: expected a number > 0"),
    ("kd = nan\n", "kd = nan: expected a finite number"),
    ("kp = inf\n", "kp = inf: expected a finite number"),
    ("kp = 1e9\n", "kp = 1000000000.0: expected a number <= 100000"),
    ("physics_dt = 0\n", f"physics_dt = 0: {STEPS}"),
    ("physics_dt = 10\n", f"physics_dt = 10: {STEPS}"),
    ("physics_dt = 0.003\n", f"physics_dt = 0.003: {STEPS}"),
    ("physics_dt = true\n", f"physics_dt = true: {STEPS}"),
    ("[kp]\nFL_hip_joint = 50.0\n", f"kp = {{FL_hip_joint = 50.0}}: expected one number, or a table naming every actuated joint ({MISSING})"),
    ("[kd]\nnot_a_joint = 1.0\n", "kd.not_a_joint = 1.0: expected one of the file's moving joints (FL_hip_joint,"),
    ('[kp]\nFL_hip_joint = "x"\n', "kp.FL_hip_joint = 'x': expected a number > 0"),
    ("nominal_height = -1\n", "nominal_height = -1.0: expected a number > 0"),
    ("nominal_height = 100\n", "nominal_height = 100.0: expected a number <= 5"),
    ('name = "../../etc x"\n', "name = '../../etc x': expected 1-64 letters, digits, '_' or '-', starting with a letter or digit"),
    ("name = 5\n", "name = 5: expected 1-64 letters, digits, '_' or '-'"),
    ('kind = "hexapod"\n', "kind = 'hexapod': expected 'quadruped' or 'humanoid'"),
    ("legs = 5\n", "legs = 5: expected a table leg = [joint, ...]"),
    ("[legs]\n" + LEGS, "legs = {FL = ['FL_hip_joint', 'FL_thigh_joint', 'FL_calf_joint'], FR = "),
    ("[legs]\n" + LEGS + 'RR = ["RR_hip_joint", "RR_thigh_joint", "ghost"]\n', "legs.RR = ['RR_hip_joint', 'RR_thigh_joint', 'ghost']: expected moving joints of the file (no moving joint 'ghost';"),
    ("[legs]\n" + LEGS + 'RR = ["RR_hip_joint", "RR_thigh_joint"]\n', "legs.RR = ['RR_hip_joint', 'RR_thigh_joint']: expected 3 joint names: hip, thigh, calf"),
    ("[legs]\n" + LEGS + 'RR = ["RR_hip_joint", "RR_thigh_joint", "RL_calf_joint"]\n', "legs.RR = ['RR_hip_joint', 'RR_thigh_joint', 'RL_calf_joint']: expected each joint in one leg only ('RL_calf_joint' is named twice)"),
    ("[legs]\n" + LEGS + 'RR = ["RR_calf_joint", "RR_thigh_joint", "RR_hip_joint"]\n', "legs.RR = ['RR_calf_joint', 'RR_thigh_joint', 'RR_hip_joint']: expected joints in order from the body to the foot ('RR_calf_joint' is not above 'RR_thigh_joint')"),
    ("[legs]\nFL = 3\n", "legs.FL = 3: expected a list of joint names"),
    ('feet = ["nowhere", "FR_foot", "RL_foot", "RR_foot"]\n', "feet = ['nowhere', 'FR_foot', 'RL_foot', 'RR_foot']: expected links of the file (no link 'nowhere';"),
    ('feet = ["FL_foot"]\n', "feet = ['FL_foot']: expected 4 link names (FL, FR, RL, RR) for a quadruped"),
    ('feet = "FL_foot"\n', "feet = 'FL_foot': expected a list of distinct link names"),
    ('feet = ["FL_foot", "FL_foot", "RL_foot", "RR_foot"]\n', "feet = ['FL_foot', 'FL_foot', 'RL_foot', 'RR_foot']: expected a list of distinct link names"),
    ("[default_pose]\nghost_joint = 0.1\n", "default_pose.ghost_joint = 0.1: expected one of the file's moving joints"),
    ("[default_pose]\nFL_calf_joint = 10.0\n", "default_pose.FL_calf_joint = 10.0: expected an angle inside the joint's limits [-2.723, -0.838] rad"),
    ('[default_pose]\nFL_calf_joint = "bent"\n', "default_pose.FL_calf_joint = 'bent': expected a number"),
    ("default_pose = 3\n", "default_pose = 3: expected a table of joint = value"),
    ("[joint_limits]\nFL_calf_joint = [1.0, -1.0]\n", "joint_limits.FL_calf_joint = [1.0, -1.0]: expected [lower, upper] with lower < upper"),
    ("[joint_limits]\nFL_calf_joint = 1.0\n", "joint_limits.FL_calf_joint = 1.0: expected [lower, upper] in rad"),
    ("[joint_limits]\nFL_calf_joint = [-1.0, nan]\n", "joint_limits.FL_calf_joint = nan: expected a finite number"),
    ("effort = 0\n", "effort = 0.0: expected a number > 0"),
    ("[effort]\nFL_calf_joint = -3\n", "effort.FL_calf_joint = -3.0: expected a number > 0"),
    ("[effort]\nghost = 3\n", "effort.ghost = 3.0: expected one of the file's moving joints"),
    ("kpp = 3\n", "kpp = 3: expected a known key (name, kind, kp, kd, effort, nominal_height, physics_dt, feet, default_pose, joint_limits, legs)"),
    ("kp = [1, 2]\n", "kp = [1, 2]: expected a number > 0"),
]


def _robot(tmp_path: Path, text: str, name: str = "dog") -> Path:
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    return path


@pytest.mark.parametrize("sidecar, message", BAD_SIDECARS, ids=[f"sidecar{i}" for i in range(len(BAD_SIDECARS))])
def test_bad_sidecar_is_refused_with_its_message(tmp_path, quadruped_urdf_text, sidecar, message):
    path = _robot(tmp_path, quadruped_urdf_text)
    side = tmp_path / "dog.frbench.toml"
    side.write_text(sidecar)
    with pytest.raises(RobotFileError, match=re.escape(f"{side}: {message}")):
        get_robot(str(path))


def test_the_corpora_are_large_enough():
    assert len(BAD_SIDECARS) >= 25 and len(BAD_URDFS) >= 20


def test_invalid_toml_is_one_line(tmp_path, quadruped_urdf_text):
    path = _robot(tmp_path, quadruped_urdf_text)
    side = tmp_path / "dog.frbench.toml"
    side.write_text("kp = [[[\n")
    with pytest.raises(RobotFileError, match=re.escape(f"{side}: not valid TOML (")):
        get_robot(str(path))


@pytest.mark.parametrize("sidecar, message", [BAD_SIDECARS[0], BAD_SIDECARS[5], BAD_SIDECARS[9], BAD_SIDECARS[14]])
def test_bad_sidecar_exits_2_with_one_line_and_no_traceback(tmp_path, quadruped_urdf_text, capsys, sidecar, message):
    path = _robot(tmp_path, quadruped_urdf_text)
    side = tmp_path / "dog.frbench.toml"
    side.write_text(sidecar)
    assert main(["robot", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{side}: {message}" in err


def test_unsafe_name_writes_nothing_outside_the_cache(tmp_path, quadruped_urdf_text, monkeypatch):
    cache = tmp_path / "cache" / "inner"
    monkeypatch.setenv("FRBENCH_CACHE", str(cache))
    path = _robot(tmp_path, quadruped_urdf_text)
    (tmp_path / "dog.frbench.toml").write_text('name = "../../etc x"\n')
    before = sorted(p for p in tmp_path.rglob("*"))
    with pytest.raises(RobotFileError):
        get_robot(str(path))
    assert sorted(p for p in tmp_path.rglob("*")) == before


def test_file_names_in_the_cache_keep_only_safe_characters():
    from frbench.robots.sim_urdf import safe_file_stem

    assert safe_file_stem("../../etc x") == "______etc_x"
    assert safe_file_stem("go2") == "go2" and safe_file_stem("") == "robot"


# ----------------------------------------------------------------- URDFs
def _edit(text: str, edit) -> str:
    root = ET.fromstring(text)
    edit(root)
    return ET.tostring(root, encoding="unicode")


def _remove_leg(root, leg):
    for joint in list(root.findall("joint")):
        if joint.get("name").startswith(leg):
            root.remove(joint)
    for link in list(root.findall("link")):
        if link.get("name").startswith(leg):
            root.remove(link)


def _add_leg(root):
    """A fifth leg: a copy of FL's joints and links named XL, hanging from the base."""
    for element in list(root):
        name = element.get("name", "")
        if name.startswith("FL_"):
            copy = ET.fromstring(ET.tostring(element).replace(b"FL_", b"XL_"))
            root.append(copy)
    root.find("joint[@name='XL_hip_joint']/origin").set("xyz", "0.0 0.0 0.0")


def _set(xpath, attribute, value):
    return lambda root: root.find(xpath).set(attribute, value)


def _two_parents(root):
    joint = ET.SubElement(root, "joint", name="extra_joint", type="fixed")
    ET.SubElement(joint, "parent", link="FR_calf")
    ET.SubElement(joint, "child", link="FL_foot")


def _loop(root):
    root.find("joint[@name='FL_hip_joint']/parent").set("link", "FL_calf")


def _second_root(root):
    link = ET.SubElement(root, "link", name="floating_box")
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "mass", value="1")
    ET.SubElement(inertial, "inertia", ixx="1", iyy="1", izz="1", ixy="0", ixz="0", iyz="0")


def _duplicate_link(root):
    root.append(ET.fromstring(ET.tostring(root.find("link[@name='FL_foot']"))))


def _remove(xpath):
    def edit(root):
        parent = root.find(xpath + "/..")
        parent.remove(root.find(xpath))
    return edit


def _replace_geometry(tag, **attrs):
    def edit(root):
        geometry = root.find("link[@name='base']/collision/geometry")
        geometry.clear()
        ET.SubElement(geometry, tag, **attrs)
    return edit


def _foot_is_calf(root):
    for leg in ("FL", "FR", "RL", "RR"):
        root.remove(root.find(f"joint[@name='{leg}_foot_joint']"))
        root.remove(root.find(f"link[@name='{leg}_foot']"))


BAD_URDFS = [
    (None, "<robot name='x'><link name='a'></robot>", "not valid XML (mismatched tag: line 1"),
    (None, "<model name='x'/>", "root element <model>, expected <robot>"),
    (None, "<robot name='x'/>", "no <link> elements"),
    (_duplicate_link, None, "link 'FL_foot' defined twice"),
    (_set("joint[@name='FL_hip_joint']/child", "link", "FL_nothing"), None, "joint 'FL_hip_joint': refers to link 'FL_nothing', which the file does not define"),
    (_two_parents, None, "link 'FL_foot' has two parent joints ('FL_foot_joint' and 'extra_joint'); a URDF must be a tree: remove one of them"),
    (_loop, None, "joints form a loop through link 'FL_hip'"),
    (_second_root, None, "2 root links (base, floating_box), expected exactly one"),
    (_set("joint[@name='FL_hip_joint']", "type", "ball"), None, "joint 'FL_hip_joint': type 'ball', expected revolute, continuous, prismatic or fixed"),
    (_set("joint[@name='FL_hip_joint']/axis", "xyz", "0 0 0"), None, "joint 'FL_hip_joint': zero joint axis"),
    (_set("joint[@name='FL_hip_joint']/origin", "xyz", "1 2"), None, "joint 'FL_hip_joint' origin xyz: '1 2', expected 3 finite numbers"),
    (_set("link[@name='FL_calf']/inertial/mass", "value", "heavy"), None, "link 'FL_calf' mass: 'heavy' is not 1 numbers"),
    (_remove("link[@name='FL_calf']/inertial/inertia"), None, "link 'FL_calf': <inertial> without <inertia>"),
    (_set("link[@name='FL_calf']/inertial/mass", "value", "0"), None, "link 'FL_calf' has mass 0 kg; every simulated link needs a positive mass"),
    (_set("link[@name='RR_thigh']/inertial/inertia", "ixx", "-0.01"), None, "link 'RR_thigh' has an inertia that is not positive definite"),
    (_set("link[@name='base']/inertial/inertia", "izz", "5.0"), None, "link 'base' inertia violates the triangle inequality"),
    (_replace_geometry("mesh", filename="meshes/trunk.stl"), None, "link 'base' collision 0: mesh file 'meshes/trunk.stl' not found"),
    (_replace_geometry("capsule", radius="0.1", length="0.2"), None, "link 'base' collision 0: unsupported collision geometry <capsule>"),
    (_remove("link[@name='base']/collision/geometry"), None, "link 'base' collision 0: collision without <geometry>"),
    (lambda r: r.find("joint[@name='FR_calf_joint']/limit").attrib.pop("lower"), None, "joint 'FR_calf_joint' has no usable limits (lower=None, upper=-0.838)"),
    (lambda r: r.find("joint[@name='FR_calf_joint']/limit").attrib.pop("effort"), None, "joint 'FR_calf_joint' has no positive effort limit (effort=None); set effort.FR_calf_joint (N·m)"),
    (_set("joint[@name='FR_calf_joint']/limit", "effort", "0.5"), None, "joint 'FR_calf_joint' needs"),
    (lambda r: _remove_leg(r, "RR"), None, "found 3 legs (FL_foot, FR_foot, RL_foot), chains of at least 3 moving joints hanging below the root; a quadruped needs 4, a humanoid 2: name them in the sidecar's [legs] table (and set kind)"),
    (_add_leg, None, "found 5 legs"),
    (None, "<robot name='box'><link name='base'><inertial><mass value='1'/><inertia ixx='0.1' iyy='0.1' izz='0.1' ixy='0' ixz='0' iyz='0'/></inertial></link></robot>", "found 0 legs (none)"),
    (_set("joint[@name='FR_hip_joint']/origin", "xyz", "0.1681 0.04675 0.0"), None, "two legs sit at the FL corner (FL_foot and FR_foot); name them in the sidecar's [legs] table"),
    (_foot_is_calf, None, "leg FL ends at its calf link 'FL_calf', with no foot link below it"),
]


@pytest.mark.parametrize("edit, text, message", BAD_URDFS, ids=[f"urdf{i}" for i in range(len(BAD_URDFS))])
def test_bad_urdf_is_refused_with_its_message(tmp_path, quadruped_urdf_text, edit, text, message):
    path = _robot(tmp_path, text if text is not None else _edit(quadruped_urdf_text, edit))
    with pytest.raises(RobotFileError, match=re.escape(f"{path}: {message}")):
        get_robot(str(path))


@pytest.mark.parametrize("index", [0, 5, 22, 25])
def test_bad_urdf_exits_2_with_one_line(tmp_path, quadruped_urdf_text, capsys, index):
    edit, text, message = BAD_URDFS[index]
    path = _robot(tmp_path, text if text is not None else _edit(quadruped_urdf_text, edit))
    assert main(["robot", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err


def test_round_off_in_an_inertia_counts_as_zero(tmp_path, quadruped_urdf_text):
    """A point-mass foot whose inertia has a round-off eigenvalue of -2e-22 loads (HyQ's case)."""
    from frbench.robots.sim_urdf import build_sim_tree
    from frbench.robots.infer import provisional_spec

    def edit(root):
        for leg in ("FL", "FR", "RL", "RR"):
            inertia = root.find(f"link[@name='{leg}_foot']/inertial/inertia")
            inertia.attrib.update(ixx="1e-6", iyy="1e-6", izz="-2e-22", ixy="0", ixz="0", iyz="0")

    path = _robot(tmp_path, _edit(quadruped_urdf_text, edit))
    spec, _, _ = provisional_spec(path)
    tree = build_sim_tree(spec)
    moments = np.linalg.eigvalsh(tree.links["FL_foot"].inertia)
    assert moments.min() > 0 and moments.max() == pytest.approx(1e-6, rel=1e-2)


# --- humanoid files of example-robot-data that cannot be simulated as they are: each refusal says what to change ---

HUMANOID_REFUSALS = [
    ("simple_humanoid_description/urdf/simple_humanoid.urdf",
     "foot link 'l_ankle' has no collision geometry, so nothing of the foot touches the ground; add a <collision> "
     "(a box under the sole) to it in the URDF, or name the links that have one in"),
    ("alexander_description/urdf/alexander_v1.lowerBodyOnly.urdf",  # legs found through the IMU frames on hips and knees
     "foot link 'LEFT_FOOT' has no collision geometry"),
    ("romeo_description/urdf/romeo_laas_small.urdf",
     "link 'l_gripper' has no <inertial> and nothing below it, so joint 'l_gripper_joint' moves no mass (a simulator "
     "cannot integrate it); give the link an <inertial> or make the joint fixed in the URDF"),
    ("romeo_description/urdf/romeo.urdf",
     "joint 'LHand' has no positive effort limit (effort=0.0), nor have 23 more (RHand, LFinger12, LFinger13, "),
    ("romeo_description/urdf/romeo_small.urdf", "link 'RShoulderYawLink' inertia violates the triangle inequality"),
]


@pytest.mark.parametrize("relative, message", HUMANOID_REFUSALS, ids=[r.split("/")[-1] for r, _ in HUMANOID_REFUSALS])
def test_humanoid_file_is_refused_with_what_to_change(relative, message):
    from frbench.robots.paths import example_robot_data

    path = example_robot_data(relative)
    with pytest.raises(RobotFileError, match=re.escape(f"{path}: {message}")):
        get_robot(str(path))


def test_a_virtual_link_between_two_joints_gets_a_negligible_mass(tmp_path):
    """human.urdf's hips are three revolute joints through links without <inertial>: simulated, not refused."""
    from frbench.robots.paths import example_robot_data
    from frbench.robots.sim_urdf import MASSLESS_FOOT_MASS

    text = example_robot_data("human_description/robots/human.urdf").read_text()
    for foot in ("left_foot", "right_foot"):  # the file has no collision geometry at all: give the feet soles
        text = text.replace(
            f'<link name="{foot}">',
            f'<link name="{foot}"><collision><origin xyz="0.05 0 -0.05"/><geometry><box size="0.2 0.08 0.02"/></geometry></collision>',
        )
    path = _robot(tmp_path, text, "human")
    from frbench.robots.infer import provisional_spec
    from frbench.robots.sim_urdf import build_sim_tree

    spec, _, legs = provisional_spec(path)
    assert spec.kind == "humanoid" and legs["left"][0] == "left_hip_Z"
    assert build_sim_tree(spec).links["left_upperleg_virtual"].mass == MASSLESS_FOOT_MASS


def test_a_humanoid_whose_ankles_cannot_hold_it_names_every_such_joint(tmp_path):
    from frbench.robots.paths import example_robot_data

    path = _robot(tmp_path, example_robot_data("g1_description/urdf/g1_29dof_rev_1_0.urdf").read_text(), "g1copy")
    side = tmp_path / "g1copy.frbench.toml"
    side.write_text("[effort]\nleft_ankle_pitch_joint = 5.0\nright_ankle_pitch_joint = 5.0\n")
    message = (
        f"{path}: 2 joint(s) need more than 80% of their effort limit to hold the standing pose (left_ankle_pitch_joint "
        f"6.29 of 5, right_ankle_pitch_joint 6.29 of 5 N·m); set effort.left_ankle_pitch_joint and the others in {side} "
        "(or a less crouched [default_pose])"
    )
    with pytest.raises(RobotFileError, match=re.escape(message)):
        get_robot(str(path))
