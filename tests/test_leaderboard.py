"""The leaderboard: `frbench submit`, `frbench leaderboard`, records, scores, rendering and refusals."""

from __future__ import annotations

import copy
import gzip
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from frbench.cli import main
from frbench.errors import ResultsError
from frbench.leaderboard import board as lb
from frbench.leaderboard.jsonfile import canonical_json, pretty_json
from frbench.leaderboard.paths import ENV_VAR, default_root
from frbench.leaderboard.records import (
    build_record,
    check_record,
    record_bytes,
    record_id,
    record_text,
    submission_fields,
)
from frbench.leaderboard.formatting import md_escape
from frbench.leaderboard.markdown import render_markdown
from frbench.leaderboard.render import page_data, render_html, script_json
from frbench.leaderboard.results import check_results
from frbench.leaderboard.scores import main_track_shortfall
from frbench.tasks.protocol import STANDARD_EPISODES, STANDARD_ROBOTS
from frbench.schemas import SCHEMA_NAMES, load_schema, schema_text, validate

sys.path.insert(0, str(Path(__file__).parent))
from results_factory import empty_board_copy, make_results, small_results, write_results  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
REPO_BOARD = REPO / "leaderboard"
SUBMITTED = "2026-11-22T02:00:00Z"


# --------------------------------------------------------------------------- helpers


@pytest.fixture(scope="module")
def full() -> dict:
    """Standard-grid results (840 cells, 2 episodes each)."""
    return make_results(episodes=3)


@pytest.fixture
def root(tmp_path: Path) -> Path:
    """A temporary copy of the repository's leaderboard folder, without its records."""
    return empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every file and folder under ``folder`` with its bytes (folders map to None)."""
    return {
        str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(folder.rglob("*"))
    }


def cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return status, out, err


def submit(capsys, root: Path, path: Path, *extra: str) -> tuple[int, str, str]:
    return cli(capsys, "submit", path, "--root", root, *extra)


def records_in(root: Path) -> list[Path]:
    return sorted((root / "records").glob("*.json*"))


# --------------------------------------------------------------------------- the repository's leaderboard


def test_repository_leaderboard_is_valid_and_up_to_date(capsys):
    status, out, err = cli(capsys, "leaderboard", "--check", "--root", REPO_BOARD)
    assert (status, err) == (0, "")
    assert "is valid and up to date" in out


def test_schema_copies_match_the_packaged_schemas():
    for name in SCHEMA_NAMES:
        assert (REPO_BOARD / "schema" / f"{name}.schema.json").read_text(encoding="utf-8") == schema_text(name)


def test_schemas_are_valid_draft_2020_12_and_agree_with_jsonschema(full):
    import jsonschema
    from referencing import Registry, Resource

    registry = Registry().with_resources(
        (load_schema(n)["$id"], Resource.from_contents(load_schema(n))) for n in SCHEMA_NAMES
    )
    for name in SCHEMA_NAMES:
        jsonschema.Draft202012Validator.check_schema(load_schema(name))
    results = small_results()
    jsonschema.Draft202012Validator(load_schema("results-v1"), registry=registry).validate(results)
    bad = copy.deepcopy(results)
    bad["cells"][0]["success_rate"] = -0.5
    assert not jsonschema.Draft202012Validator(load_schema("results-v1"), registry=registry).is_valid(bad)
    record = build_record(results, _fields(results))
    jsonschema.Draft202012Validator(load_schema("record-v1"), registry=registry).validate(record)


# --------------------------------------------------------------------------- results checks


def _fields(results: dict, **kw) -> dict:
    args = dict(name=None, description="", submitter=None, link=None, submitted=SUBMITTED)
    args.update(kw)
    return submission_fields(results, **args)


def test_factory_results_pass_the_checks(full):
    check_results(full)
    check_results(small_results())
    check_results(make_results(robots=("go2",), backends=("mujoco",), terrains=("flat",), levels=(1,), seeds=(0,)))


def test_scores_are_recomputed_from_cells():
    results = small_results()
    # submitted summaries that lie are refused, and scores never read them
    record = build_record(results, _fields(results))
    assert record["track"] == "partial"
    assert record["scores"] == {
        "overall": 0.5625,
        "per_family": {"flat": 0.8125, "stairs": 0.3125},
        "per_backend": {"mujoco": 0.625, "pybullet": 0.5},
        "per_robot": {"go2": 0.5625},
        "sim_to_sim_gap": 0.125,
        "cells": 16,
        "episodes": 64,
    }
    assert record["id"] == record_id(results) and re.fullmatch(r"[0-9a-f]{64}", record["id"])


def test_standard_grid_is_the_main_track_and_extra_cells_do_not_count(full):
    record = build_record(full, _fields(full))
    assert record["track"] == "main"
    assert record["scores"]["cells"] == 5 * 3 * 7 * 3 * 4  # three simulators (protocol 1.3)
    assert sorted(record["scores"]["per_family"]) == sorted(["flat", "rough", "slopes", "stairs", "stones", "gaps", "beams"])
    rates = [c["success_rate"] for c in full["cells"] if c["robot"] in STANDARD_ROBOTS]
    assert record["scores"]["overall"] == pytest.approx(sum(rates) / len(rates), abs=1e-12)
    # a superset of the standard grid is still main, scored on the standard cells only
    bigger = make_results(robots=(*STANDARD_ROBOTS, "anymal_like"), episodes=3, unseen=True)
    big = build_record(bigger, _fields(bigger))
    assert big["track"] == "main"
    assert big["scores"]["cells"] == 1260 and "anymal_like" not in big["scores"]["per_robot"]
    # missing one seed: partial
    fewer = make_results(seeds=(0, 1, 2), episodes=1)
    assert build_record(fewer, _fields(fewer))["track"] == "partial"
    assert main_track_shortfall(fewer["cells"]) == "315 of the standard grid's 1260 cells are missing"
    # every standard cell present but with fewer than STANDARD_EPISODES episodes: partial
    thin = make_results(episodes=STANDARD_EPISODES - 1)
    assert build_record(thin, _fields(thin))["track"] == "partial"
    assert main_track_shortfall(thin["cells"]) == f"1260 standard cells have fewer than {STANDARD_EPISODES} episodes"
    assert main_track_shortfall(full["cells"]) is None


def test_one_backend_has_no_sim_to_sim_gap():
    results = small_results(backends=("mujoco",))
    record = build_record(results, _fields(results))
    assert record["scores"]["sim_to_sim_gap"] is None
    assert record["scores"]["overall"] == 0.625


def _mutate(results: dict, edit) -> dict:
    results = copy.deepcopy(results)
    edit(results)
    return results


def _set(path: str, value):
    def edit(results):
        node = results
        parts = re.findall(r"[^.\[\]]+", path)
        for part in parts[:-1]:
            node = node[int(part)] if part.isdigit() else node[part]
        last = parts[-1]
        if value is _DELETE:
            del node[int(last) if last.isdigit() else last]
        else:
            node[int(last) if last.isdigit() else last] = value
    return edit


_DELETE = object()


def _cell0_successes(results):
    cell = results["cells"][0]
    cell["successes"], cell["success_rate"] = 3, 0.75  # its 4 episode records all succeed


def _drop_episode(results):
    del results["episodes"][0]


def _energy(results):
    results["cells"][0]["mean_energy"] += 1.0


def _summary(results):
    results["summary"][0]["success_rate_mean"] = 0.5


def _duplicate_cell(results):
    results["cells"].append(copy.deepcopy(results["cells"][0]))


def _missing_cell(results):
    del results["cells"][-1]


def _checkpoint_without_sha(results):
    results["policy"]["checkpoint"] = "runs/ppo/model.pt"


# (edit of small_results(), pinned message)
REFUSALS = {
    "wrong schema version": (_set("schema_version", 2), "schema_version: 2 is not supported; this frbench reads results schema_version 1"),
    "schema version as text": (_set("schema_version", "1"), "schema_version: '1' is not supported; this frbench reads results schema_version 1"),
    "missing schema version": (_set("schema_version", _DELETE), "schema_version: required field is missing; expected 1"),
    "unknown protocol": (_set("protocol_version", "9.9"), "protocol_version: unknown protocol version '9.9'; known: 1.0"),
    "missing versions": (_set("versions", _DELETE), "versions: required field is missing"),
    "missing frbench commit": (_set("frbench.git_commit", _DELETE), "frbench.git_commit: required field is missing"),
    "missing simulator version": (_set("versions.mujoco", _DELETE), "versions.mujoco: required field is missing"),
    "missing urdf checksum": (_set("robots.go2.urdf_sha256", _DELETE), "robots.go2.urdf_sha256: required field is missing"),
    "missing seeds": (_set("config.seeds", _DELETE), "config.seeds: required field is missing"),
    "checkpoint without checksum": (_checkpoint_without_sha, "policy.sha256: required when policy.checkpoint is set"),
    "negative rate": (_set("cells[0].success_rate", -0.25), "cells[0].success_rate: -0.25 is below the minimum 0"),
    "rate above one": (_set("cells[0].success_rate", 1.5), "cells[0].success_rate: 1.5 is above the maximum 1"),
    "nan rate": (_set("cells[0].success_rate", float("nan")), "cells[0].success_rate: NaN is not allowed (numbers must be finite)"),
    "infinite energy": (_set("episodes[3].energy", float("inf")), "episodes[3].energy: Infinity is not allowed (numbers must be finite)"),
    "rate as text": (_set("cells[0].success_rate", "1.0"), "cells[0].success_rate: expected number, got string '1.0'"),
    "successes above episodes": (_set("cells[0].successes", 5), "cells[0].successes: 5 successes exceed 4 episodes"),
    "rate contradicts counts": (_set("cells[1].success_rate", 0.5), "cells[1].success_rate: 0.5 differs from successes/episodes = 4/4 = 1"),
    "cell contradicts episodes": (_cell0_successes, "cells[0].successes: 3 but 4 of its 4 episode records succeed"),
    "missing episode record": (_drop_episode, "cells[0].episodes: 4 but 3 episode records have robot=go2 backend=mujoco terrain=flat level=1 seed=0"),
    "mean contradicts episodes": (_energy, "cells[0].mean_energy: "),
    "summary contradicts cells": (_summary, "summary[0].success_rate_mean: 0.5 differs from the mean of its cells' success_rate, 1"),
    "duplicate cell": (_duplicate_cell, "cells[16]: duplicate cell robot=go2 backend=mujoco terrain=flat level=1 seed=0 (also cells[0])"),
    "missing cell": (_missing_cell, "cells: no cell for robot=go2 backend=pybullet terrain=stairs level=5 seed=1, which config lists"),
    "unexpected field": (_set("cells[2].bonus", 1), "cells[2].bonus: unexpected field"),
    "markup in policy name": (_set("policy.name", "<b>x</b>"), "policy.name: '<b>x</b>' does not match the pattern"),
    "markup in robot source": (_set("robots.go2.source", "<img src=x onerror=alert(1)>"), "robots.go2.source: '<img src=x onerror=alert(1)>' does not match the pattern"),
    "path in robot name": (_set("cells[0].robot", "../../go2"), "cells[0].robot: '../../go2' does not match the pattern"),
}


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_submit_refuses_bad_results(case, root, tmp_path, capsys):
    edit, message = REFUSALS[case]
    path = write_results(tmp_path / "results.json", _mutate(small_results(), edit))
    before = snapshot(root)
    status, out, err = submit(capsys, root, path)
    assert status == 2 and out == ""
    assert err.startswith(f"frbench submit: error: {path}: {message}"), err
    assert err.count("\n") == 1
    assert snapshot(root) == before


def test_check_results_raises_results_error_naming_the_field():
    bad = _mutate(small_results(), _set("cells[0].success_rate", -0.25))
    with pytest.raises(ResultsError, match=re.escape("cells[0].success_rate: -0.25 is below the minimum 0")):
        check_results(bad)


def _text(tmp_path: Path, text: str | bytes) -> Path:
    path = tmp_path / "results.json"
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return path


FILE_REFUSALS = {
    "malformed": ('{"schema_version": 1,, }', "not valid JSON at line 1 column 22: Expecting property name enclosed in double quotes"),
    "empty": ("", "file is empty; expected a JSON object"),
    "array": ("[1, 2]", "expected a JSON object at the top level, got array"),
    "duplicate key": ('{"schema_version": 1, "schema_version": 1}', "not valid: the key 'schema_version' appears twice in one object"),
    "not utf-8": (b'{"a": "\xff"}', "not UTF-8 text (byte 7); expected a JSON file"),
    "deep nesting": ('{"schema_version": 1, "config": ' + "[" * 40 + "]" * 40 + "}", "not valid: JSON nested deeper than 32 levels"),
    "bare NaN": ('{"schema_version": NaN}', "schema_version: NaN is not supported; this frbench reads results schema_version 1"),
}


@pytest.mark.parametrize("case", sorted(FILE_REFUSALS))
def test_submit_refuses_bad_files(case, root, tmp_path, capsys):
    text, message = FILE_REFUSALS[case]
    path = _text(tmp_path, text)
    before = snapshot(root)
    status, out, err = submit(capsys, root, path)
    assert (status, out) == (2, "")
    assert err == f"frbench submit: error: {path}: {message}\n"
    assert snapshot(root) == before


def test_submit_refuses_a_truncated_file(root, tmp_path, capsys):
    text = json.dumps(small_results(), indent=1)
    path = _text(tmp_path, text[: len(text) // 2])
    before = snapshot(root)
    status, _, err = submit(capsys, root, path)
    assert status == 2
    assert re.fullmatch(
        rf"frbench submit: error: {re.escape(str(path))}: not valid JSON: the text ends early at line \d+ column \d+ "
        r"with a string, object or array still open; is the file truncated\?\n", err
    ), err
    assert snapshot(root) == before


def test_submit_refuses_a_huge_file_by_size_before_reading(root, tmp_path, capsys, monkeypatch):
    path = tmp_path / "huge.json"
    with open(path, "wb") as handle:  # sparse: 300 MB on paper, nothing on disk
        handle.truncate(300 * 1024 * 1024)
    opened = []
    real_open = open
    monkeypatch.setattr("builtins.open", lambda file, *a, **k: opened.append(file) or real_open(file, *a, **k))
    before = snapshot(root)
    status, _, err = submit(capsys, root, path)
    assert status == 2
    assert err == f"frbench submit: error: {path}: file is 300.0 MB, above the 50.0 MB limit; refusing to read it\n"
    assert str(path) not in map(str, opened)
    assert snapshot(root) == before


def test_submit_refuses_a_missing_file(root, tmp_path, capsys):
    status, _, err = submit(capsys, root, tmp_path / "nope.json")
    assert status == 2 and err == f"frbench submit: error: {tmp_path / 'nope.json'}: no such file\n"


FIELD_REFUSALS = {
    "path name": (["--name", "../../etc/passwd"], "--name: '../../etc/passwd' is not allowed; use 1-64 letters, digits, '.', '_' or '-', starting with a letter or digit"),
    "absolute name": (["--name", "/tmp/x"], "--name: '/tmp/x' is not allowed"),
    "markup name": (["--name", "<script>alert(1)</script>"], "--name: '<script>alert(1)</script>' is not allowed"),
    "long name": (["--name", "x" * 65], "--name: 'xxxxxxxx"),
    "markup description": (["--description", "nice <script>alert(1)</script>"], "--description: '<' is not allowed (plain text only, no markup)"),
    "multi-line description": (["--description", "one\ntwo"], "--description: control or formatting character U+000A is not allowed (one line of plain text)"),
    "bidi description": (["--description", "abc\u202edef"], "--description: control or formatting character U+202E is not allowed"),
    "long description": (["--description", "y" * 281], "--description: is 281 characters long, above the limit of 280"),
    "markup submitter": (["--submitter", "<img src=x onerror=alert(1)>"], "--submitter: '<' is not allowed (plain text only, no markup)"),
    "javascript link": (["--link", "javascript:alert(1)"], "--link: 'javascript:alert(1)' is not allowed; give an http:// or https:// URL"),
    "quoted link": (["--link", 'https://x.org/"onmouseover="alert(1)'], "--link: "),
}


@pytest.mark.parametrize("case", sorted(FIELD_REFUSALS))
def test_submit_refuses_bad_fields(case, root, tmp_path, capsys):
    args, message = FIELD_REFUSALS[case]
    path = write_results(tmp_path / "results.json", small_results())
    before = snapshot(root)
    status, _, err = submit(capsys, root, path, *args)
    assert status == 2
    assert err.startswith(f"frbench submit: error: {message}"), err
    assert err.count("\n") == 1
    assert snapshot(root) == before


# --------------------------------------------------------------------------- submitting


def test_submit_writes_a_record_and_regenerates_the_board(root, tmp_path, capsys):
    results = small_results()
    path = write_results(tmp_path / "results.json", results)
    status, out, err = submit(capsys, root, path, "--name", "go2-scripted", "--submitter", "Ada L.",
                              "--description", "Scripted controller & friends", "--link", "https://example.org/paper?id=1")
    assert (status, err) == (0, "")
    rid = record_id(results)
    assert out.startswith(f"added record {rid[:12]} (go2-scripted, partial track): overall success 0.563, sim-to-sim gap 0.125, 16 cells\n"
                          "partial, not ranked on the main board: 1244 of the standard grid's 1260 cells are missing\n")
    assert [p.name for p in records_in(root)] == [f"{rid}.json.gz"]
    stored = (root / "records" / f"{rid}.json.gz").read_bytes()
    assert stored[:2] == b"\x1f\x8b" and stored[4:8] == b"\0\0\0\0"  # gzip, modification time 0: deterministic
    record = json.loads(gzip.decompress(stored))
    assert record["results"] == results  # kept verbatim, per-episode records included
    assert record["submission"]["name"] == "go2-scripted" and record["submission"]["policy"] == "scripted"
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", record["submission"]["submitted"])
    check_record(record, file_name=f"{rid}.json.gz")
    assert stored == record_bytes(record) and len(stored) < len(record_text(record)) / 4
    readme = (root / "README.md").read_text()
    assert "go2\\-scripted" not in readme and "go2-scripted" in readme
    assert "Scripted controller \\& friends" in readme
    assert f"[{rid[:12]}](records/{rid}.json.gz)" in readme
    assert rid in (root / "index.html").read_text()
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


def test_identical_resubmission_is_refused_even_under_another_name(root, tmp_path, capsys):
    path = write_results(tmp_path / "results.json", small_results())
    assert submit(capsys, root, path, "--name", "first")[0] == 0
    before = snapshot(root)
    status, _, err = submit(capsys, root, path, "--name", "second")
    rid = record_id(small_results())
    assert status == 2
    assert err.startswith(f"frbench submit: error: {path}: these results were already submitted as record {rid[:12]} (")
    assert err.rstrip().endswith("identical resubmissions are refused")
    assert snapshot(root) == before


def test_submit_refuses_a_records_folder_leading_outside(root, tmp_path, capsys):
    outside = tmp_path / "outside"
    outside.mkdir()
    shutil.rmtree(root / "records")
    (root / "records").symlink_to(outside)
    path = write_results(tmp_path / "results.json", small_results())
    status, _, err = submit(capsys, root, path)
    assert status == 2
    assert err == f"frbench submit: error: {root / 'records'} leads outside the leaderboard folder {root}; refusing to write there\n"
    assert list(outside.iterdir()) == []


def test_dry_run_writes_nothing(root, tmp_path, capsys):
    path = write_results(tmp_path / "results.json", small_results())
    before = snapshot(root)
    status, out, _ = submit(capsys, root, path, "--dry-run")
    assert status == 0 and out.startswith("would add record ")
    assert snapshot(root) == before


def test_a_submission_is_refused_while_an_existing_record_is_invalid(root, tmp_path, capsys):
    first = write_results(tmp_path / "a.json", small_results())
    assert submit(capsys, root, first)[0] == 0
    [record_path] = records_in(root)
    edited = gzip.decompress(record_path.read_bytes()).decode().replace('"successes": 4', '"successes": 3', 1)
    record_path.write_bytes(gzip.compress(edited.encode()))
    before = snapshot(root)
    second = write_results(tmp_path / "b.json", small_results(seeds=(7,)))
    status, _, err = submit(capsys, root, second)
    assert status == 2
    assert err.startswith(f"frbench submit: error: cannot add a record while the leaderboard holds an invalid one: {record_path}: results.cells[")
    assert snapshot(root) == before


_CONCURRENT = """
import sys, time
from frbench.cli import main
start = float(sys.argv[1])
while time.time() < start:
    time.sleep(0.0005)
sys.exit(main(sys.argv[2:]))
"""


def _race(root: Path, paths: list[Path]) -> list[subprocess.CompletedProcess]:
    start = time.time() + 1.0
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    procs = [
        subprocess.Popen([sys.executable, "-c", _CONCURRENT, str(start), "submit", str(p), "--root", str(root), "--name", f"racer{i}"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        for i, p in enumerate(paths)
    ]
    return [subprocess.CompletedProcess(p.args, p.wait(60), *p.communicate()) for p in procs]


def test_concurrent_submissions_all_land(root, tmp_path, capsys):
    paths = [write_results(tmp_path / f"r{i}.json", small_results(seeds=(i,))) for i in range(4)]
    done = _race(root, paths)
    assert [d.returncode for d in done] == [0, 0, 0, 0], [d.stderr for d in done]
    ids = sorted(record_id(small_results(seeds=(i,))) for i in range(4))
    assert [p.name[:64] for p in records_in(root)] == ids
    assert not [p for p in (root / "records").iterdir() if p.name.startswith(".incoming")]
    readme = (root / "README.md").read_text()
    assert all(f"racer{i}" in readme for i in range(4))
    assert all(i in (root / "index.html").read_text() for i in ids)
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


def test_concurrent_identical_submissions_land_once(root, tmp_path, capsys):
    path = write_results(tmp_path / "same.json", small_results())
    done = _race(root, [path, path])
    assert sorted(d.returncode for d in done) == [0, 2]
    loser = next(d for d in done if d.returncode == 2)
    assert "identical resubmissions are refused" in loser.stderr
    assert len(records_in(root)) == 1
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


# --------------------------------------------------------------------------- the leaderboard command


@pytest.fixture(scope="module")
def populated_template(tmp_path_factory, full) -> Path:
    """A leaderboard with two main records and one partial one, built once."""
    folder = tmp_path_factory.mktemp("populated")
    root = empty_board_copy(REPO_BOARD, folder / "leaderboard")
    better = make_results(episodes=3, skill=0.95, salt=1, policy="ppo", checkpoint="runs/ppo/model.pt")
    for name, results in (("baseline", full), ("ppo-best", better), ("tiny", small_results())):
        lb.submit(write_results(folder / f"{name}.json", results), root, name=name)
    return root


@pytest.fixture
def populated(populated_template, tmp_path) -> Path:
    root = tmp_path / "leaderboard"
    shutil.copytree(populated_template, root)
    return root


def test_table_ranks_main_records_and_lists_partial_ones(populated, capsys):
    status, out, _ = cli(capsys, "leaderboard", "--root", populated)
    assert status == 0
    lines = out.splitlines()
    assert lines[0] == ("Main board, protocol 1.4: records covering the standard grid, ranked by mean success "
                        "(~: its 95 % interval overlaps the record above) (2 records)")
    assert lines[2].split()[:4] == ["1", "ppo-best", "ppo", "1.4"]
    assert lines[3].split()[:4] == ["2", "baseline", "scripted", "1.4"]
    tiny = next(line for line in lines if line.startswith("tiny ")).split()
    assert tiny[3] == "0.563" and tiny[5] == "0.813" and tiny[7] == "-"  # ties round up, as in the page; overall, flat, rough
    assert tiny[4].startswith("(") and tiny[4].endswith(")")  # the interval beside the score
    assert "Partial records, protocol 1.4 (not ranked against the main board) (1 record)" in lines


def test_json_output_and_filters(populated, capsys):
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "json")
    data = json.loads(out)
    assert status == 0 and [r["name"] for r in data["main"]] == ["ppo-best", "baseline"]
    tiny = data["partial"][0]["scores"]
    assert (tiny["overall"], tiny["sim_to_sim_gap"], tiny["per_family_level"]["stairs"]) == (0.5625, 0.125, {"1": 0.5, "5": 0.125})
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "json", "--backend", "mujoco")
    tiny = json.loads(out)["partial"][0]["scores"]
    assert (tiny["overall"], tiny["sim_to_sim_gap"], tiny["cells"]) == (0.625, None, 8)
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "json", "--terrain", "stairs", "--robot", "go2")
    data = json.loads(out)
    assert data["filters"] == {"robot": "go2", "terrain": "stairs"}
    assert (data["partial"][0]["scores"]["overall"], data["partial"][0]["scores"]["sim_to_sim_gap"]) == (0.3125, 0.125)
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "json", "--robot", "aliengo")
    assert [r["name"] for r in json.loads(out)["main"]] == ["ppo-best", "baseline"] and json.loads(out)["partial"] == []


def test_unknown_filter_values_are_refused(populated, capsys):
    status, _, err = cli(capsys, "leaderboard", "--root", populated, "--robot", "go3")
    assert status == 2 and err.startswith("frbench leaderboard: error: unknown robot 'go3'") and "did you mean 'go2'?" in err
    status, _, err = cli(capsys, "leaderboard", "--root", populated, "--format", "md", "--backend", "mujoco")
    assert status == 2 and err.startswith("frbench leaderboard: error: --backend: filters apply to --format table and json")


def test_md_and_html_regenerate_deterministically(populated, capsys):
    readme, index = (populated / "README.md").read_bytes(), (populated / "index.html").read_bytes()
    (populated / "README.md").unlink()
    (populated / "index.html").write_text("stale")
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "md")
    assert status == 0 and out == f"wrote {populated / 'README.md'}\n"
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "html")
    assert status == 0 and out == f"wrote {populated / 'index.html'}\n"
    assert (populated / "README.md").read_bytes() == readme and (populated / "index.html").read_bytes() == index
    status, out, _ = cli(capsys, "leaderboard", "--root", populated, "--format", "md")
    assert out == f"up to date: {populated / 'README.md'}\n"


def test_check_reports_stale_and_invalid_files(populated, capsys):
    assert cli(capsys, "leaderboard", "--check", "--root", populated)[0] == 0
    readme = populated / "README.md"
    readme.write_text(readme.read_text() + "\nedited by hand\n")
    status, out, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert (status, out) == (1, "")
    assert err == f"frbench leaderboard --check: {readme} is out of date with the records; run `frbench leaderboard --format md` and commit the result\n"
    cli(capsys, "leaderboard", "--format", "md", "--root", populated)
    (populated / "index.html").unlink()
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and "index.html is missing; run `frbench leaderboard --format html`" in err
    cli(capsys, "leaderboard", "--format", "html", "--root", populated)

    def read(path: Path) -> str:
        return gzip.decompress(path.read_bytes()).decode()

    def write(path: Path, text: str) -> None:  # a record edited by hand: unpacked, changed, packed again
        path.write_bytes(gzip.compress(text.encode(), mtime=0))

    record = next(p for p in records_in(populated) if "tiny" in read(p))
    rid = record.name[:64]
    original = read(record)
    write(record, original.replace('"overall": 0.5625', '"overall": 0.9', 1))
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1
    assert err.splitlines()[0] == (f"frbench leaderboard --check: {record}: scores: differ from the scores recomputed "
                                   "from results.cells (overall 0.9 recorded, 0.5625 recomputed)")
    write(record, original.replace('"description": ""', '"description": "<script>alert(1)</script>"', 1))
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: submission.description: '<script>" in err
    write(record, original.replace('"protocol_version": "1.4"', '"protocol_version": "0.9"', 1))
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: results.protocol_version: unknown protocol version '0.9'; known: 1.0, 1.1, 1.2, 1.3, 1.4" in err
    write(record, original.replace('"created": "2026-11-22T01:23:45Z"', '"created": "2026-11-22T01:23:46Z"', 1))
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: id: {rid} is not the sha256 of the record's results (" in err
    write(record, original[:1000])
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: not valid JSON: the text ends early" in err
    record.write_bytes(gzip.compress(original.encode(), mtime=0)[:-100])  # the compressed file cut short
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: the gzip data ends early; is the file truncated?" in err
    record.write_bytes(b"\x1f\x8b" + b"\0" * 40)
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{record}: not a valid gzip file (" in err
    write(record, original)
    renamed = record.with_name("0" * 64 + ".json.gz")
    record.rename(renamed)
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and f"{renamed}: file name: a record with id {rid} must be named {rid}.json.gz" in err
    renamed.rename(record)
    plain = record.with_name(f"{rid}.json")  # the uncompressed form: reported with the command that compresses it
    plain.write_text(original)
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and (f"{plain}: a record stored uncompressed; records are stored as <id>.json.gz: "
                            f"run `gzip -9n {plain}` (or submit its results again)") in err
    plain.unlink()
    (populated / "records" / ".incoming-x.tmp").write_text("{}")
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", populated)
    assert status == 1 and "records/.incoming-x.tmp: not a record" in err
    (populated / "records" / ".incoming-x.tmp").unlink()
    assert cli(capsys, "leaderboard", "--check", "--root", populated)[0] == 0


def test_root_comes_from_option_env_or_checkout(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert default_root() == REPO_BOARD  # source checkout
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "elsewhere"))
    assert default_root() == tmp_path / "elsewhere"
    status, _, err = cli(capsys, "leaderboard")
    assert status == 2
    assert err == (f"frbench leaderboard: error: leaderboard folder {tmp_path / 'elsewhere'} does not exist; run frbench "
                   f"from a clone of the frbench repository, pass --root DIR or set {ENV_VAR}\n")
    shutil.copytree(REPO_BOARD, tmp_path / "elsewhere")
    assert cli(capsys, "leaderboard", "--check")[0] == 0


# --------------------------------------------------------------------------- rendering is inert


def _hostile_record() -> dict:
    results = small_results()
    record = build_record(results, _fields(results))
    record["submission"]["name"] = "x</script><script>alert(1)</script>"  # bypasses submit's checks on purpose
    record["submission"]["description"] = "<img src=x onerror=alert(2)> & [click](javascript:alert(3)) | `code`"
    record["submission"]["submitter"] = "<b>bold</b>"
    return record


def test_hostile_text_is_escaped_in_html_and_markdown():
    record = _hostile_record()
    html = render_html([record])
    assert "<script>alert" not in html and "<img" not in html and "<b>bold" not in html
    assert html.count("<script") == 2  # the data block and the page script
    block = re.search(r'<script type="application/json" id="leaderboard-data">(.*?)</script>', html, re.S).group(1)
    data = json.loads(block)
    assert data["records"][0]["name"] == record["submission"]["name"]
    assert data["records"][0]["description"] == record["submission"]["description"]
    readme = render_markdown([record])
    assert not re.search(r"(?<!\\)<(img|script|b)", readme) and not re.search(r"(?<!\\)\]\(javascript", readme)
    assert "\\<img src=x onerror=alert(2)\\> \\& \\[click\\](javascript:alert(3)) \\| \\`code\\`" in readme
    assert md_escape("a|b<c>[d](e)") == "a\\|b\\<c\\>\\[d\\](e)"
    assert script_json({"s": "</script>&"}) == '{"s":"\\u003c/script\\u003e\\u0026"}'


def test_page_is_self_contained():
    html = render_html([_hostile_record()])
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", html)  # no network resources
    assert "innerHTML" not in html and "eval(" not in html
    csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]+)"', html).group(1)
    assert "default-src 'none'" in csp and "script-src 'sha256-" in csp


def test_empty_board_renders():
    readme = render_markdown([])
    assert readme.count("_No records yet._") == 3 and "_None._" in readme  # main board, humanoid track, records
    data = page_data([])
    assert data["records"] == [] and data["families"] == ["flat", "rough", "slopes", "stairs", "stones", "gaps", "beams"]
    assert render_html([]) == render_html([])  # deterministic: no timestamps


# --------------------------------------------------------------------------- odds and ends


def test_pretty_json_round_trips_and_is_line_per_cell():
    results = small_results()
    text = pretty_json(results)
    assert json.loads(text) == results
    assert len(text.splitlines()) < 200  # 16 cells + 64 episodes, one line each
    assert canonical_json({"b": 1, "a": [1.5, "é"]}) == '{"a":[1.5,"\\u00e9"],"b":1}'


def test_validator_messages():
    with pytest.raises(ResultsError, match=re.escape("config.levels[1]: 11 is above the maximum 10")):
        validate(_mutate(small_results(), _set("config.levels", [1, 11])), "results-v1")
    with pytest.raises(ResultsError, match=re.escape("config.seeds[1]: 0 repeats config.seeds[0]")):
        validate(_mutate(small_results(), _set("config.seeds", [0, 0])), "results-v1")
    with pytest.raises(ResultsError, match=re.escape("cells[0].mean_time_to_recover: -1 is below the minimum 0")):
        validate(_mutate(small_results(), _set("cells[0].mean_time_to_recover", -1)), "results-v1")
    with pytest.raises(ResultsError, match=re.escape("policy.sha256: expected string or null, got integer")):
        validate(_mutate(small_results(), _set("policy.sha256", 5)), "results-v1")
    with pytest.raises(ResultsError, match=re.escape("cells[0].success: ")):
        validate(_mutate(small_results(), _set("cells[0].success", True)), "results-v1")


# --------------------------------------------------------------------------- protocol versions and intervals


def test_records_of_another_protocol_version_are_archived_not_ranked(tmp_path, capsys):
    root = empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")
    old = make_results(episodes=3, skill=0.95, salt=3, protocol_version="1.0")
    lb.submit(write_results(tmp_path / "old.json", old), root, name="old-but-better")
    lb.submit(write_results(tmp_path / "new.json", make_results(episodes=3, skill=0.5, salt=4)), root, name="current")
    status, out, _ = cli(capsys, "leaderboard", "--root", root, "--format", "json")
    data = json.loads(out)
    assert status == 0 and data["protocol_version"] == "1.4"
    assert [r["name"] for r in data["main"]] == ["current"] and data["main"][0]["rank"] == 1
    assert [r["name"] for r in data["archived"]] == ["old-but-better"]
    assert data["archived"][0]["rank"] == 1 and data["archived"][0]["protocol_version"] == "1.0"  # within 1.0 only
    low, high = data["main"][0]["intervals"]["overall"]
    assert low < data["main"][0]["scores"]["overall"] < high
    readme = (root / "README.md").read_text()
    assert "## Archived records (earlier protocol versions, superseded records)" in readme and "| old-but-better | scripted | anonymous | 1.0 |" in readme


def test_ranking_refuses_to_mix_protocol_versions():
    from frbench.errors import FrbenchError
    from frbench.leaderboard.scores import check_same_protocol

    assert check_same_protocol(["1.1", "1.1"]) == "1.1"
    with pytest.raises(FrbenchError, match="refusing to rank records of protocol versions 1.0, 1.1 together"):
        check_same_protocol(["1.1", "1.0"])


def test_neighbours_with_overlapping_intervals_are_marked(tmp_path, capsys):
    root = empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")
    for name, skill, salt in (("a", 0.60, 5), ("b", 0.59, 6), ("c", 0.05, 7)):
        lb.submit(write_results(tmp_path / f"{name}.json", make_results(episodes=3, skill=skill, salt=salt)), root, name=name)
    data = json.loads(cli(capsys, "leaderboard", "--root", root, "--format", "json")[1])
    marks = {r["name"]: r["tied_above"] for r in data["main"]}
    order = [r["name"] for r in data["main"]]
    assert order[2] == "c" and marks["c"] is False  # far below: its order is established
    assert marks[order[1]] is True  # a and b: within each other's intervals
    lines = cli(capsys, "leaderboard", "--root", root)[1].splitlines()
    assert lines[3].split()[0] == "2~" and lines[4].split()[0] == "3"
