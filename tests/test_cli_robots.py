"""``frbench robots`` and ``frbench robot check|add`` as a user runs them."""

from __future__ import annotations

import json

import pytest

from frbench.cli import main


def test_robots_json_lists_all_six(capsys):
    assert main(["robots", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert {"go2", "go1", "aliengo", "spot_like", "lite3_like", "g1"} <= set(rows)
    assert rows["go2"]["mass_kg"] == pytest.approx(16.085)
    assert rows["g1"]["dof"] == 29 and rows["g1"]["kind"] == "humanoid"
    assert rows["spot_like"]["mass_kg"] == pytest.approx(32.5)


def test_robot_check_json_passes_for_go2(capsys):
    assert main(["robot", "check", "go2", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["robot"] == "go2" and report["ok"] is True
    assert set(report["mass"]) == {"pinocchio", "mujoco", "pybullet"}
    assert report["max_mass_error"] < 1e-6 and report["max_com_error"] < 1e-4


def test_robot_check_passes_for_a_quadruped_given_by_path(capsys):
    from frbench.robots.paths import example_robot_data

    path = example_robot_data("a1_description/urdf/a1.urdf")
    assert main(["robot", "check", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] is True


def test_robot_check_exits_1_when_the_robot_cannot_stand(tmp_path, quadruped_urdf_text, capsys):
    path = tmp_path / "weak.urdf"
    path.write_text(quadruped_urdf_text)
    (tmp_path / "weak.frbench.toml").write_text("kp = 2.0\nkd = 0.1\n")
    assert main(["robot", "check", str(path)]) == 1
    assert "sags to" in capsys.readouterr().out


def test_unknown_robot_is_a_one_line_error_with_exit_2(capsys):
    assert main(["robot", "check", "aliengoo"]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0
    assert "unknown robot 'aliengoo'" in err and "did you mean 'aliengo'?" in err


def test_robot_add_then_list(tmp_path, quadruped_urdf_text, capsys):
    path = tmp_path / "cli_dog.urdf"
    path.write_text(quadruped_urdf_text)
    assert main(["robot", "add", str(path), "--name", "cli_dog"]) == 0
    assert "added robot 'cli_dog'" in capsys.readouterr().out
    assert main(["robots", "--json"]) == 0
    assert "cli_dog" in {row["name"] for row in json.loads(capsys.readouterr().out)}


def test_bad_urdf_is_refused_without_a_traceback(tmp_path, capsys):
    path = tmp_path / "broken.urdf"
    path.write_text("<robot")
    assert main(["robot", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: not valid XML" in err and "Traceback" not in err


def test_json_output_is_clean_json_at_the_file_descriptor_level():
    """Bullet prints ``argv[0]=`` from C on every connect; ``--json`` output must still parse."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "frbench.cli", "robot", "check", "go1", "--json"],
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out)["robot"] == "go1"
