"""Protocol 1.2's unseen grid: real robots no policy trains on, the named grids and their results."""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from frbench.cli import main
from frbench.evaluation.grid import EvaluationRequest, validate
from frbench.evaluation.grids import expected_cell_keys, resolve_grids, unseen_part
from frbench.evaluation.intervals import bootstrap_rates, percentile_interval, sorted_cells
from frbench.robots import ground_truth
from frbench.robots.builtin import BUILTIN_ROBOTS
from frbench.robots.registry import get_robot
from frbench.robots.unseen import UNSEEN_HUMANOIDS, UNSEEN_QUADRUPEDS, UNSEEN_ROBOTS
from frbench.tasks import protocol

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_factory import make_results  # noqa: E402


def _texts(value) -> list[str]:
    """Every string inside a (nested) config value: names, paths, keys."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [t for f in dataclasses.fields(value) for t in _texts(getattr(value, f.name))]
    if isinstance(value, dict) or hasattr(value, "items"):
        return [t for k, v in value.items() for t in (*_texts(k), *_texts(v))]
    if isinstance(value, (list, tuple, set, frozenset)):
        return [t for v in value for t in _texts(v)]
    return [str(value)] if isinstance(value, (str, Path)) else []


def _names_an_unseen_robot(texts: list[str]) -> list[str]:
    files = {r.file for r in UNSEEN_ROBOTS.values()}
    return [t for t in texts for name in (*UNSEEN_ROBOTS, *files)
            if t == name or t.lower().endswith("/" + name) or ("/" in name and name in t)]


def test_no_training_preset_morphology_range_or_robot_table_names_an_unseen_robot():
    from frbench.robots import morphology, morphology_presets
    from frbench.training import bodies, presets

    assert _names_an_unseen_robot(_texts(dict(presets.PRESETS))) == []
    # the body distributions (``TrainEnvConfig.bodies``): their names and every value of their tables
    assert _names_an_unseen_robot(_texts(dict(bodies.BODIES))) == [] and len(_texts(dict(bodies.BODIES))) > 8
    ranges = [presets.COVERING_MORPHOLOGY_RANGES, presets.LIGHT_MORPHOLOGY_RANGES, morphology.morphology_ranges()]
    assert _names_an_unseen_robot(_texts(ranges)) == []
    tables = {name: value for name, value in vars(morphology_presets).items() if name.isupper()}
    assert tables and _names_an_unseen_robot(_texts(tables)) == []
    assert not set(UNSEEN_ROBOTS) & set(BUILTIN_ROBOTS)
    for name in BUILTIN_ROBOTS:  # no built-in robot is one of their files
        spec = BUILTIN_ROBOTS[name]()
        assert _names_an_unseen_robot([str(spec.urdf_path), spec.source]) == [], name
    # the check itself catches a preset that names one
    assert _names_an_unseen_robot(_texts({"robot": "anymal_c"})) == ["anymal_c"]


def test_the_unseen_quadrupeds_span_9_to_50_kg_and_their_masses_are_the_files():
    assert len(UNSEEN_QUADRUPEDS) >= 6 and {r.kind for r in UNSEEN_QUADRUPEDS} == {"quadruped"}
    assert {r.kind for r in UNSEEN_HUMANOIDS} == {"humanoid"} and {"talos", "icub"} <= {r.name for r in UNSEEN_HUMANOIDS}
    masses = [r.mass_kg for r in UNSEEN_QUADRUPEDS]
    assert min(masses) <= 9.0 and max(masses) >= 50.0
    for robot in UNSEEN_ROBOTS.values():
        spec = get_robot(robot.name)
        assert spec.name == robot.name and spec.kind == robot.kind and spec.source == robot.source
        assert ground_truth.total_mass(spec) == pytest.approx(robot.mass_kg, abs=5e-4), robot.name
        assert robot.reason and robot.path().is_file()


def test_the_unseen_grid_is_576_cells_and_its_worst_case_interval_is_within_2_5_points():
    part = unseen_part(version="1.2")  # two simulators; 1.3's three: tests/test_protocol_13.py
    keys = part.keys()
    assert len(keys) == 9 * 2 * 4 * 2 * 4 == 576 and part.episodes == protocol.UNSEEN_EPISODES == 3
    assert part.terrains == ("flat", "rough", "slopes", "stairs") and part.levels == (1, 5)
    # a simulated unseen grid at 50 % success in every cell, through the project's bootstrap
    rng = np.random.default_rng(0)
    cells = [dict(zip(("robot", "backend", "terrain", "level", "seed"), key), successes=int(rng.binomial(3, 0.5)),
                  episodes=3) for key in keys]
    low, high = percentile_interval(bootstrap_rates(sorted_cells(cells)).mean(axis=1))
    assert (high - low) / 2 <= 0.025
    assert 1.96 * np.sqrt(0.25 / (576 * 3)) < 0.0236  # the normal bound the protocol states


def test_grids_resolve_per_policy_and_humanoids_are_not_scored_for_a_quadruped_policy():
    resolved = resolve_grids(["standard", "unseen"], lambda name: get_robot(name).kind == "quadruped", "1.2")
    assert len(resolved.keys) == 840 + 576
    assert set(resolved.not_scored) == {"icub", "talos"}
    both = resolve_grids(["unseen"], lambda name: True, "1.2")
    assert len(both.keys) == 576 + 2 * 2 * 4 * 2 * 4 and not both.not_scored
    assert len(resolve_grids(["standard", "unseen"], lambda name: True).keys) == (840 + 576 + 128) * 3 // 2  # 1.3
    request = EvaluationRequest(policy="scripted", grid=["unseen"])
    validate(request)
    assert len(request.cells()) == 864 and request.robots == [r.name for r in UNSEEN_QUADRUPEDS]
    assert expected_cell_keys({"grid": ["unseen"], "robots": request.robots}) == set(unseen_part().keys())


def test_results_name_their_grid_and_a_1_2_record_needs_the_unseen_grid_to_be_main():
    from frbench.leaderboard.records import build_record, submission_fields
    from frbench.leaderboard.results import check_results
    from frbench.leaderboard.scores import main_track_shortfall

    both = make_results(episodes=3, skill=0.5, salt=2)
    check_results(both)
    assert both["protocol_version"] == "1.4" and both["config"]["grid"] == ["standard", "unseen"]
    record = build_record(both, submission_fields(both, name="x", description="", submitter="a", link=None,
                                                   submitted="2026-01-01T00:00:00Z"))
    assert record["track"] == "main" and record["scores"]["unseen"]["cells"] == 864  # three simulators
    matched = [c["success_rate"] for c in both["cells"] if c["robot"] in protocol.STANDARD_ROBOTS
               and c["terrain"] in protocol.UNSEEN_TERRAINS and c["level"] in protocol.UNSEEN_LEVELS]
    assert len(matched) == 5 * 3 * 4 * 2 * 4
    assert record["scores"]["generalisation_gap"] == pytest.approx(
        sum(matched) / len(matched) - record["scores"]["unseen"]["overall"])
    standard_only = make_results(episodes=3, skill=0.5, salt=2, unseen=False)
    assert main_track_shortfall(standard_only["cells"], "1.2") == "576 of the unseen grid's 576 cells are missing"
    assert main_track_shortfall(standard_only["cells"], "1.1") is None  # 1.1 asked for the standard grid only
    missing = dict(both, cells=[c for c in both["cells"] if c["robot"] != "b1"])
    with pytest.raises(Exception, match=r"cells: no cell for robot=b1 .* which config.grid \['standard', 'unseen'\] holds"):
        check_results(missing)


@pytest.mark.parametrize("args, message", [
    (["--grid", "bogus"], "--grid 'bogus': unknown grid; known: standard, unseen, humanoid"),
    (["--grid", "unseen", "--robots", "go2"], "--grid unseen fixes the robots, backends, terrains, levels, seeds and "
                                              "episodes: drop --robots"),
])
def test_bad_grid_input_is_one_line_and_exit_2(args, message, capsys, tmp_path):
    status = main(["evaluate", "--policy", "zero", *args, "--out", str(tmp_path / "r.json")])
    err = capsys.readouterr().err
    assert status == 2 and err == f"frbench evaluate: error: {message}\n"
    assert not (tmp_path / "r.json").exists()


def test_evaluate_grid_unseen_writes_the_grid_into_the_results(tmp_path, capsys, monkeypatch):
    """A reduced unseen grid (one robot, one family) through the CLI path that `--grid unseen` takes."""
    import frbench.evaluation.grids as grids

    small = dataclasses.replace(unseen_part(), robots=("a1",), backends=("mujoco",), terrains=("flat",), levels=(1,),
                                seeds=(0,), episodes=2)
    monkeypatch.setattr(grids, "grid_parts", lambda name, version=None: (small, dataclasses.replace(small, robots=("icub",))))
    out = tmp_path / "unseen.json"
    status = main(["evaluate", "--grid", "unseen", "--policy", "scripted", "--jobs", "1", "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    results = json.loads(out.read_text())
    assert results["protocol_version"] == "1.4" and results["config"]["grid"] == ["unseen"]
    assert list(results["config"]["not_scored"]) == ["icub"] and "robot 'icub' of the grid is not scored" in captured.err
    assert [(c["robot"], c["episodes"]) for c in results["cells"]] == [("a1", 2)]
    assert results["robots"]["a1"]["source"] == "example-robot-data: a1_description/urdf/a1.urdf"


def test_the_board_shows_standard_and_unseen_with_the_gap_and_ranks_by_unseen(tmp_path):
    from frbench.leaderboard import board as lb
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.render import board, page_data
    from results_factory import empty_board_copy, write_results

    root = empty_board_copy(Path(__file__).resolve().parents[1] / "leaderboard", tmp_path / "leaderboard")
    strong = make_results(episodes=3, skill=0.9, salt=1)
    weak_unseen = make_results(episodes=3, skill=0.6, salt=2)
    lb.submit(write_results(tmp_path / "a.json", strong), root, name="strong")
    lb.submit(write_results(tmp_path / "b.json", weak_unseen), root, name="weaker")
    lb.submit(write_results(tmp_path / "c.json", make_results(episodes=3, skill=0.99, salt=3, unseen=False)), root,
              name="standard-only")
    data = board(load_records(root))
    assert [r["name"] for r in data["main"]] == ["strong", "weaker"]
    assert [r["name"] for r in data["partial"]] == ["standard-only"]  # 1.2 without the unseen grid
    ranking = data["unseen_ranking"]
    assert [r["name"] for r in ranking] == ["strong", "weaker"] and ranking[0]["humanoids"] is None
    for row in data["main"]:
        g = row["generalisation"]
        assert g["unseen"][1] < g["unseen"][0] < g["unseen"][2]
        assert g["gap"][0] == pytest.approx(g["matched"][0] - g["unseen"][0])
    readme = (root / "README.md").read_text()
    assert "### Ranked by unseen success (protocol 1.4)" in readme and "| Unseen | Matched − unseen | Humanoids |" in readme
    assert readme.count("| n/a |") >= 4  # the humanoid column of both tables, both records
    entries = {e["name"]: e for e in page_data(load_records(root))["records"]}
    assert entries["strong"]["generalisation"]["unseen"] == ranking[0]["unseen"]
    assert entries["standard-only"]["generalisation"] is None
