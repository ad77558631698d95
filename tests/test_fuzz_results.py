"""Fuzzing results files and leaderboard records through the CLI.

Results: a valid, self-consistent results object (`results_factory.small_results`) with 1-3 random edits at
random places (a value replaced by any JSON value, NaN and infinities included; a field removed or added),
or its text cut short or spliced, read by ``frbench submit`` (with and without ``--dry-run``), ``compare``
and ``plot-results``. Records: a valid record likewise edited (submission fields, scores, id, the attached
policy file and verifications too), stored as frbench stores records (gzip, ``records/<id>.json.gz``) in a
temporary board and read by ``frbench leaderboard --check``, ``leaderboard --format json`` and ``verify``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib.font_manager  # noqa: F401  (its font cache is read before HOME moves into a sandbox)
import pytest
from hypothesis import given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_support import FRBENCH_DIRS, assert_clean, fuzz_settings, outcome, sandbox, snapshot  # noqa: E402
from results_factory import empty_board_copy, small_results  # noqa: E402

from frbench.leaderboard.jsonfile import gzip_bytes, pretty_json  # noqa: E402
from frbench.leaderboard.records import build_record, submission_fields  # noqa: E402

SMOKE, SLOW_RESULTS, SLOW_RECORDS = 8, 2500, 1500
pytestmark = pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")  # reprs of large documents
REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"

json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-2**40, 2**40), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20), st.sampled_from(["go2", "mujoco", "flat", "1.1", "0" * 64, "scripted", "", "../x"]),
)
json_values = st.recursive(json_scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                                 st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                           max_leaves=10)


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _paths(value, prefix + (key,))
    elif isinstance(doc, list):
        for index, value in enumerate(doc):
            yield from _paths(value, prefix + (index,))


@st.composite
def edited(draw, doc: dict) -> str:
    """``doc`` with random edits, as JSON text (NaN allowed), sometimes cut short or spliced."""
    doc = json.loads(json.dumps(doc))
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        path = draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "replace", "remove", "add"]))
        if action == "replace":
            parent[path[-1]] = draw(json_values)
        elif action == "remove":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(max_size=12))] = draw(json_values)
        else:
            parent.append(draw(json_values))
    text = json.dumps(doc)
    corruption = draw(st.sampled_from(["none"] * 6 + ["cut", "splice"]))
    if corruption == "cut":
        text = text[: draw(st.integers(0, len(text)))]
    elif corruption == "splice":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(st.text(max_size=8)) + text[at:]
    return text


RESULTS = small_results()
RECORD = build_record(RESULTS, submission_fields(RESULTS, name="fuzz", description="a record", submitter="fuzzer",
                                                 link=None, submitted="2026-11-22T02:00:00Z"))
COMMANDS = {
    "submit --dry-run": lambda f: ("submit", f, "--dry-run"),
    "submit": lambda f: ("submit", f, "--name", "fuzzed"),
    "compare": lambda f: ("compare", f),
    "plot-results": lambda f: ("plot-results", f, "--out", "plots"),
}


@pytest.fixture(scope="module")
def empty_board(tmp_path_factory) -> Path:
    return empty_board_copy(REPO_BOARD, tmp_path_factory.mktemp("board") / "leaderboard")


def _results_property(board: Path, text: str, command: str):
    with sandbox(board) as root:
        path = root / "results.json"
        path.write_text(text, encoding="utf-8")
        before = snapshot(root, FRBENCH_DIRS)
        result = outcome(*COMMANDS[command](path))
        assert_clean(result, before, root, outputs=("plots",), label=command)
        if result.status == 2:
            assert str(path) in result.err, result.err
    return result


def _records_property(board: Path, text: str, named_by_id: bool, command: str):
    with sandbox(board) as root:
        try:
            name = json.loads(text)["id"] if named_by_id else RECORD["id"]
        except (ValueError, TypeError, KeyError, IndexError):
            name = RECORD["id"]
        path = root / "leaderboard" / "records" / f"{name if isinstance(name, str) and name.isalnum() else RECORD['id']}.json.gz"
        path.write_bytes(gzip_bytes(text.encode("utf-8")))
        before = snapshot(root, FRBENCH_DIRS)
        argv = {"check": ("leaderboard", "--check"), "json": ("leaderboard", "--format", "json"),
                "verify": ("verify", path, "--sample", "1")}[command]
        result = outcome(*argv)
        assert_clean(result, before, root, failing=command in ("check", "verify"), label=command)
    return result


results_cases = st.tuples(edited(RESULTS), st.sampled_from(sorted(COMMANDS)))
record_cases = st.tuples(edited(RECORD), st.booleans(), st.sampled_from(["check"] * 4 + ["json"] * 3 + ["verify"]))


@fuzz_settings(SMOKE)
@given(results_cases)
def test_generated_results_files_smoke(empty_board, case):
    _results_property(empty_board, *case)


@fuzz_settings(SMOKE)
@given(record_cases)
def test_generated_records_smoke(empty_board, case):
    _records_property(empty_board, *case)


@pytest.mark.slow
@fuzz_settings(SLOW_RESULTS)
@given(results_cases)
def test_generated_results_files(empty_board, case):
    _results_property(empty_board, *case)


@pytest.mark.slow
@fuzz_settings(SLOW_RECORDS)
@given(record_cases)
def test_generated_records(empty_board, case):
    _records_property(empty_board, *case)


def test_the_unedited_documents_are_valid(empty_board):
    """The generators start from documents every command accepts."""
    assert _results_property(empty_board, json.dumps(RESULTS), "submit").status == 0
    assert _results_property(empty_board, json.dumps(RESULTS), "plot-results").status == 0
    listed = _records_property(empty_board, pretty_json(RECORD), True, "json")
    assert listed.status == 0 and json.loads(listed.out)["partial"][0]["name"] == "fuzz"
