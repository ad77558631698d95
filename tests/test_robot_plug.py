"""Robots given by path: derived gains and step, measured height, humanoids, y-up files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from frbench.cli import main
from frbench.robot_checks.check import check_robot
from frbench.robot_checks.lookup import get_robot, with_measured_height
from frbench.robots import ground_truth
from frbench.robots.gains import B_MAX, SAG, derive_gains
from frbench.robots.infer import provisional_spec, spec_from_path
from frbench.robots.paths import example_robot_data, pybullet_data_file


def test_derived_gains_hold_the_static_torque_within_the_sag():
    spec, _, legs = provisional_spec(example_robot_data("go2_description/urdf/go2.urdf"))
    d = derive_gains(spec, tuple(legs.values()))
    tau, kp = np.abs(d.static_torque), np.asarray(d.kp)
    assert np.all(tau / kp <= SAG * 1.001)  # kp is rounded to 4 significant digits
    assert np.all(np.asarray(d.stability_b) <= B_MAX) and np.all(np.asarray(d.stability_a) < 2)
    assert sum(d.foot_force_z) == pytest.approx(ground_truth.total_mass(spec) * 9.81, rel=1e-6)
    assert d.physics_dt == 0.004 and d.mode_b <= B_MAX and d.kp[:3] == d.kp[9:12]  # legs share gains per joint


def test_gains_scale_with_the_robot():
    light = spec_from_path(example_robot_data("solo_description/robots/solo12.urdf"))
    heavy = spec_from_path(example_robot_data("anymal_c_simple_description/urdf/anymal.urdf"))
    assert ground_truth.total_mass(light) == pytest.approx(2.5, abs=0.01)
    assert ground_truth.total_mass(heavy) == pytest.approx(52.13, abs=0.01)
    assert max(heavy.kp) > 20 * max(light.kp)
    assert heavy.physics_dt < 0.005  # the heavy robot's stiff calves need a smaller step


def test_leg_reach_lifts_the_thigh_floor_and_caps_the_effort():
    from frbench.robots.gains import FLOOR_ANGLE, GRAVITY, leg_reach, static_model

    spec, _, legs = provisional_spec(example_robot_data("go2_description/urdf/go2.urdf"))
    model, data, _, _ = static_model(spec)
    reach = leg_reach(model, data, spec, tuple(legs.values()))
    assert [reach[j] for j in legs["FL"]] == pytest.approx([0.5215, 0.426, 0.213], abs=1e-4)  # hip offset + 2 x 0.213 m
    d = derive_gains(spec, tuple(legs.values()))
    share = ground_truth.total_mass(spec) / 4 * GRAVITY  # [N]
    # the thigh holds almost nothing at the standing pose (0.75 N·m): its floor is the foot's share at the leg's reach
    assert abs(d.static_torque[1]) < 1.0 and d.kp[1] == pytest.approx(share * 0.426 / FLOOR_ANGLE, rel=1e-3)  # 33.6
    # efforts 23.7 / 23.7 / 45.43 N·m capped at the foot's share of the weight at the whole leg's reach
    assert spec.torque_limits[:3] == pytest.approx((23.7, 23.7, 45.43))
    assert d.effort[:3] == pytest.approx((20.57,) * 3, abs=0.01) and d.as_dict()["effort"] == list(d.effort)
    # Solo12's file says 1000 N·m for a 2.5 kg robot: 2.08 N·m; a sidecar's effort is taken as given
    solo = spec_from_path(example_robot_data("solo_description/robots/solo12.urdf"))
    assert solo.torque_limits == pytest.approx((2.076,) * 12, abs=1e-3)


def test_a_sidecar_effort_is_not_capped(tmp_path):
    sidecar = tmp_path / "solo12.frbench.toml"
    sidecar.write_text("effort = 3.0\n")
    spec = spec_from_path(example_robot_data("solo_description/robots/solo12.urdf"), sidecar)
    assert spec.torque_limits == (3.0,) * 12


@pytest.mark.slow
@pytest.mark.parametrize("relative", ["solo_description/robots/solo12.urdf", "anymal_c_simple_description/urdf/anymal.urdf"])
def test_derived_gains_stand_a_tiny_and_a_heavy_robot_in_both_simulators(relative):
    spec = get_robot(str(example_robot_data(relative)))
    report = check_robot(spec, n_random=1)
    assert report.ok, report.problems
    for name in ("mujoco", "pybullet"):
        assert report.standing[name]["height"] > 0.9 * report.kinematic_height


def test_g1_by_path_loads_as_a_humanoid():
    spec, _, legs = provisional_spec(example_robot_data("g1_description/urdf/g1_29dof_rev_1_0.urdf"))
    assert spec.kind == "humanoid" and spec.n_joints == 29
    assert legs["left"][0] == "left_hip_pitch_joint" and legs["right"][-1] == "right_ankle_roll_joint"
    assert spec.foot_links == ("left_ankle_roll_link", "right_ankle_roll_link")
    assert [g.name for g in spec.mass_groups] == ["trunk", "legs", "arms"]
    assert {"pelvis", "torso", "left_thigh", "left_shin"} <= {g.name for g in spec.contact_groups}
    knee = spec.joint_names.index("left_knee_joint")
    assert spec.default_pose[knee] > 0.2  # knees bent in the direction their limits allow
    groups = ground_truth.group_masses(spec.replace(kp=(1.0,) * 29))
    assert groups.sum() == pytest.approx(33.341, abs=1e-3)


@pytest.mark.slow
def test_g1_by_path_passes_the_check():
    spec = get_robot(str(example_robot_data("g1_description/urdf/g1_29dof_rev_1_0.urdf")))
    report = check_robot(spec, n_random=1)
    assert report.ok, report.problems


def test_a_y_up_file_is_turned_upright():
    spec, _, _ = provisional_spec(pybullet_data_file("laikago/laikago_toes.urdf"))
    zup, _, _ = provisional_spec(pybullet_data_file("laikago/laikago_toes_zup.urdf"))
    assert spec.kind == zup.kind == "quadruped"
    np.testing.assert_allclose(np.reshape(spec.root_rotation, (3, 3)), [[0, 0, 1], [1, 0, 0], [0, 1, 0]])
    assert zup.root_rotation == ()
    assert spec.foot_links == ("toeFL", "toeFR", "toeRL", "toeRR")


def test_continuous_joints_get_a_turn_of_limits():
    spec, _, _ = provisional_spec(pybullet_data_file("aliengo/aliengo.urdf"))
    thigh = spec.joint_names.index("FL_upper_joint")
    assert (spec.joint_lower[thigh], spec.joint_upper[thigh]) == pytest.approx((-np.pi, np.pi))


def test_check_json_reports_the_derived_values(capsys):
    assert main(["robot", "check", str(example_robot_data("a1_description/urdf/a1.urdf")), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] is True and report["kind"] == "quadruped" and report["physics_dt"] == 0.005
    assert len(report["derivation"]["kp"]) == 12 and report["derivation"]["kp"] == report["kp"]
    assert report["kinematic_height"] == pytest.approx(0.2676, abs=1e-3)
    assert abs(report["standing"]["mujoco"]["nominal_height"] - report["kinematic_height"]) < 0.1 * report["kinematic_height"]


# --- humanoids given by path: the derivation for the class (frbench.robots.humanoid_gains) -----------------------


def _derivation(spec) -> dict:
    return json.loads(dict(spec.extra)["derivation"])


def test_g1_by_path_gets_its_step_from_the_derivation_and_sways_within_its_feet():
    from frbench.robots.gains import A_MAX
    from frbench.robots.humanoid_gains import SWAY_FRACTION

    spec = spec_from_path(example_robot_data("g1_description/urdf/g1_29dof_rev_1_0.urdf"))
    d = _derivation(spec)
    # no per-joint balance floor: the ankle rolls were 217 N·m/rad on 0.4 g·m² of foot, which forced 1 ms
    assert spec.physics_dt == d["physics_dt"] == 0.0025 and d["mode_b"] <= B_MAX and d["mode_a"] <= A_MAX * 1.001
    assert d["standing_stiffness"] >= 0 > d["gravity_stiffness"]  # it falls without its PD, stands with it (gravity x2)
    assert 0 < d["sway"] <= SWAY_FRACTION * d["support_margin"] * 1.001
    left, right = spec.joint_names.index("left_ankle_pitch_joint"), spec.joint_names.index("right_ankle_pitch_joint")
    assert spec.kp[left] == spec.kp[right] and spec.kd[left] == spec.kd[right]
    wrist = spec.joint_names.index("left_wrist_yaw_joint")
    assert spec.kd[wrist] > 0.05  # Kd lowered only in the stiffest damping mode, not a tenth everywhere (0.013 flailed)


def test_talos_stands_on_its_soles_in_both_simulators():
    """Talos' lowest leaf is a sole frame with no geometry and its ankle mesh's principal axes are 10° off the sole."""
    from frbench.robots.humanoid_gains import support

    spec = get_robot(str(example_robot_data("talos_data/robots/talos_reduced.urdf")))
    assert spec.foot_links == ("leg_left_6_link", "leg_right_6_link")
    feet = support(spec)
    np.testing.assert_allclose(feet.depth, [0.221, 0.304], atol=2e-3)  # two flat soles, not two box edges
    assert float(dict(spec.extra)["kinematic_height"]) == pytest.approx(1.0533, abs=1e-3)  # the fitted sole, not the frame
    report = check_robot(spec, n_random=1)
    assert report.ok, report.problems
    assert report.physics_dt == 0.0025 and report.support["tilt_margin"] == pytest.approx(0.112, abs=0.005)
    for name in ("mujoco", "pybullet"):
        assert report.standing[name]["height"] == pytest.approx(1.050, abs=0.01)


def test_icub_is_turned_to_face_forward_with_its_feet_along_x():
    """iCub's root frame has x backwards and y to the right; its COLLADA meshes are drawn y-up."""
    from frbench.robots.humanoid_gains import support

    spec, _, legs = provisional_spec(example_robot_data("icub_description/robots/icub_reduced.urdf"))
    np.testing.assert_allclose(np.reshape(spec.root_rotation, (3, 3)), np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    assert legs["left"][0] == "l_hip_pitch" and spec.foot_links == ("l_ankle_2", "r_ankle_2")
    knee = spec.joint_names.index("l_knee")
    assert spec.default_pose[knee] == spec.default_pose[spec.joint_names.index("r_knee")] < -0.3
    feet = support(spec)
    assert feet.depth[0] == pytest.approx(0.156, abs=2e-3)  # each foot 0.156 m long in x, 0.062 m wide
    assert feet.polygon[:, 1].min() == pytest.approx(-feet.polygon[:, 1].max(), abs=1e-3)


def test_bolt_fails_the_check_saying_why_no_key_can_fix_it(capsys):
    """Bolt has no ankles and 1.6 cm feet: a tilt of less than 0.01 rad carries its CoM off them."""
    path = str(example_robot_data("bolt_description/robots/bolt.urdf"))
    report = check_robot(get_robot(path), n_random=1)
    assert not report.ok and len(report.problems) == 1
    problem = report.problems[0]
    assert problem.startswith("cannot stand by holding a pose: its CoM is 0.004 m outside the feet's support polygon")
    assert "no sidecar key can fix it: its feet are at most 0.032 m across" in problem
    assert "give each foot link a sole (a box collision) at least 0.038 m long" in problem
    assert report.support["tilt_margin"] < 0.05
    capsys.readouterr()
    assert main(["robot", "check", path]) == 1
    out = capsys.readouterr().out
    assert f"static support: CoM {report.support['com_height']:.3f} m up, -0.004 m inside the feet's support polygon" in out


def test_bolt_with_soles_and_a_straight_pose_stands(tmp_path):
    """The message's remedy works: soles in the URDF, then the [default_pose] the next message asks for."""
    import re as regex

    text = example_robot_data("bolt_description/robots/bolt.urdf").read_text()
    for side in ("FL", "FR"):
        start = text.index(f'<link name="{side}_FOOT">')
        end = text.index("</link>", start)
        block = regex.sub(r"<collision>.*?</collision>", "", text[start:end], flags=regex.S)
        sole = '<collision><origin xyz="0 0 -0.01"/><geometry><box size="0.08 0.05 0.01"/></geometry></collision>'
        text = text[:start] + block + sole + text[end:]
    path = tmp_path / "bolt_soles.urdf"
    path.write_text(text)
    report = check_robot(get_robot(str(path)), n_random=1)
    assert not report.ok and "set [default_pose] in the sidecar so the soles lie flat" in report.problems[0]
    (tmp_path / "bolt_soles.frbench.toml").write_text(
        "[default_pose]\nFL_HFE = 0.0\nFL_KFE = 0.0\nFR_HFE = 0.0\nFR_KFE = 0.0\n"
    )
    report = check_robot(with_measured_height(spec_from_path(path)), n_random=1)
    assert report.ok, report.problems
    for name in ("mujoco", "pybullet"):
        assert report.standing[name]["height"] > 0.9 * report.kinematic_height
