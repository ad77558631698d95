"""Robots given by path: derived gains and step, measured height, humanoids, y-up files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from frbench.cli import main
from frbench.robots import get_robot, ground_truth
from frbench.robots.check import check_robot
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
    light = spec_from_path(example_robot_data("solo_description/robots/solo12.urdf"), measure=False)
    heavy = spec_from_path(example_robot_data("anymal_c_simple_description/urdf/anymal.urdf"), measure=False)
    assert ground_truth.total_mass(light) == pytest.approx(2.5, abs=0.01)
    assert ground_truth.total_mass(heavy) == pytest.approx(52.13, abs=0.01)
    assert max(heavy.kp) > 20 * max(light.kp)
    assert heavy.physics_dt < 0.005  # the heavy robot's stiff calves need a smaller step


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
