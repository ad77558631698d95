"""benchmarks/robot_variants.py: a preset robot's variants keep its name and starts; bad variants get one line."""

from __future__ import annotations

from pathlib import Path

import pytest

from frbench.evaluation.runner import Cell, run_cell
from tests.scripts import load_script as load


def load_script():
    return load("benchmarks/robot_variants.py", "robot_variants_script")


def test_a_variant_is_parsed_into_fields_and_numbers():
    rv = load_script()
    assert rv.parse_variant("kp=80,kd=2") == {"kp": 80.0, "kd": 2.0}
    with pytest.raises(ValueError, match="'knee=3' is not FIELD=VALUE with a field of MorphologyParams"):
        rv.parse_variant("kp=80,knee=3")
    with pytest.raises(ValueError, match="'x' is not a number"):
        rv.parse_variant("kp=x")


def test_a_bad_variant_exits_2_with_one_line(capsys):
    rv = load_script()
    assert rv.main(["--variant", "hip_lenght=0.04"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "hip_lenght=0.04" in err


def test_the_unchanged_variant_plays_the_registry_robot_episode_for_episode(tmp_path, monkeypatch):
    monkeypatch.setenv("FRBENCH_CACHE", str(tmp_path))
    rv = load_script()
    same = rv.variant_spec("lite3_like", {}, 0)
    shorter = rv.variant_spec("lite3_like", {"hip_length": 0.045}, 1)
    assert same.name == shorter.name == "lite3_like"
    assert Path(same.urdf_path).read_text() != Path(shorter.urdf_path).read_text()
    keys = ("initial_pose", "success", "time_to_recover", "final_displacement")
    played = [[tuple(r[k] for k in keys) for r in run_cell(Cell(robot, "mujoco", "flat", 1, 0, 2), "scripted")]
              for robot in (same, "lite3_like")]
    assert played[0] == played[1]
