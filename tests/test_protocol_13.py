"""Protocol 1.3: the standard and unseen grids in three simulators (PhysX added), pairwise sim-to-sim gaps in
results and scores, results that reuse a 1.2 record's MuJoCo and PyBullet episodes, and
`EvaluationRequest.protocol_version` (docs/protocol.md, "Protocol 1.3")."""

from __future__ import annotations

import copy
import sys
from pathlib import Path

import pytest

from frbench.errors import FrbenchError, ResultsError
from frbench.evaluation.grid import EvaluationRequest, build_results, run_grid, validate
from frbench.evaluation.grids import grid_parts, resolve_grids
from frbench.evaluation.results import SIM_TO_SIM_PAIRS, aggregate_cells, gap_field, sim_to_sim, summarize
from frbench.leaderboard import board as lb
from frbench.leaderboard import regenerate
from frbench.leaderboard.records import build_record, submission_fields, write_record
from frbench.leaderboard.results import check_results
from frbench.leaderboard.reuse import (check_against_source, check_board_reuse, check_reused, episodes_sha256,
                                       reused_episodes, reused_field)
from frbench.leaderboard.scores import main_track_shortfall, record_scores, score_intervals
from frbench.tasks.protocol import KNOWN_PROTOCOL_VERSIONS, PROTOCOL_VERSION, grid_backends

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import empty_board_copy, make_results, small_results  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SUBMITTED = "2026-11-22T02:00:00Z"
THREE = ("mujoco", "pybullet", "physx")

#: Episodes succeeding out of 4 per (backend, terrain, level) in `three_simulator_results` (seed-independent):
#: MuJoCo and PyBullet as `results_factory.SMALL_SUCCESSES`, PhysX 4, 1, 0, 1.
SUCCESSES = {
    ("mujoco", "flat", 1): 4, ("mujoco", "flat", 5): 3, ("mujoco", "stairs", 1): 2, ("mujoco", "stairs", 5): 1,
    ("pybullet", "flat", 1): 3, ("pybullet", "flat", 5): 3, ("pybullet", "stairs", 1): 2, ("pybullet", "stairs", 5): 0,
    ("physx", "flat", 1): 4, ("physx", "flat", 5): 1, ("physx", "stairs", 1): 0, ("physx", "stairs", 5): 1,
}


def _success(robot, backend, terrain, level, seed, episode) -> bool:
    return episode < SUCCESSES[(backend, terrain, level)]


def rebuilt(results: dict, protocol_version: str) -> dict:
    """``results`` with cells, summary and sim_to_sim recomputed from its episodes by frbench's own results builder
    (`frbench.evaluation.results`, as `frbench.evaluation.grid.build_results` writes them), of ``protocol_version``."""
    out = dict(results, protocol_version=protocol_version)
    out["cells"] = aggregate_cells(results["episodes"])
    out["summary"] = summarize(out["cells"])
    out["sim_to_sim"] = sim_to_sim(out["summary"])
    return out


def three_simulator_results(backends=THREE, protocol_version: str = "1.3") -> dict:
    """go2 on flat and stairs, levels 1 and 5, seeds 0 and 1, 4 episodes per cell in ``backends`` (`SUCCESSES`):
    success rates MuJoCo 1, .75, .5, .25; PyBullet .75, .75, .5, 0; PhysX 1, .25, 0, .25 (flat 1, flat 5, stairs 1,
    stairs 5). MuJoCo and PyBullet episodes are `small_results`' own, bit for bit."""
    base = make_results(robots=("go2",), backends=backends, terrains=("flat", "stairs"), levels=(1, 5), seeds=(0, 1),
                        episodes=4, success=_success)
    return rebuilt(base, protocol_version)


def _fields(results: dict) -> dict:
    return submission_fields(results, name=None, description="", submitter=None, link=None, submitted=SUBMITTED)


def _copy_with(results: dict, edit) -> dict:
    out = copy.deepcopy(results)
    edit(out)
    return out


# --------------------------------------------------------------------------- the grids per version


def test_grid_simulators_per_protocol_version():
    assert PROTOCOL_VERSION == "1.4" and "1.3" in KNOWN_PROTOCOL_VERSIONS
    assert grid_backends("1.2") == ("mujoco", "pybullet") == grid_backends("1.1")
    assert grid_backends("1.3") == THREE == grid_backends("1.4") == grid_backends()


def test_grid_cell_counts_per_protocol_version():
    standard_12, standard_13 = grid_parts("standard", "1.2")[0], grid_parts("standard", "1.3")[0]
    assert (len(standard_12.keys()), len(standard_13.keys())) == (840, 1260)
    quadrupeds_12, humanoids_12 = grid_parts("unseen", "1.2")
    quadrupeds_13, humanoids_13 = grid_parts("unseen", "1.3")
    assert (len(quadrupeds_12.keys()), len(quadrupeds_13.keys())) == (576, 864)
    assert (len(humanoids_12.keys()), len(humanoids_13.keys())) == (128, 192)
    # 1.3 is 1.2 plus the same cells in PhysX
    added = set(standard_13.keys()) - set(standard_12.keys())
    assert set(standard_12.keys()) < set(standard_13.keys()) and {k[1] for k in added} == {"physx"}
    resolved = resolve_grids(["standard", "unseen"], lambda name: name not in ("icub", "talos"), "1.3")
    assert len(resolved.keys) == 1260 + 864 and resolved.axes.backends == THREE
    assert sorted(resolved.not_scored) == ["icub", "talos"]


@pytest.fixture(scope="module")
def complete_12() -> dict:
    """A protocol 1.2 main-track results object: the standard and unseen grids in MuJoCo and PyBullet."""
    return make_results(episodes=3, protocol_version="1.2")


def test_a_complete_12_record_lacks_its_physx_cells_under_13(complete_12):
    cells = complete_12["cells"]
    assert main_track_shortfall(cells, "1.2") is None
    assert main_track_shortfall(cells, "1.3") == "420 of the standard grid's 1260 cells are missing"
    standard_only = [c for c in cells if c["robot"] in grid_parts("standard", "1.3")[0].robots]
    assert main_track_shortfall(standard_only, "1.3") == "420 of the standard grid's 1260 cells are missing"
    check_results(complete_12)
    relabelled = dict(complete_12, protocol_version="1.3")
    with pytest.raises(ResultsError, match=r"^cells: no cell for robot=\S+ backend=physx terrain=\S+ level=\d+ "
                                           r"seed=\d+, which config.grid \['standard', 'unseen'\] holds$"):
        check_results(relabelled)


# --------------------------------------------------------------------------- results: sim_to_sim


def _row(backend: str, terrain: str, level: int, mean: float) -> dict:
    return {"robot": "go2", "backend": backend, "terrain": terrain, "level": level, "success_rate_mean": mean}


def test_sim_to_sim_holds_each_simulators_mean_and_each_pairs_gap():
    summary = [_row("mujoco", "flat", 1, 0.75), _row("pybullet", "flat", 1, 0.5), _row("physx", "flat", 1, 0.125),
               _row("mujoco", "stairs", 5, 0.25), _row("physx", "stairs", 5, 0.625), _row("pybullet", "rough", 1, 1.0)]
    assert [gap_field(*pair) for pair in SIM_TO_SIM_PAIRS] == ["gap", "gap_mujoco_physx", "gap_pybullet_physx"]
    assert sim_to_sim(summary) == [
        {"robot": "go2", "terrain": "flat", "level": 1, "mujoco": 0.75, "pybullet": 0.5, "physx": 0.125,
         "gap": 0.25, "gap_mujoco_physx": 0.625, "gap_pybullet_physx": 0.375},
        # MuJoCo and PhysX only: no `gap` (MuJoCo - PyBullet); rough ran in one simulator: no entry
        {"robot": "go2", "terrain": "stairs", "level": 5, "mujoco": 0.25, "physx": 0.625, "gap_mujoco_physx": -0.375},
    ]


def test_sim_to_sim_of_mujoco_and_pybullet_keeps_the_old_entry():
    entries = sim_to_sim([_row("mujoco", "flat", 1, 0.75), _row("pybullet", "flat", 1, 0.5)])
    assert entries == [{"robot": "go2", "terrain": "flat", "level": 1, "mujoco": 0.75, "pybullet": 0.5, "gap": 0.25}]
    assert list(entries[0]) == ["robot", "terrain", "level", "mujoco", "pybullet", "gap"]
    # and the factory's two-simulator results, made before PhysX, are what frbench's builder writes
    old = small_results()
    assert rebuilt(old, old["protocol_version"])["sim_to_sim"] == old["sim_to_sim"]


# --------------------------------------------------------------------------- results: the checks


@pytest.fixture(scope="module")
def three() -> dict:
    return three_simulator_results()


def test_check_results_accepts_three_simulator_results(three):
    check_results(three)
    assert len(three["cells"]) == 24 and len(three["sim_to_sim"]) == 4
    assert three["sim_to_sim"][0] == {"robot": "go2", "terrain": "flat", "level": 1, "mujoco": 1.0, "pybullet": 0.75,
                                      "physx": 1.0, "gap": 0.25, "gap_mujoco_physx": 0.0, "gap_pybullet_physx": -0.25}
    check_results(three_simulator_results(("mujoco", "physx")))  # a pair without PyBullet


def _entry(field: str, value):
    def edit(results):
        results["sim_to_sim"][0][field] = value
    return edit


def _drop(field: str):
    def edit(results):
        del results["sim_to_sim"][0][field]
    return edit


@pytest.mark.parametrize(("edit", "message"), [
    (_entry("gap_mujoco_physx", 0.25), r"^sim_to_sim\[0\]\.gap_mujoco_physx: 0\.25 differs from mujoco - physx = 0$"),
    (_entry("gap_pybullet_physx", 0.25), r"^sim_to_sim\[0\]\.gap_pybullet_physx: 0\.25 differs from pybullet - "
                                         r"physx = -0\.25$"),
    (_entry("physx", 0.5), r"^sim_to_sim\[0\]\.physx: 0\.5 differs from the summary's success_rate_mean, 1$"),
    (_drop("physx"), r"^sim_to_sim\[0\]\.physx: missing, but the summary has it$"),
    (_drop("gap_pybullet_physx"), r"^sim_to_sim\[0\]\.gap_pybullet_physx: missing$"),
])
def test_check_results_refuses_a_wrong_three_simulator_entry(three, edit, message):
    with pytest.raises(ResultsError, match=message):
        check_results(_copy_with(three, edit))


def test_check_results_refuses_a_gap_or_mean_of_a_simulator_that_did_not_run():
    two = three_simulator_results(("mujoco", "pybullet"))
    check_results(two)
    with pytest.raises(ResultsError, match=r"^sim_to_sim\[0\]\.gap_mujoco_physx: mujoco and physx did not both "
                                           r"run it$"):
        check_results(_copy_with(two, _entry("gap_mujoco_physx", 0.0)))
    with pytest.raises(ResultsError, match=r"^sim_to_sim\[0\]\.physx: physx ran no cell of it$"):
        check_results(_copy_with(two, _entry("physx", 1.0)))
    # |MuJoCo - PyBullet| is accepted in `gap` as before PhysX, its other pairs' signs are not optional
    check_results(_copy_with(two, _entry("gap", 0.25)))
    with pytest.raises(ResultsError, match=r"^sim_to_sim\[0\]\.gap_pybullet_physx: 0\.25 differs"):
        check_results(_copy_with(three_simulator_results(), _entry("gap_pybullet_physx", 0.25)))


# --------------------------------------------------------------------------- scores


def test_scores_of_three_simulators_hold_pairwise_gaps(three):
    scores = record_scores(three["cells"], "partial")
    # |mean over seeds| differences per (terrain, level): MuJoCo-PyBullet .25 0 0 .25, MuJoCo-PhysX 0 .5 .5 0,
    # PyBullet-PhysX .25 .5 .5 .25
    assert scores["pairwise_gaps"] == {"mujoco-pybullet": 0.125, "mujoco-physx": 0.25, "pybullet-physx": 0.375}
    assert scores["sim_to_sim_gap"] == (0.5 + 1.0 + 1.5) / 12 == 0.25  # the mean over all 12 (pair, entry) gaps
    assert scores["overall"] == 0.5 and scores["per_backend"] == {"mujoco": 0.625, "pybullet": 0.5, "physx": 0.375}
    assert scores["per_family"] == {"flat": 0.75, "stairs": 0.25}
    assert (scores["cells"], scores["episodes"]) == (24, 96)


def test_gaps_average_over_entries_not_over_pairs():
    """A pair that ran fewer (robot, terrain, level) weighs less: sim_to_sim_gap is the mean over every pair's
    entries. MuJoCo and PyBullet ran flat and stairs, PhysX flat only."""
    results = three_simulator_results()
    results["cells"] = [c for c in results["cells"] if c["backend"] != "physx" or c["terrain"] == "flat"]
    scores = record_scores(results["cells"], "partial")
    assert scores["pairwise_gaps"] == {"mujoco-pybullet": 0.125, "mujoco-physx": 0.25, "pybullet-physx": 0.375}
    # entries: MuJoCo-PyBullet .25 0 0 .25, MuJoCo-PhysX 0 .5, PyBullet-PhysX .25 .5
    assert scores["sim_to_sim_gap"] == 1.75 / 8


def test_mujoco_pybullet_scores_are_as_before(three):
    results = small_results()
    scores = record_scores(results["cells"], "partial")
    # by hand (small_results' docstring): rates MuJoCo 1 .75 .5 .25, PyBullet .75 .75 .5 0, |gaps| .25 0 0 .25
    assert scores == {"overall": 0.5625, "per_family": {"flat": 0.8125, "stairs": 0.3125},
                      "per_backend": {"mujoco": 0.625, "pybullet": 0.5}, "per_robot": {"go2": 0.5625},
                      "sim_to_sim_gap": 0.125, "cells": 16, "episodes": 64}
    # the MuJoCo and PyBullet cells of a three-simulator record score as that record
    assert record_scores([c for c in three["cells"] if c["backend"] != "physx"], "partial") == scores
    intervals = score_intervals(results["cells"])
    assert "signed_gaps" not in intervals and intervals["signed_gap"][0] == 0.125
    # one pair among three simulators (no PyBullet) is no `pairwise_gaps` either
    two = three_simulator_results(("mujoco", "physx"))
    assert "pairwise_gaps" not in record_scores(two["cells"], "partial")
    assert record_scores(two["cells"], "partial")["sim_to_sim_gap"] == 0.25


def test_score_intervals_give_each_pairs_signed_gap(three):
    intervals = score_intervals(three["cells"])
    signed = intervals["signed_gaps"]
    assert list(signed) == ["mujoco-pybullet", "mujoco-physx", "pybullet-physx"]
    # signed means over (terrain, level): (.25 + 0 + 0 + .25) / 4, (0 + .5 + .5 + 0) / 4, (-.25 + .5 + .5 - .25) / 4
    assert [point for point, _, _ in signed.values()] == [0.125, 0.25, 0.125]
    for point, low, high in signed.values():
        assert low <= point <= high and high - low > 0
    assert intervals["signed_gap"] == signed["mujoco-pybullet"]
    physx_only = score_intervals(three["cells"], backend="physx")
    assert physx_only["signed_gap"] is None and "signed_gaps" not in physx_only


def test_record_of_three_simulators_passes_the_record_schema(three):
    record = build_record(three, _fields(three))
    assert record["track"] == "partial" and record["scores"]["pairwise_gaps"]["pybullet-physx"] == 0.375


# --------------------------------------------------------------------------- reuse of a 1.2 record's episodes


@pytest.fixture(scope="module")
def source() -> dict:
    """The protocol 1.2 record whose MuJoCo and PyBullet episodes the 1.3 results reuse."""
    results = three_simulator_results(("mujoco", "pybullet"), protocol_version="1.2")
    return build_record(results, _fields(results))


@pytest.fixture(scope="module")
def reusing(source) -> dict:
    """Protocol 1.3 results holding the source's MuJoCo and PyBullet episodes and new PhysX ones."""
    results = three_simulator_results()
    results["reused"] = reused_field(source, ["mujoco", "pybullet"])
    return results


def test_reused_field_names_the_source_and_its_episodes(source, reusing):
    reused = reused_field(source, ["mujoco", "pybullet"])
    assert reused == {"record": source["id"], "protocol_version": "1.2", "backends": ["mujoco", "pybullet"],
                      "episodes": 64, "episodes_sha256": episodes_sha256(source["results"]["episodes"],
                                                                         ["mujoco", "pybullet"])}
    # the checksum reads the reused simulators' episodes only, in (robot, backend, terrain, level, seed, episode)
    # order whatever the list's order
    episodes = reusing["episodes"]
    assert episodes_sha256(episodes, ["mujoco", "pybullet"]) == reused["episodes_sha256"]
    assert episodes_sha256(list(reversed(episodes)), ["pybullet", "mujoco"]) == reused["episodes_sha256"]
    assert episodes_sha256(episodes, ["mujoco"]) != reused["episodes_sha256"]
    assert reused_episodes(source, ["mujoco", "pybullet"]) == [e for e in episodes if e["backend"] != "physx"]


def test_check_results_accepts_consistent_reuse(source, reusing):
    check_results(reusing)
    check_against_source(reusing, source)
    # a PhysX episode is no reused one: editing it leaves the checksum
    edited = _copy_with(reusing, lambda r: next(e for e in r["episodes"] if e["backend"] == "physx")
                        .update(initial_pose="prone"))
    check_reused(edited)


def _first_mujoco_episode(results: dict) -> dict:
    return next(e for e in results["episodes"] if e["backend"] == "mujoco")


def test_check_results_refuses_a_changed_reused_episode(reusing):
    edited = _copy_with(reusing, lambda r: _first_mujoco_episode(r).update(initial_pose="prone"))
    with pytest.raises(ResultsError, match=r"^reused\.episodes_sha256: the results' episodes of mujoco, pybullet have "
                                           r"another checksum$"):
        check_results(edited)


def _reused(field: str, value):
    def edit(results):
        results["reused"][field] = value
    return edit


@pytest.mark.parametrize(("edit", "message"), [
    (_reused("episodes", 63), r"^reused\.episodes: 63 but the results hold 64 episodes of mujoco, pybullet$"),
    (_reused("backends", ["mujoco", "mujoco-warp"]), r"^reused\.backends: mujoco-warp not among config\.backends$"),
    (_reused("protocol_version", "1.3"), r"^reused\.protocol_version: 1\.3 is not earlier than the results' 1\.3$"),
    (_reused("protocol_version", "1.4"), r"^reused\.protocol_version: 1\.4 is not earlier than the results' 1\.3$"),
    (lambda r: r["episodes"].remove(_first_mujoco_episode(r)),
     r"^reused\.episodes: 64 but the results hold 63 episodes of mujoco, pybullet$"),
])
def test_check_reused_refuses_inconsistent_reuse(reusing, edit, message):
    with pytest.raises(ResultsError, match=message):
        check_reused(_copy_with(reusing, edit))


def test_reuse_is_checked_against_its_source(source, reusing):
    other_results = three_simulator_results(("mujoco", "pybullet"), protocol_version="1.2")
    _first_mujoco_episode(other_results).update(initial_pose="prone")  # "supine" in the source
    other = build_record(other_results, _fields(other_results))
    with pytest.raises(ResultsError, match=rf"^reused\.record: {source['id'][:12]} is not record {other['id'][:12]}$"):
        check_against_source(reusing, other)
    # a source whose episodes are not the ones reused (its id kept): another checksum
    forged = dict(other, id=source["id"])
    with pytest.raises(ResultsError, match=rf"^reused\.episodes_sha256: record {source['id'][:12]}'s episodes of "
                                           r"mujoco, pybullet have another checksum$"):
        check_against_source(reusing, forged)
    relabelled = dict(source, results=dict(source["results"], protocol_version="1.1"))
    with pytest.raises(ResultsError, match=r"^reused\.protocol_version: 1\.2 but record \w{12} is of protocol 1\.1$"):
        check_against_source(reusing, relabelled)


def test_the_board_checks_reuse_between_its_records(source, reusing):
    record = build_record(reusing, _fields(reusing))
    assert check_board_reuse([source, record]) == [record["id"]]
    assert check_board_reuse([record]) == []  # the source is not on the board: nothing to compare
    # a board whose source record's MuJoCo episodes differ from the reused ones (its id kept)
    tampered = _copy_with(source, lambda s: _first_mujoco_episode(s["results"]).update(initial_pose="prone"))
    with pytest.raises(ResultsError, match=rf"^record {record['id'][:12]}: reused\.episodes_sha256: record "
                                           rf"{source['id'][:12]}'s episodes of mujoco, pybullet have another checksum$"):
        check_board_reuse([tampered, record])


def test_leaderboard_check_compares_a_reusing_record_with_its_source(tmp_path, source, reusing):
    """`frbench leaderboard --check`: a 1.3 record that names a 1.2 record on the board but holds other MuJoCo
    episodes (its own checksum recomputed, so that its results pass check_results) is a problem."""
    root = empty_board_copy(REPO / "leaderboard", tmp_path / "leaderboard")
    write_record(root, source)
    forged = _copy_with(reusing, lambda r: _first_mujoco_episode(r).update(initial_pose="prone"))
    forged["reused"]["episodes_sha256"] = episodes_sha256(forged["episodes"], ["mujoco", "pybullet"])
    check_results(forged)
    record = build_record(forged, _fields(forged))
    write_record(root, record)
    regenerate(root)
    assert lb.check(root).problems == [
        f"record {record['id'][:12]}: reused.episodes_sha256: record {source['id'][:12]}'s episodes of mujoco, "
        "pybullet have another checksum",
        f"{root / 'README.md'} and {root / 'index.html'} were not compared because of the problems above",
    ]
    (root / "records" / f"{record['id']}.json.gz").unlink()
    honest = build_record(reusing, _fields(reusing))
    write_record(root, honest)
    regenerate(root)
    assert lb.check(root).problems == []


# --------------------------------------------------------------------------- EvaluationRequest.protocol_version


def test_an_unknown_protocol_version_is_a_one_line_error():
    request = EvaluationRequest(policy="zero", robots=["go2"], backends=["mujoco"], terrains=["flat"], levels=[1],
                                seeds=[0], episodes=1, protocol_version="9.9")
    with pytest.raises(FrbenchError) as error:
        validate(request)
    assert str(error.value) == "unknown protocol version '9.9' (known: 1.0, 1.1, 1.2, 1.3, 1.4)"


def _tiny(protocol_version: str, backends: list[str]) -> dict:
    request = EvaluationRequest(policy="zero", robots=["go2"], backends=backends, terrains=["flat"], levels=[1],
                                seeds=[0], episodes=1, jobs=1, protocol_version=protocol_version)
    return build_results(request, validate(request), run_grid(request))


def test_a_13_evaluation_writes_its_version_and_passes_the_checks():
    results = _tiny("1.3", ["mujoco", "physx"])
    assert results["protocol_version"] == "1.3" and "protocol_version" not in results["config"]
    check_results(results)
    assert [e["backend"] for e in results["episodes"]] == ["mujoco", "physx"]
    entry = results["sim_to_sim"][0]
    assert set(entry) == {"robot", "terrain", "level", "mujoco", "physx", "gap_mujoco_physx"}
    assert entry["gap_mujoco_physx"] == entry["mujoco"] - entry["physx"]
    # the MuJoCo episode is 1.2's, bit for bit: 1.3 changes no start, physics or success test
    assert _tiny("1.2", ["mujoco"])["episodes"] == results["episodes"][:1]
