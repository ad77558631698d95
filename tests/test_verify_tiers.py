"""`frbench verify`'s tiers (exact, reproduced, consistent, failed) and the processors it names.

A real one-cell record of the built-in `scripted` policy (go2, MuJoCo, flat, level 1, seed 0, 2 episodes),
submitted to a temporary board, then edited the way a cheat would (everything recomputed so that the record
checks): one episode's energy moved by 1e-3 relative must fail; a move of 1e-7 relative (what another
processor's kernels could do) is "reproduced", with the largest deviation printed.
"""

from __future__ import annotations

import json
import socket
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_factory import empty_board_copy  # noqa: E402
from test_verify import _rebuilt, _replace, cli, evaluate, submitted  # noqa: E402

from frbench.evaluation.provenance import processor_info, processor_label  # noqa: E402
from frbench.leaderboard.records import load_record  # noqa: E402
from frbench.leaderboard.verify import REPRODUCED_TOLERANCE, largest_deviation  # noqa: E402

REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"


@pytest.fixture(scope="module")
def scripted() -> dict:
    return evaluate("scripted")


@pytest.fixture
def root(tmp_path: Path) -> Path:
    return empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")


def _energy_scaled(capsys, root, tmp_path, results, factor: float) -> Path:
    """The record of ``results`` with episode 1's energy times ``factor``, recomputed so that it checks."""
    path = submitted(capsys, root, tmp_path, results, None)
    original = load_record(path)

    def edit(edited):
        edited["episodes"][1]["energy"] *= factor
    return _replace(root, path, _rebuilt(results, original["submission"], edit))


def test_an_honest_record_is_exact_and_both_processors_are_named(capsys, root, tmp_path, scripted):
    assert scripted["processor"] == processor_info()
    path = submitted(capsys, root, tmp_path, scripted, None)
    status, out, _ = cli(capsys, "verify", path, "--sample", 2, "--save")
    assert status == 0, out
    here = processor_label(processor_info())
    assert f"processor: the record's {here}; this run's {here}" in out
    assert "largest deviation of a metric: 0 relative" in out
    assert "record " in out and "verified, tier exact: 2 of 2 sampled episodes reproduced bit for bit" in out
    (entry,) = load_record(path)["verifications"]
    assert (entry["tier"], entry["largest_deviation"], entry["processor"]) == ("exact", 0.0, processor_info())
    assert "tolerance" not in entry
    readme = (root / "README.md").read_text()
    assert "2 exact" in readme and f"(bit-identical) on {processor_label(processor_info())}" in readme.replace("\\", "")


def test_a_metric_edited_by_1e_3_relative_is_refused(capsys, root, tmp_path, scripted):
    path = _energy_scaled(capsys, root, tmp_path, scripted, 1 + 1e-3)
    status, out, _ = cli(capsys, "verify", path, "--sample", 2, "--save")
    energy = scripted["episodes"][1]["energy"]
    assert status == 1
    assert f"mismatch: go2 mujoco flat level 1 seed 0 episode 1: energy {energy * (1 + 1e-3)!r} -> {energy!r}" in out
    assert "does NOT verify, tier failed" in out
    assert "largest deviation of a metric: 0.000999 relative (energy, go2 mujoco flat level 1 seed 0 episode 1)" in out
    assert "verifications" not in load_record(path)


def test_a_metric_within_the_tolerance_is_reproduced_with_its_largest_deviation(capsys, root, tmp_path, scripted):
    path = _energy_scaled(capsys, root, tmp_path, scripted, 1 + 1e-7)
    status, out, _ = cli(capsys, "verify", path, "--sample", 2, "--save")
    assert status == 0, out
    assert "largest deviation of a metric: 1e-07 relative (energy, go2 mujoco flat level 1 seed 0 episode 1)" in out
    assert f"verified, tier reproduced: 2 of 2 sampled episodes reproduced within {REPRODUCED_TOLERANCE:g} relative" in out
    (entry,) = load_record(path)["verifications"]
    assert (entry["tier"], entry["tolerance"], entry["mode"]) == ("reproduced", REPRODUCED_TOLERANCE, "exact")
    assert entry["largest_deviation"] == pytest.approx(1e-7, rel=1e-6)
    assert "2 reproduced" in (root / "README.md").read_text()
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


def test_a_record_without_a_processor_says_so(capsys, root, tmp_path, scripted):
    older = {k: v for k, v in scripted.items() if k != "processor"}  # results made before processors were recorded
    path = submitted(capsys, root, tmp_path, older, None)
    status, out, _ = cli(capsys, "verify", path, "--sample", 1)
    assert status == 0 and "processor: the record's not recorded; this run's " in out


def test_the_processor_names_vendor_model_and_extensions_but_no_host():
    info = processor_info()
    assert set(info) == {"vendor", "model", "architecture", "vector_extensions"}
    assert info["vendor"] and info["model"] and info["architecture"]
    host = socket.gethostname()
    if len(host) >= 4:
        assert host not in json.dumps(info)
    assert largest_deviation({"energy": 100.0, "success": True}, {"energy": 100.5, "success": False}) == \
        pytest.approx((0.5 / 100.5, "energy"))
