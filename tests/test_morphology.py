"""Tests of the morphology generator (frbench.robots.morphology)."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from frbench.robots import morphology as morph
from frbench.robots import morphology_frame as morph_frame
from frbench.robots import morphology_urdf as morph_urdf
from frbench.robots.morphology import MORPHOLOGY_RANGES, MorphologyParams
from frbench.robots.morphology_presets import LITE3_LIKE, SPOT_LIKE

LEGS = ("FL", "FR", "RL", "RR")
CANONICAL_JOINTS = tuple(f"{leg}_{part}_joint" for leg in LEGS for part in ("hip", "thigh", "calf"))


def _samples(seed: int, n: int) -> list[MorphologyParams]:
    rng = np.random.default_rng(seed)
    return [morph.sample(rng) for _ in range(n)]


def _params_total(p: MorphologyParams) -> float:
    return p.trunk_mass + 4 * (p.hip_mass + p.thigh_mass + p.calf_mass + p.foot_mass)


PRESETS = {"default": MorphologyParams(), "spot": SPOT_LIKE, "lite3": LITE3_LIKE}
CASES = {**PRESETS, "sampled": _samples(7, 1)[0]}


# --------------------------------------------------------------------------- sampling


def test_ranges_are_the_paper_table():
    assert len(MORPHOLOGY_RANGES) == 14
    assert MORPHOLOGY_RANGES["trunk_mass"] == (4.0, 28.0)
    assert MORPHOLOGY_RANGES["calf_height"] == (0.013, 0.019)
    fields = {f.name for f in dataclasses.fields(MorphologyParams)}
    assert set(MORPHOLOGY_RANGES) <= fields
    assert all(lo < hi for lo, hi in MORPHOLOGY_RANGES.values())


def test_defaults_lie_in_ranges():
    p = MorphologyParams()
    for name, (lo, hi) in MORPHOLOGY_RANGES.items():
        assert lo <= getattr(p, name) <= hi, name


def test_samples_within_ranges():
    samples = _samples(0, 200)
    for name, (lo, hi) in MORPHOLOGY_RANGES.items():
        values = np.array([getattr(p, name) for p in samples])
        assert values.min() >= lo and values.max() <= hi, name
        # uniform over the whole range, not stuck at one value
        assert values.max() - values.min() > 0.8 * (hi - lo), name
    assert all(type(getattr(p, name)) is float for p in samples[:5] for name in MORPHOLOGY_RANGES)


def test_same_seed_same_params_and_different_seeds_differ():
    assert _samples(0, 20) == _samples(0, 20)
    a, b = _samples(0, 1)[0], _samples(1, 1)[0]
    assert a != b
    assert all(getattr(a, name) != getattr(b, name) for name in MORPHOLOGY_RANGES)


def test_sample_keeps_base_fields_and_resets_preset_geometry():
    p = morph.sample(np.random.default_rng(3), base=SPOT_LIKE)
    assert p.kp == SPOT_LIKE.kp == 150.0 and p.calf_torque == 113.2 and p.foot_radius == 0.036
    assert p.hip_x is None and p.hip_y is None
    assert p.thigh_inertia is None and p.trunk_inertia is None
    x, y = morph.hip_position(p)
    assert x == pytest.approx(p.trunk_length / 2 - morph.HIP_X_MARGIN)
    assert y == pytest.approx(p.trunk_width / 2)


def test_sample_requires_a_generator():
    with pytest.raises(TypeError):
        morph.sample(0)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- URDF content


def _inertia_matrix(el: ET.Element) -> np.ndarray:
    g = {k: float(el.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    return np.array([
        [g["ixx"], g["ixy"], g["ixz"]],
        [g["ixy"], g["iyy"], g["iyz"]],
        [g["ixz"], g["iyz"], g["izz"]],
    ])


def _check_urdf_xml(text: str, p: MorphologyParams) -> None:
    root = ET.fromstring(text)
    links = root.findall("link")
    assert len(links) == 17
    assert root.find("link").get("name") == "base"
    total = 0.0
    for link in links:
        inertial = link.find("inertial")
        assert inertial is not None, link.get("name")
        mass = float(inertial.find("mass").get("value"))
        assert mass > 0
        total += mass
        moments = np.linalg.eigvalsh(_inertia_matrix(inertial.find("inertia")))
        assert moments.min() > 0, link.get("name")
        a, b, c = moments
        assert a + b >= c and b + c >= a and a + c >= b, link.get("name")
        assert link.find("visual") is None
        assert link.find("collision/geometry/mesh") is None
    assert abs(total - _params_total(p)) < 1e-9
    joints = {j.get("name"): j for j in root.findall("joint")}
    revolute = [n for n, j in joints.items() if j.get("type") == "revolute"]
    assert tuple(revolute) == CANONICAL_JOINTS
    for n in revolute:
        lim = joints[n].find("limit")
        assert float(lim.get("lower")) < float(lim.get("upper"))
        assert float(lim.get("effort")) > 0 and float(lim.get("velocity")) > 0
    for leg in LEGS:
        foot = joints[f"{leg}_foot_joint"]
        assert foot.get("type") == "fixed" and foot.find("child").get("link") == f"{leg}_foot"
        assert float(foot.find("origin").get("xyz").split()[2]) == -p.calf_length


def test_sampled_urdfs_have_valid_inertias_and_exact_mass():
    for p in _samples(0, 50):
        _check_urdf_xml(morph_urdf.urdf_string(p), p)


@pytest.mark.parametrize("case", sorted(PRESETS))
def test_preset_urdfs_have_valid_inertias_and_exact_mass(case):
    p = PRESETS[case]
    _check_urdf_xml(morph_urdf.urdf_string(p, name=case), p)


def test_kinematic_layout():
    p = MorphologyParams()
    root = ET.fromstring(morph_urdf.urdf_string(p))
    joints = {j.get("name"): j for j in root.findall("joint")}
    x, y = morph.hip_position(p)
    for leg, sx, sy in (("FL", 1, 1), ("FR", 1, -1), ("RL", -1, 1), ("RR", -1, -1)):
        hip = joints[f"{leg}_hip_joint"]
        assert [float(v) for v in hip.find("origin").get("xyz").split()] == [sx * x, sy * y, 0.0]
        assert hip.find("axis").get("xyz") == "1 0 0"
        thigh = joints[f"{leg}_thigh_joint"]
        assert [float(v) for v in thigh.find("origin").get("xyz").split()] == [0.0, sy * p.hip_length, 0.0]
        assert thigh.find("axis").get("xyz") == "0 1 0"
        calf = joints[f"{leg}_calf_joint"]
        assert [float(v) for v in calf.find("origin").get("xyz").split()] == [0.0, 0.0, -p.thigh_length]
    go2_limits = {"FL_hip_joint": (-1.047, 1.047), "FL_thigh_joint": (-1.571, 3.491),
                  "RR_thigh_joint": (-0.524, 4.538), "RL_calf_joint": (-2.723, -0.838)}
    for name, (lo, hi) in go2_limits.items():
        lim = joints[name].find("limit")
        assert (float(lim.get("lower")), float(lim.get("upper"))) == (lo, hi)
    assert float(joints["FR_calf_joint"].find("limit").get("effort")) == 45.43


def test_write_urdf(tmp_path):
    path = morph_urdf.write_urdf(LITE3_LIKE, tmp_path / "sub" / "lite3.urdf", name="lite3")
    assert path.read_text() == morph_urdf.urdf_string(LITE3_LIKE, name="lite3")
    assert ET.parse(path).getroot().get("name") == "lite3"


# --------------------------------------------------------------------------- simulators


@pytest.mark.parametrize("case", sorted(CASES))
def test_pinocchio_mass_and_joints(case):
    pin = pytest.importorskip("pinocchio")
    p = CASES[case]
    model = pin.buildModelFromXML(morph_urdf.urdf_string(p), pin.JointModelFreeFlyer())
    assert model.nq == 19 and model.nv == 18
    assert tuple(model.names)[2:] == CANONICAL_JOINTS
    assert abs(pin.computeTotalMass(model) - _params_total(p)) < 1e-9


@pytest.mark.parametrize("case", ["default", "spot", "lite3"])
def test_nominal_height_matches_pinocchio_kinematics(case):
    pin = pytest.importorskip("pinocchio")
    p = CASES[case]
    model = pin.buildModelFromXML(morph_urdf.urdf_string(p), pin.JointModelFreeFlyer())
    data = model.createData()
    q = pin.neutral(model)  # base at the origin, identity orientation
    q[7:] = morph_frame.default_pose(p)
    pin.framesForwardKinematics(model, data, q)
    depths = [-data.oMf[model.getFrameId(f"{leg}_foot")].translation[2] for leg in LEGS]
    assert morph.nominal_height(p) == pytest.approx(min(depths) + p.foot_radius, abs=1e-12)


def test_joint_sign_conventions():
    pin = pytest.importorskip("pinocchio")
    p = MorphologyParams()
    model = pin.buildModelFromXML(morph_urdf.urdf_string(p), pin.JointModelFreeFlyer())
    data = model.createData()

    def foot(leg: str, hip: float, thigh: float, calf: float) -> np.ndarray:
        q = pin.neutral(model)
        i = 7 + 3 * LEGS.index(leg)
        q[i:i + 3] = (hip, thigh, calf)
        pin.framesForwardKinematics(model, data, q)
        return data.oMf[model.getFrameId(f"{leg}_foot")].translation.copy()

    straight = foot("FL", 0.0, 0.0, 0.0)
    assert foot("FL", 0.0, 0.5, 0.0)[0] < straight[0]  # positive thigh: foot backward
    assert foot("FL", 0.0, 0.0, -0.5)[0] > straight[0]  # negative calf: knee folds, foot forward
    assert foot("FL", 0.3, 0.0, 0.0)[1] > straight[1]  # positive hip on the left: outward
    pose = morph_frame.default_pose(p)
    assert pose[0] == -pose[3] == 0.1  # stand_hip mirrored on the right legs
    assert foot("FR", pose[3], 0.0, 0.0)[1] < foot("FR", 0.0, 0.0, 0.0)[1]  # outward on the right too


@pytest.mark.parametrize("case", sorted(CASES))
def test_mujoco_loads_with_exact_mass(case):
    mujoco = pytest.importorskip("mujoco")
    p = CASES[case]
    spec = mujoco.MjSpec.from_string(morph_urdf.urdf_string(p))
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.worldbody.first_body().add_freejoint()
    model = spec.compile()
    assert model.nu == 0 and model.njnt == 13 and model.nq == 19
    hinges = [model.joint(i).name for i in range(model.njnt) if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE]
    assert tuple(hinges) == CANONICAL_JOINTS
    assert abs(float(model.body_mass.sum()) - _params_total(p)) < 1e-9


@pytest.mark.parametrize("case", sorted(CASES))
def test_pybullet_loads_with_12_revolute_joints(case, tmp_path):
    pybullet = pytest.importorskip("pybullet")
    from pybullet_utils import bullet_client

    p = CASES[case]
    path = morph_urdf.write_urdf(p, tmp_path / f"{case}.urdf")
    client = bullet_client.BulletClient(pybullet.DIRECT)
    try:
        body = client.loadURDF(str(path), flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        infos = [client.getJointInfo(body, j) for j in range(client.getNumJoints(body))]
        revolute = [i[1].decode() for i in infos if i[2] == pybullet.JOINT_REVOLUTE]
        assert tuple(revolute) == CANONICAL_JOINTS
        mass = client.getDynamicsInfo(body, -1)[0] + sum(client.getDynamicsInfo(body, j)[0] for j in range(len(infos)))
        assert abs(mass - _params_total(p)) < 1e-9
    finally:
        client.disconnect()


# --------------------------------------------------------------------------- presets and spec


def test_preset_masses():
    assert abs(morph.total_mass(SPOT_LIKE) - 32.5) < 1e-9
    assert SPOT_LIKE.trunk_mass == pytest.approx(32.5 - 4 * (1.68 + 2.34 + 0.35 + SPOT_LIKE.foot_mass))
    assert (SPOT_LIKE.hip_mass, SPOT_LIKE.thigh_mass, SPOT_LIKE.calf_mass) == (1.68, 2.34, 0.35)
    lite3 = 5.606 + 4 * (0.55 + 0.86 + 0.153 + LITE3_LIKE.foot_mass)
    assert abs(morph.total_mass(LITE3_LIKE) - lite3) < 1e-9
    assert morph.total_mass(LITE3_LIKE) == pytest.approx(11.94, abs=0.005)  # robots.md total


def test_preset_kinematics():
    assert morph.hip_position(SPOT_LIKE) == (0.29785, 0.055)
    assert SPOT_LIKE.hip_length == 0.1108 and SPOT_LIKE.calf_torque == 113.2
    assert morph.hip_position(LITE3_LIKE) == (0.1745, 0.062)
    assert LITE3_LIKE.hip_length == 0.09735
    assert morph_frame.default_pose(SPOT_LIKE)[:6] == (0.0, 0.9, -1.5, 0.0, 0.9, -1.5)
    assert morph_frame.default_pose(SPOT_LIKE)[6:9] == (0.0, 1.1, -1.5)


@pytest.mark.parametrize("case", sorted(CASES))
def test_spec_from_params(case, tmp_path):
    p = CASES[case]
    spec = morph_urdf.spec_from_params(p, f"morph_{case}", tmp_path / "m.urdf")
    assert spec.kind == "quadruped" and spec.physics_dt == 0.005
    assert spec.joint_names == CANONICAL_JOINTS
    assert len(spec.contact_groups) == 13 and len(spec.mass_groups) == 4 and len(spec.knee_groups) == 4
    assert [g.name for g in spec.mass_groups] == ["base", "hip", "thigh", "calf"]
    assert spec.mass_groups[3].links == ("FL_calf", "FR_calf", "RL_calf", "RR_calf")
    assert spec.foot_links == ("FL_foot", "FR_foot", "RL_foot", "RR_foot")
    assert spec.kp == (p.kp,) * 12 and spec.kd == (p.kd,) * 12
    assert spec.torque_limits[:3] == (p.hip_torque, p.thigh_torque, p.calf_torque)
    assert all(lo <= q <= hi for lo, q, hi in zip(spec.joint_lower, spec.default_pose, spec.joint_upper))
    assert spec.nominal_height == morph.nominal_height(p)
    assert spec.license == "BSD-3-Clause" and spec.source


def test_nominal_height_of_go2_like_defaults():
    h = morph.nominal_height(MorphologyParams())
    assert 0.25 < h < 0.40
    p = MorphologyParams()
    expected = (p.thigh_length * math.cos(1.0) + p.calf_length * math.cos(-0.5)) * math.cos(0.1) \
        - p.hip_length * math.sin(0.1) + p.foot_radius
    assert h == pytest.approx(expected)  # the rear legs (thigh 1.0) are the lower pair


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "field, value",
    [("trunk_mass", -1.0), ("calf_mass", 0.0), ("thigh_length", math.nan), ("foot_radius", math.inf),
     ("hip_x", -0.1), ("kp", 0.0), ("kd", math.nan), ("calf_upper", math.nan)],
)
def test_invalid_params_raise_naming_the_field(field, value):
    bad = dataclasses.replace(MorphologyParams(), **{field: value})
    with pytest.raises(ValueError, match=field):
        morph.validate(bad)
    with pytest.raises(ValueError, match=field):
        morph_urdf.urdf_string(bad)


def test_inconsistent_limits_and_inertias_raise():
    with pytest.raises(ValueError, match="stand_calf"):
        morph.validate(dataclasses.replace(MorphologyParams(), stand_calf=0.0))
    with pytest.raises(ValueError, match="hip_lower"):
        morph.validate(dataclasses.replace(MorphologyParams(), hip_lower=2.0, stand_hip=2.5, hip_upper=1.0))
    with pytest.raises(ValueError, match="thigh_inertia"):
        morph.validate(dataclasses.replace(MorphologyParams(), thigh_inertia=(1.0, 0.1, 0.1)))
    with pytest.raises(ValueError, match="calf_inertia"):
        morph.validate(dataclasses.replace(MorphologyParams(), calf_inertia=(1.0, -1.0, 1.0)))
    with pytest.raises(ValueError, match="trunk_mass"):
        morph.sample(np.random.default_rng(0), base=dataclasses.replace(MorphologyParams(), trunk_mass=-2.0))


def test_a_trunk_com_shift_moves_the_com_alike_in_pinocchio_mujoco_and_pybullet(tmp_path):
    from frbench.robots import ground_truth
    from frbench.robot_checks.check import check_robot

    shift = (0.04, -0.03, 0.02)
    plain = morph_urdf.cached_spec(MorphologyParams(), "plain", tmp_path / "plain.urdf")
    shifted = morph_urdf.cached_spec(dataclasses.replace(MorphologyParams(), trunk_com_shift=shift), "shifted",
                                tmp_path / "shifted.urdf")
    assert 'origin xyz="0 0 0"' in morph_urdf.urdf_string(MorphologyParams())  # unshifted URDFs unchanged
    pose = ([0.0, 0.0, 0.5], [1.0, 0.0, 0.0, 0.0], plain.default_pose)
    moved = ground_truth.center_of_mass(shifted, *pose) - ground_truth.center_of_mass(plain, *pose)
    total = ground_truth.total_mass(plain)
    np.testing.assert_allclose(moved, np.array(shift) * MorphologyParams().trunk_mass / total, atol=1e-12)
    report = check_robot(shifted, n_random=2, stand=False)
    assert report.max_com_error < 1e-4 and report.max_mass_error < 1e-6


def test_a_com_shift_must_be_three_finite_numbers():
    with pytest.raises(ValueError, match="trunk_com_shift"):
        morph.validate(dataclasses.replace(MorphologyParams(), trunk_com_shift=(0.0, math.nan, 0.0)))
