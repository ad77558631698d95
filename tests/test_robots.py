"""Robot specs, the registry, URDF refusals and the Pinocchio ground truth."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from frbench.errors import RobotFileError, UnknownNameError
from frbench.robots import get_robot, ground_truth, robot_names
from frbench.robots.registry import add_user_robot, user_robots
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.urdf_tree import parse_urdf

BUILTIN = ("go2", "go1", "aliengo", "spot_like", "lite3_like", "g1")


def test_builtin_robots_are_listed_in_order():
    assert tuple(robot_names()[:6]) == BUILTIN


def test_unknown_robot_suggests_the_closest_name():
    with pytest.raises(UnknownNameError, match=re.escape("unknown robot 'go3' (known: aliengo, g1, go1, go2, lite3_like, spot_like); did you mean 'go2'?")):
        get_robot("go3")


def test_canonical_joint_order_is_by_name_not_file_order():
    go1 = get_robot("go1")  # the file lists FR first
    assert go1.joint_names[:3] == ("FL_hip_joint", "FL_thigh_joint", "FL_calf_joint")
    assert go1.joint_names[3] == "FR_hip_joint"
    # limits follow the joints: calf limits are the file's calf limits
    assert go1.joint_lower[2] == pytest.approx(-2.818) and go1.joint_upper[1] == pytest.approx(4.501)
    assert go1.torque_limits[:3] == (23.7, 23.7, 35.55)


def test_aliengo_continuous_thighs_get_limits():
    spec = get_robot("aliengo")
    assert spec.joint_lower[1] == pytest.approx(-2.094) and spec.joint_upper[1] == pytest.approx(4.189)
    tree = parse_urdf(sim_robot_file(spec).path)
    assert all(j.type == "revolute" for j in tree.moving_joints())
    assert ground_truth.load(spec).model.nq == 19  # no cos/sin pairs


def test_go2_ground_truth_matches_the_measured_values():
    spec = get_robot("go2")
    assert ground_truth.total_mass(spec) == pytest.approx(16.085, abs=1e-9)
    np.testing.assert_allclose(ground_truth.group_masses(spec), [7.277, 4 * 0.767, 4 * 1.241, 4 * 0.194], atol=1e-9)
    com = ground_truth.center_of_mass(spec, [0, 0, 0], [1, 0, 0, 0], np.zeros(12))
    np.testing.assert_allclose(com, [0.00822, 0.0, -0.02849], atol=1e-5)


def test_com_follows_the_base_pose():
    spec = get_robot("go1")
    q = np.asarray(spec.default_pose)
    at_origin = ground_truth.center_of_mass(spec, [0, 0, 0], [1, 0, 0, 0], q)
    yawed = ground_truth.center_of_mass(spec, [1, 2, 3], [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)], q)
    expected = np.array([1 - at_origin[1], 2 + at_origin[0], 3 + at_origin[2]])  # 90° about z
    np.testing.assert_allclose(yawed, expected, atol=1e-12)


@pytest.mark.parametrize("name", BUILTIN)
def test_group_masses_sum_to_the_total(name):
    spec = get_robot(name)
    assert ground_truth.group_masses(spec).sum() == pytest.approx(ground_truth.total_mass(spec), abs=1e-9)


def test_quadruped_groups_are_frnets():
    spec = get_robot("go2")
    assert [g.name for g in spec.mass_groups] == ["base", "hip", "thigh", "calf"]
    assert len(spec.contact_groups) == 13 and spec.contact_groups[0].name == "base"
    assert spec.contact_groups[3].name == "FL_calf" and spec.knee_groups[0].links == ("FL_thigh", "FL_calf")


def test_simulation_urdf_has_no_meshes_and_keeps_feet():
    spec = get_robot("go2")
    tree = parse_urdf(sim_robot_file(spec).path)
    assert all(c.kind != "mesh" for link in tree.links.values() for c in link.collisions)
    assert set(spec.foot_links) <= set(tree.links)
    assert "FL_hip_rotor" not in tree.links  # merged into its parent
    assert tree.total_mass() == pytest.approx(16.085, abs=1e-9)


# ----------------------------------------------------------------- refusals
def _write(tmp_path: Path, text: str, name: str = "robot.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _edit(text: str, edit) -> str:
    root = ET.fromstring(text)
    edit(root)
    return ET.tostring(root, encoding="unicode")


def test_refuses_missing_file():
    with pytest.raises(RobotFileError, match=re.escape("/nowhere/robot.urdf: no such URDF file")):
        get_robot("/nowhere/robot.urdf")


# ----------------------------------------------------------------- adding robots
def test_robot_by_path_infers_legs_and_reads_the_sidecar(tmp_path, quadruped_urdf_text):
    path = _write(tmp_path, quadruped_urdf_text, "mydog.urdf")
    spec = get_robot(str(path))
    assert spec.joint_names[:3] == ("FL_hip_joint", "FL_thigh_joint", "FL_calf_joint")
    assert spec.foot_links == ("FL_foot", "FR_foot", "RL_foot", "RR_foot")
    assert spec.kp[:3] == spec.kp[3:6] == spec.kp[9:12] and len(set(spec.kp[:3])) == 3  # derived per leg joint
    (tmp_path / "mydog.frbench.toml").write_text('kp = 33.0\nnominal_height = 0.31\n[default_pose]\nFL_thigh_joint = 0.7\n')
    spec = get_robot(str(path))
    assert spec.kp == (33.0,) * 12 and spec.nominal_height == 0.31 and spec.default_pose[1] == 0.7


def test_robot_add_registers_persistently(tmp_path, quadruped_urdf_text):
    path = _write(tmp_path, quadruped_urdf_text, "pup.urdf")
    add_user_robot(path, "pup", check=lambda spec: (True, []))
    assert user_robots()["pup"]["urdf"] == str(path.resolve())
    assert "pup" in robot_names() and get_robot("pup").name == "pup"
    with pytest.raises(RobotFileError, match=re.escape("robot name 'go2' is a built-in robot")):
        add_user_robot(path, "go2", force=True)


def test_plugin_robots_come_from_entry_points(monkeypatch):
    import frbench.robots.registry as registry

    spec = get_robot("go1").replace(name="plugdog")

    class EntryPoint:
        name = "plugdog"

        def load(self):
            return lambda: spec

    monkeypatch.setattr(registry, "entry_points", lambda group: [EntryPoint()] if group == "frbench.robots" else [])
    registry._spec_by_name.cache_clear()
    assert "plugdog" in robot_names()
    assert get_robot("plugdog") is spec
    registry._spec_by_name.cache_clear()


def test_import_frbench_loads_no_simulator_or_plugin():
    import subprocess
    import sys

    code = "import sys, frbench, frbench.robots, frbench.terrains; print(sorted(m for m in ('mujoco','pybullet','pinocchio','torch') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"
