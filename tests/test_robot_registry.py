"""`frbench robot add|remove`: the check before adding, --force, re-adding, removing, robots whose file vanished."""

from __future__ import annotations

import json
import re

import pytest

from frbench.cli import main
from frbench.errors import RobotFileError, UnknownNameError
from frbench.robots import get_robot, robot_names
from frbench.robots.registry import add_user_robot, remove_user_robot, user_robots


def _urdf(tmp_path, text, name):
    """The URDF and a sidecar giving its height (no settling in the simulators: these tests are about the registry)."""
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    (tmp_path / f"{name}.frbench.toml").write_text("nominal_height = 0.3\n")
    return path


def _passing(spec):
    return True, []


def _failing(spec):
    return False, ["mujoco: does not stand (base height 0.1 m)"]


def test_add_refuses_a_robot_that_fails_its_check_unless_forced(tmp_path, quadruped_urdf_text):
    path = _urdf(tmp_path, quadruped_urdf_text, "weakdog")
    with pytest.raises(RobotFileError, match=re.escape("robot 'weakdog' not added: `frbench robot check` fails (mujoco: does not stand")):
        add_user_robot(path, "weakdog", check=_failing)
    assert "weakdog" not in user_robots()
    add_user_robot(path, "weakdog", check=_failing, force=True)
    assert user_robots()["weakdog"]["check"] == "fail"


def test_re_adding_a_name_needs_force(tmp_path, quadruped_urdf_text):
    path = _urdf(tmp_path, quadruped_urdf_text, "pup")
    add_user_robot(path, "pup", check=_passing)
    other = _urdf(tmp_path, quadruped_urdf_text, "pup2")
    with pytest.raises(RobotFileError, match=re.escape(f"robot 'pup' is already registered (urdf {path.resolve()}); pass --force to replace it")):
        add_user_robot(other, "pup", check=_passing)
    add_user_robot(other, "pup", check=_passing, force=True)
    assert user_robots()["pup"]["urdf"] == str(other.resolve())


@pytest.mark.parametrize("name, message", [
    ("../../etc x", "--name '../../etc x': expected 1-64 letters, digits, '_' or '-'"),
    ("go2", "robot name 'go2' is a built-in robot; choose another name"),
    ("", "--name '': expected 1-64 letters"),
])
def test_add_refuses_bad_names(tmp_path, quadruped_urdf_text, name, message):
    path = _urdf(tmp_path, quadruped_urdf_text, "dog")
    with pytest.raises(RobotFileError, match=re.escape(message)):
        add_user_robot(path, name, check=_passing)


def test_remove(tmp_path, quadruped_urdf_text):
    path = _urdf(tmp_path, quadruped_urdf_text, "gone")
    add_user_robot(path, "gone", check=_passing)
    assert remove_user_robot("gone")["urdf"] == str(path.resolve())
    assert "gone" not in user_robots() and "gone" not in robot_names()
    with pytest.raises(UnknownNameError, match=re.escape("unknown user robot 'gone' (known: )")):
        remove_user_robot("gone")
    with pytest.raises(RobotFileError, match=re.escape("robot 'go2' is built in and cannot be removed")):
        remove_user_robot("go2")


def test_a_robot_whose_file_vanished_is_listed_as_unavailable(tmp_path, quadruped_urdf_text, capsys):
    path = _urdf(tmp_path, quadruped_urdf_text, "ghost")
    add_user_robot(path, "ghost", check=_passing)
    path.unlink()
    assert "ghost" not in robot_names()
    with pytest.raises(RobotFileError, match=re.escape(f"robot 'ghost' is unavailable: its URDF {path.resolve()} no longer exists; `frbench robot remove ghost` unregisters it")):
        get_robot("ghost")
    assert main(["robots", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert rows["ghost"] == {"name": "ghost", "available": False, "reason": f"its URDF {path.resolve()} no longer exists"}
    assert rows["go2"]["available"] is True
    assert main(["robots"]) == 0
    assert f"ghost        unavailable: its URDF {path.resolve()} no longer exists" in capsys.readouterr().out
    assert main(["robot", "remove", "ghost"]) == 0
    assert "removed robot 'ghost'" in capsys.readouterr().out


@pytest.mark.slow
def test_policies_list_with_a_vanished_robot(tmp_path, quadruped_urdf_text, capsys):
    path = _urdf(tmp_path, quadruped_urdf_text, "ghost")
    add_user_robot(path, "ghost", check=_passing)
    path.unlink()
    assert main(["policies", "--json"]) == 0
    assert "scripted" in capsys.readouterr().out


def test_cli_add_runs_the_check_and_exits_1_when_it_fails(tmp_path, quadruped_urdf_text, capsys):
    path = _urdf(tmp_path, quadruped_urdf_text, "floppy")
    (tmp_path / "floppy.frbench.toml").write_text("kp = 2.0\nkd = 0.1\nnominal_height = 0.3\n")
    assert main(["robot", "add", str(path), "--name", "floppy"]) == 1
    err = capsys.readouterr().err
    assert "robot 'floppy' not added: `frbench robot check` fails (" in err and err.count("\n") == 1
    assert main(["robot", "add", str(path), "--name", "floppy", "--force"]) == 0
    assert "added robot 'floppy'" in capsys.readouterr().out
    assert main(["robot", "add", str(path), "--name", "floppy"]) == 2
    assert "robot 'floppy' is already registered" in capsys.readouterr().err


def test_sim_urdf_cache_stays_bounded_and_spares_files_in_use(tmp_path):
    import os
    import time

    from frbench.robots.sim_urdf import prune_cache

    now = time.time()
    for i in range(12):
        path = tmp_path / f"f{i}.urdf"
        path.write_text("x")
        os.utime(path, (now - 7200 - i, now - 7200 - i))  # used two hours ago, f0 most recently
    (tmp_path / "in-use.urdf").write_text("x")  # just used by some process
    prune_cache(tmp_path, keep=5, min_age_s=3600.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f0.urdf", "f1.urdf", "f2.urdf", "f3.urdf", "in-use.urdf"]
    prune_cache(tmp_path, keep=2, min_age_s=0.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f0.urdf", "in-use.urdf"]


def test_sim_urdf_file_pruned_by_another_process_is_made_again():
    from frbench.robots.sim_urdf import sim_robot_file

    spec = get_robot("go1")
    first = sim_robot_file(spec)
    first.path.unlink()  # what a concurrent prune or `frbench cache clear` does
    again = sim_robot_file(spec)
    assert again.path == first.path and again.path.is_file()
    assert again.sha256 == first.sha256


def test_evaluation_records_the_check_of_a_robot_given_by_path(tmp_path, quadruped_urdf_text):
    from frbench.robot_checks.check import checks_for_evaluation
    from frbench.robots.sidecar import PHYSICS_STEPS

    path = _urdf(tmp_path, quadruped_urdf_text, "limp")
    (tmp_path / "limp.frbench.toml").write_text("kp = 2.0\nkd = 0.1\nnominal_height = 0.3\n")
    checks = checks_for_evaluation(["go2", str(path)])
    assert set(checks) == {"limp"}  # built-in robots are not re-checked
    assert checks["limp"]["ok"] is False and checks["limp"]["physics_dt"] in PHYSICS_STEPS
    assert any("does not stand" in problem for problem in checks["limp"]["problems"])
