"""Fuzzing command-line values: levels, seeds, episodes, names, submission fields, filters, sample sizes.

Values mix valid tokens with random text and numbers (negative, huge, non-numeric, empty, lists with gaps).
``frbench evaluate`` is checked up to the point where its grid would run: `run_grid` is replaced by a stand-in
that records the request and stops, so a valid request is accepted without simulating hours of episodes.
Every case gives a valid result or one line on stderr with exit status 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from hypothesis import event, given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_support import FRBENCH_DIRS, assert_clean, fuzz_settings, outcome, sandbox, snapshot  # noqa: E402
from results_factory import empty_board_copy, small_results, write_results  # noqa: E402

SMOKE, SLOW_EVALUATE, SLOW_OTHERS = 10, 2000, 1500
REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"

numbers = st.one_of(st.integers(-5, 12), st.integers(-2**70, 2**70), st.floats().map(repr))
tokens = st.one_of(
    numbers.map(str),
    st.sampled_from(["go2", "go1", "g1", "spot_like", "mujoco", "pybullet", "flat", "stairs", "gaps", "scripted", "zero",
                     "frnet", "local", "ray", "", " ", ",", "../go2", "go2.urdf", "-1", "1e3", "0x10", "nan"]),
    st.text(max_size=12),
)
lists = st.lists(tokens, max_size=4).map(",".join)


class Accepted(Exception):
    """Raised by the stand-in for `run_grid`: the request passed every check."""


@pytest.fixture(scope="module")
def board(tmp_path_factory) -> Path:
    """A leaderboard with one record (small_results, named 'probe')."""
    from frbench.leaderboard import board as lb

    root = empty_board_copy(REPO_BOARD, tmp_path_factory.mktemp("board") / "leaderboard")
    lb.submit(write_results(tmp_path_factory.mktemp("r") / "r.json", small_results()), root, name="probe")
    return root


@pytest.fixture
def grid_stops(monkeypatch):
    import frbench.evaluation.grid as grid

    def stop(request, progress=None):
        raise Accepted(request)
    monkeypatch.setattr(grid, "run_grid", stop)


evaluate_options = st.dictionaries(
    st.sampled_from(["--levels", "--seeds", "--episodes", "--robots", "--terrains", "--backends", "--policy",
                     "--executor", "--jobs"]),
    st.one_of(lists, tokens), min_size=1, max_size=4)


def _evaluate_property(options: dict) -> None:
    argv = ["evaluate", "--robots", "go2", "--backends", "mujoco", "--terrains", "flat", "--out", "out.json"]
    for option, value in options.items():
        argv += [f"{option}={value}"]
    with sandbox() as root:
        before = snapshot(root, FRBENCH_DIRS)
        try:
            result = outcome(*argv)
        except Accepted as accepted:
            request = accepted.args[0]
            assert all(1 <= level <= 10 for level in request.levels) and request.episodes >= 1 and request.seeds
            event("evaluate accepted")
            return
        assert_clean(result, before, root, label="evaluate")
        assert result.status == 2, result.out


def _others_property(board: Path, case: tuple) -> None:
    command, values = case
    with sandbox(board) as root:
        results = write_results(root / "results.json", small_results(seeds=(7,)))
        record = next((root / "leaderboard" / "records").glob("*.json.gz"))
        argv = {
            "submit": lambda v: ["submit", results, "--dry-run", "--name", v[0], "--description", v[1],
                                 "--submitter", v[2], "--link", v[3]],
            "leaderboard": lambda v: ["leaderboard", "--format", v[0] or "table", *(["--robot", v[1]] if v[1] else []),
                                      *(["--backend", v[2]] if v[2] else []), *(["--terrain", v[3]] if v[3] else [])],
            "verify": lambda v: ["verify", v[0] if v[1] == "id" else record, "--sample", v[2], "--seed", v[3]],
            "spec": lambda v: ["spec", "--robot", v[0], *(["--json"] if v[1] else [])],
            "robot check": lambda v: ["robot", "check", v[0], "--seed", v[1]],
        }[command](values)
        before = snapshot(root, FRBENCH_DIRS)
        result = outcome(*argv)
        assert_clean(result, before, root, failing=command in ("verify", "robot check"), label=command)
        if command == "leaderboard" and result.status == 0 and values[0] == "json":
            assert json.loads(result.out)["partial"][0]["name"] == "probe"


def _at_most_two(text: str) -> bool:
    try:
        return int(text) <= 2
    except ValueError:
        return True


texts = st.text(max_size=40)
#: --sample values that re-run at most two episodes when valid (each re-run simulates a cell)
samples = st.one_of(st.integers(-3, 2).map(str), st.integers(-2**64, 0).map(str), tokens.filter(_at_most_two))
small_ints = st.one_of(st.integers(-3, 2).map(str), st.integers(-2**64, 2**64).map(str), tokens)
others = st.one_of(
    st.tuples(st.just("submit"), st.tuples(st.one_of(tokens, st.from_regex(r"[A-Za-z0-9][A-Za-z0-9._-]{0,70}", fullmatch=True)),
                                           texts, texts, st.one_of(texts, st.sampled_from(["https://example.org/x", "http://a.b:80/", "ftp://x"])))),
    st.tuples(st.just("leaderboard"), st.tuples(st.sampled_from(["table", "json", "md", "html", "", "xml"]), tokens, tokens, tokens)),
    st.tuples(st.just("verify"), st.tuples(tokens, st.sampled_from(["id", "file"]), samples, small_ints)),
    st.tuples(st.just("spec"), st.tuples(st.one_of(tokens, st.sampled_from(["go2", "g1", "aliengo"])), st.booleans())),
    st.tuples(st.just("robot check"), st.tuples(st.one_of(st.text(max_size=12), st.sampled_from(["nothing", "g0", "go22"])), small_ints)),
)


@fuzz_settings(SMOKE)
@given(evaluate_options)
def test_evaluate_values_smoke(grid_stops, options):
    _evaluate_property(options)


@fuzz_settings(SMOKE)
@given(others)
def test_other_values_smoke(board, case):
    _others_property(board, case)


@pytest.mark.slow
@fuzz_settings(SLOW_EVALUATE)
@given(evaluate_options)
def test_evaluate_values(grid_stops, options):
    _evaluate_property(options)


@pytest.mark.slow
@fuzz_settings(SLOW_OTHERS)
@given(others)
def test_other_values(board, case):
    _others_property(board, case)
