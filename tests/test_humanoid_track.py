"""The humanoid track (docs/protocol.md, "The humanoid track"): the ``humanoid`` grid of protocol 1.3 (the G1 part
and the unseen humanoid set), the track a record covering it is on, its scores, its section of the board and its
ranking there, the README, the text table and JSON, and tools/humanoid_records.py on a tiny grid."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

import pytest

from frbench.cli import main
from frbench.errors import FrbenchError
from frbench.evaluation.grid import EvaluationRequest, validate
from frbench.evaluation.grids import GridPart, grid_parts, parse_grids, resolve_grids
from frbench.evaluation.results import aggregate_cells, sim_to_sim, summarize
from frbench.leaderboard import markdown, render, sections
from frbench.leaderboard.records import build_record, submission_fields, write_record
from frbench.leaderboard.results import check_results
from frbench.leaderboard.scores import generalisation, humanoid_track_shortfall, track_of

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import make_results  # noqa: E402

NOT_DRIVEN = "the policy does not drive this robot (humanoid grid: scored n/a, not 0)"
#: G1 episodes succeeding out of 3 per family (every simulator, level and seed): flat 1, rough 2/3, slopes 1/3,
#: stairs 0, so the G1 score is 0.5; ``better`` adds one success per family (capped at 3): 0.75.
G1_SUCCESSES = {"flat": 3, "rough": 2, "slopes": 1, "stairs": 0}


def _success(better: bool):
    def success(robot, backend, terrain, level, seed, episode) -> bool:
        if robot == "g1":
            return episode < min(3, G1_SUCCESSES[terrain] + better)
        return episode == 0 and backend == "mujoco"  # the humanoid set: 1/3 in MuJoCo, 0 elsewhere -> 1/9

    return success


def humanoid_results(policy: str, *, with_set: bool, better: bool = False, inputs: str | None = None) -> dict:
    """Results of ``frbench evaluate --grid humanoid`` under protocol 1.3 (`G1_SUCCESSES`): the G1 part, and the
    humanoid set (``with_set``) or its robots in ``config.not_scored``."""
    g1, humanoid_set = grid_parts("humanoid", "1.3")
    parts = [g1, humanoid_set] if with_set else [g1]
    made = [make_results(robots=p.robots, backends=p.backends, terrains=p.terrains, levels=p.levels, seeds=p.seeds,
                         episodes=p.episodes, policy=policy, success=_success(better), unseen=False) for p in parts]
    results = made[0]
    results["episodes"] = [e for m in made for e in m["episodes"]]
    results["robots"] = {r: {**v, "urdf_sha256": f"{i + 32:02x}" * 32}
                         for i, (r, v) in enumerate(r for m in made for r in m["robots"].items())}
    results["config"].update(robots=[r for p in parts for r in p.robots], grid=["humanoid"])
    if not with_set:
        results["config"]["not_scored"] = {r: NOT_DRIVEN for r in humanoid_set.robots}
    return protocol_13(results, inputs)


def protocol_13(results: dict, inputs: str | None = None) -> dict:
    """``results`` of protocol 1.3, cells, summary and sim_to_sim made from its episodes by frbench's own builder
    (three simulators); ``inputs``: what its policy read. Checked like a submission."""
    results["cells"] = aggregate_cells(results["episodes"])
    results["summary"] = summarize(results["cells"])
    results["sim_to_sim"] = sim_to_sim(results["summary"])
    results["protocol_version"] = "1.3"
    if inputs:
        results["policy"]["inputs"] = inputs
    check_results(results)
    return results


def record_of(results: dict, name: str | None = None, submitted: str = "2026-11-22T02:00:00Z") -> dict:
    return build_record(results, submission_fields(results, name=name, description="", submitter=None, link=None,
                                                   submitted=submitted))


@pytest.fixture(scope="module")
def records() -> dict[str, dict]:
    """mpc-distilled-g1 (G1 only, 0.5, submitted an hour after zero), zero (G1 and the set, 0.5) and mpc
    (simulator state, 0.75)."""
    return {
        "g1_only": record_of(humanoid_results("mpc-distilled-g1", with_set=False), submitted="2026-11-22T03:00:00Z"),
        "zero": record_of(humanoid_results("zero", with_set=True)),
        "mpc": record_of(humanoid_results("mpc", with_set=True, better=True, inputs="simulator-state")),
    }


@pytest.fixture
def current_13(monkeypatch):
    """The board's modules see protocol 1.3 as the current one."""
    for module in (sections, render, markdown):
        monkeypatch.setattr(module, "PROTOCOL_VERSION", "1.3")


# --------------------------------------------------------------------------- the grid


def test_the_humanoid_grid_of_protocol_13():
    g1, humanoid_set = grid_parts("humanoid", "1.3")
    assert (g1.robots, g1.backends, g1.terrains, g1.levels, g1.seeds, g1.episodes) == (
        ("g1",), ("mujoco", "pybullet", "physx"), ("flat", "rough", "slopes", "stairs"), (1, 5, 10), (0, 1, 2, 3), 3)
    assert len(g1.keys()) == 144 and len(g1.keys()) * g1.episodes == 432
    assert 1.96 * math.sqrt(0.25 / 432) == pytest.approx(0.0472, abs=5e-5)  # the overall half-width, <= 5 points
    assert humanoid_set == grid_parts("unseen", "1.3")[1] and len(humanoid_set.keys()) == 192
    g1_only = resolve_grids(["humanoid"], lambda robot: robot == "g1", "1.3")
    assert len(g1_only.keys) == 144 and g1_only.not_scored == {"icub": NOT_DRIVEN, "talos": NOT_DRIVEN}
    every = resolve_grids(["humanoid"], lambda robot: True, "1.3")
    assert len(every.keys) == 336 and every.not_scored == {} and every.axes.levels == (1, 5, 10)
    assert parse_grids("humanoid,standard", "1.3") == ["standard", "humanoid"]
    with pytest.raises(FrbenchError, match="the policy drives none of its robots"):
        resolve_grids(["humanoid"], lambda robot: False, "1.3")


def test_a_g1_policy_resolves_the_grid_with_the_humanoid_set_not_scored():
    request = EvaluationRequest(policy="mpc-distilled-g1", grid=["humanoid"], protocol_version="1.3")
    validate(request)
    assert len(request.cells()) == 144 and request.robots == ["g1"] and request.episodes == 3
    assert request.not_scored == {"icub": NOT_DRIVEN, "talos": NOT_DRIVEN}


def test_protocol_12_has_no_humanoid_grid():
    with pytest.raises(FrbenchError, match=r"^--grid humanoid: the humanoid grid is defined from protocol 1\.3 on, "
                                           r"not under protocol 1\.2$"):
        grid_parts("humanoid", "1.2")
    with pytest.raises(FrbenchError, match="not under protocol 1.2"):
        parse_grids("standard,humanoid", "1.2")


# --------------------------------------------------------------------------- track and scores


def test_a_complete_g1_record_is_on_the_humanoid_track_and_a_cell_short_is_partial(records):
    g1_only = records["g1_only"]
    assert g1_only["track"] == "humanoid" and records["zero"]["track"] == "humanoid"
    cells, skipped = g1_only["results"]["cells"], ("icub", "talos")
    assert track_of(cells, "1.3", skipped) == "humanoid"
    assert humanoid_track_shortfall(cells[1:], "1.3", skipped) == "1 of the humanoid G1 grid's 144 cells are missing"
    assert track_of(cells[1:], "1.3", skipped) == "partial"
    assert humanoid_track_shortfall(cells, "1.3") == "192 of the humanoid set grid's 192 cells are missing"
    short = [dict(c, episodes=2) if i == 5 else c for i, c in enumerate(cells)]
    assert humanoid_track_shortfall(short, "1.3", skipped) == "1 humanoid G1 cells have fewer than 3 episodes"
    assert track_of(cells, "1.2", skipped) == "partial"
    assert humanoid_track_shortfall(cells, "1.2") == "the humanoid grid is defined from protocol 1.3 on, not under 1.2"


def test_scores_are_the_g1_cells_and_the_humanoid_set_is_scored_apart(records):
    zero = records["zero"]["scores"]
    assert zero["cells"] == 144 and zero["episodes"] == 432 and list(zero["per_robot"]) == ["g1"]
    assert zero["overall"] == pytest.approx(0.5)
    assert zero["per_family"] == pytest.approx({"flat": 1.0, "rough": 2 / 3, "slopes": 1 / 3, "stairs": 0.0})
    assert zero["unseen_humanoids"]["cells"] == 192 and zero["unseen_humanoids"]["overall"] == pytest.approx(1 / 9)
    assert records["mpc"]["scores"]["overall"] == pytest.approx(0.75)
    humanoids = generalisation(records["zero"]["results"]["cells"], "humanoid")["humanoids"]
    assert humanoids[0] == pytest.approx(1 / 9) and humanoids[1] < 1 / 9 < humanoids[2]
    g1_only = records["g1_only"]
    assert "unseen_humanoids" not in g1_only["scores"]
    assert generalisation(g1_only["results"]["cells"], "humanoid") == {"humanoids": None}


# --------------------------------------------------------------------------- the board


def test_the_humanoid_section_ranks_its_records_with_the_simulator_state_policy_marked(records, current_13):
    g1 = grid_parts("humanoid", "1.3")[0]
    short = make_results(robots=g1.robots, backends=g1.backends, terrains=g1.terrains, levels=g1.levels, seeds=(0, 1),
                         policy="mpc", success=_success(False), unseen=False)  # seeds 2 and 3 missing: partial
    # (its episodes are not the mpc record's, so that record does not extend it: `sections.superseded`)
    partial = record_of(protocol_13(short, "simulator-state"), "mpc-short")
    data = render.board([*records.values(), partial])
    assert [r["name"] for r in data["humanoid"]] == ["mpc", "zero", "mpc-distilled-g1"]
    assert [r["rank"] for r in data["humanoid"]] == [1, 2, 3] and data["humanoid"][0]["inputs"] == "simulator-state"
    # zero and mpc-distilled-g1: 0.5 each, the same gaps (0): the earlier submission first, the two tied
    assert data["humanoid"][2]["tied_above"] and not data["humanoid"][1]["tied_above"]
    assert [r["name"] for r in data["partial"]] == ["mpc-short"] and data["main"] == [] and data["archived"] == []
    assert data["humanoid"][2]["humanoids_not_scored"] == f"icub, talos: {NOT_DRIVEN}"
    assert data["humanoid"][1]["generalisation"]["humanoids"][0] == pytest.approx(1 / 9)

    readme = markdown.render_markdown(list(records.values()))
    section = readme[readme.index("## Humanoid track (protocol 1.3)"):readme.index("## Partial records")]
    assert "432 episodes: a 95 % interval of at most ±4.7 points" in section
    assert "| 1 | mpc | mpc (simulator state) | **0.750 (" in section
    assert f"| n/a: icub, talos: {NOT_DRIVEN} |" in section and "| 0.111 (" in section

    table = render.render_table(list(records.values()), track="humanoid")
    assert table.startswith("Humanoid track, protocol 1.3") and "Main board" not in table
    assert "mpc (simulator state)" in table
    assert f"mpc-distilled-g1: humanoid set n/a: icub, talos: {NOT_DRIVEN}" in table
    alone = json.loads(render.render_json(list(records.values()), track="humanoid"))
    assert sorted(alone) == ["filters", "humanoid", "protocol_version"] and len(alone["humanoid"]) == 3
    assert "humanoid" in json.loads(render.render_json(list(records.values())))


def test_leaderboard_track_humanoid_prints_the_track_alone(records, current_13, tmp_path, capsys):
    from frbench.commands.leaderboard import SECTION_CHOICES

    assert SECTION_CHOICES == sections.SECTIONS
    root = tmp_path / "leaderboard"
    for record in records.values():
        write_record(root, record)
    assert main(["leaderboard", "--root", str(root), "--track", "humanoid"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Humanoid track, protocol 1.3") and "(3 records)" in out and "Partial" not in out
    assert main(["leaderboard", "--root", str(root), "--format", "md", "--track", "humanoid"]) == 2
    assert "--track: filters apply to --format table and json" in capsys.readouterr().err


# --------------------------------------------------------------------------- tools/humanoid_records.py


def test_the_job_runs_chunk_by_chunk_resumes_and_assembles_checked_results(tmp_path, monkeypatch, capsys):
    from frbench.evaluation import grids
    from tools import humanoid_records

    tiny = GridPart(("g1",), ("mujoco",), ("flat",), (1,), (0,), 1)
    tiny_set = dataclasses.replace(tiny, robots=("icub",))
    monkeypatch.setattr(grids, "grid_parts", lambda name, version=None: (tiny, tiny_set))
    out = tmp_path / "out"
    args = ["--protocol", "1.3", "--out", str(out), "--only", "zero,mpc-distilled-g1"]
    assert humanoid_records.main([*args, "--max-chunks", "1"]) == 0
    assert sorted(p.name for p in out.glob("*/chunks/*.json")) == ["humanoid-g1-mujoco-flat.json"]
    first = (out / "zero/chunks/humanoid-g1-mujoco-flat.json").stat().st_mtime_ns
    assert humanoid_records.main([*args, "--status"]) == 0
    assert "zero                 1/2 chunks" in capsys.readouterr().out
    assert humanoid_records.main(args) == 0
    assert (out / "zero/chunks/humanoid-g1-mujoco-flat.json").stat().st_mtime_ns == first  # not run again
    assert sorted(str(p.relative_to(out)) for p in out.glob("*/chunks/*.json")) == [
        "mpc-distilled-g1/chunks/humanoid-g1-mujoco-flat.json", "zero/chunks/humanoid-g1-mujoco-flat.json",
        "zero/chunks/humanoid-icub-mujoco-flat.json"]
    zero = json.loads((out / "zero/results.json").read_text())
    g1_only = json.loads((out / "mpc-distilled-g1/results.json").read_text())
    assert zero["protocol_version"] == "1.3" and zero["config"]["grid"] == ["humanoid"]
    assert [c["robot"] for c in zero["cells"]] == ["g1", "icub"] and zero["config"]["not_scored"] == {}
    assert [c["robot"] for c in g1_only["cells"]] == ["g1"] and set(g1_only["config"]["not_scored"]) == {"icub"}
    assert json.loads((out / "zero/meta.json").read_text())["protocol_version"] == "1.3"
    monkeypatch.setattr(grids, "grid_parts", grid_parts)  # the protocol's own grids: 1.2 has none, nothing is made
    with pytest.raises(FrbenchError, match="not under protocol 1.2"):
        humanoid_records.main(["--protocol", "1.2", "--out", str(tmp_path / "never")])
    assert not (tmp_path / "never").exists()
