"""`frbench verify` of a foreign policy (ONNX) whose episodes differ by processor: the statistical check.

The processor dependence is imitated by editing the record: a last-bit change of a metric (what another
processor's float32 kernels give) must leave the record "consistent, not verified"; outcomes the policy does
not produce (every episode of a cell claimed a success it never has) must make it inconsistent.
"""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path

import pytest

from frbench.cli import main
from frbench.evaluation.results import aggregate_cells, sim_to_sim, summarize
from frbench.leaderboard import board as lb
from frbench.leaderboard.records import load_record
from frbench.leaderboard.verify import STATISTICAL_ALPHA, poisson_binomial_p_value

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_factory import empty_board_copy  # noqa: E402

REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"


def test_the_poisson_binomial_p_value_by_hand():
    assert poisson_binomial_p_value([0.5, 0.5], 1) == pytest.approx(1.0)
    assert poisson_binomial_p_value([0.5, 0.5], 2) == pytest.approx(0.5)  # P(0) + P(2)
    assert poisson_binomial_p_value([1.0, 1.0, 1.0], 0) == 0.0
    assert poisson_binomial_p_value([0.9, 0.9, 0.9, 0.9], 0) == pytest.approx(1e-4)  # 0.1^4: only 0 is as unlikely
    assert STATISTICAL_ALPHA == 1e-3


@pytest.fixture(scope="module")
def foreign(tmp_path_factory) -> tuple[Path, dict]:
    """(ONNX file, its results on go2 MuJoCo flat level 1 seed 0, 2 episodes)."""
    from policy_factory import export_onnx, mlp

    folder = tmp_path_factory.mktemp("foreign")
    onnx = export_onnx(mlp(seed=5), folder / "foreign.onnx")
    out = folder / "results.json"
    status = main(["evaluate", "--policy", str(onnx), "--robots", "go2", "--backends", "mujoco", "--terrains", "flat",
                   "--levels", "1", "--seeds", "0", "--episodes", "2", "--jobs", "1", "--out", str(out)])
    assert status == 0
    return onnx, json.loads(out.read_text())


def _submit_edited(tmp_path: Path, onnx: Path, results: dict, edit) -> Path:
    results = copy.deepcopy(results)
    edit(results["episodes"])
    results["cells"] = aggregate_cells(results["episodes"])
    results["summary"] = summarize(results["cells"])
    results["sim_to_sim"] = sim_to_sim(results["summary"])
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(results))
    root = empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")
    return lb.submit(path, root, name="foreign", policy_file=onnx).path


def _verify(capsys, record: Path, *extra) -> tuple[int, str]:
    status = main(["verify", str(record), "--sample", "2", *extra])
    return status, capsys.readouterr().out


def test_last_bit_differences_are_reproduced_and_larger_ones_only_consistent(foreign, tmp_path, capsys):
    onnx, results = foreign

    def nudge(episodes):  # what another processor's float32 kernels could do to a metric
        episodes[0]["energy"] = episodes[0]["energy"] * (1 + 1e-12)

    (tmp_path / "last-bit").mkdir()
    record = _submit_edited(tmp_path / "last-bit", onnx, results, nudge)
    status, out = _verify(capsys, record, "--save")
    assert status == 0, out
    assert "verified, tier reproduced: 2 of 2 sampled episodes reproduced within 1e-06 relative" in out
    assert load_record(record)["verifications"][0]["tier"] == "reproduced"

    def shift(episodes):  # beyond the tolerance, the outcomes unchanged: a chaotic episode gone elsewhere
        episodes[0]["energy"] = episodes[0]["energy"] * (1 + 1e-3)

    (tmp_path / "shifted").mkdir()
    record = _submit_edited(tmp_path / "shifted", onnx, results, shift)
    status, out = _verify(capsys, record, "--save")
    assert status == 0, out
    assert "cannot be verified bit for bit here" in out and "statistical check:" in out
    assert "tier consistent: consistent with its re-run episodes but NOT verified" in out and "nothing written" in out
    assert "verifications" not in load_record(record)


def test_outcomes_the_policy_never_produces_are_inconsistent(foreign, tmp_path, capsys):
    onnx, results = foreign
    if any(e["success"] for e in results["episodes"]):
        pytest.skip("this network recovers in the cell; the check needs a cell it never recovers in")

    def claim_success(episodes):
        for episode in episodes:
            episode["success"], episode["time_to_recover"] = True, 1.0

    record = _submit_edited(tmp_path, onnx, results, claim_success)
    status, out = _verify(capsys, record)
    assert status == 1, out
    assert "statistical check: 0 of 2 re-run episodes succeeded where the record's cells predict 2.00 (p = 0 < 0.001)" in out
