"""Records that carry their policy (`frbench submit --policy-file`) and `frbench verify`.

Records here are real: a one-cell grid (go2, MuJoCo, flat, level 1, seed 0, 2 episodes) evaluated with a
shipped checkpoint or a built-in policy, submitted to a temporary board, then tampered with the way a
cheat would: episodes edited (and everything recomputed so the record checks), the policy file swapped
(with and without fixing up its hash), or episodes run under other protocol rules.
"""

from __future__ import annotations

import copy
import gzip
import json
import shutil
import sys
from pathlib import Path

import pytest

from frbench.cli import main
from frbench.evaluation.grid import EvaluationRequest, build_results, run_grid, validate
from frbench.evaluation.results import aggregate_cells, sim_to_sim, summarize
from frbench.io import sha256_file
from frbench.leaderboard import board as lb
from frbench.leaderboard import policy_files
from frbench.leaderboard.policy_files import MAX_POLICY_BYTES
from frbench.leaderboard.records import build_record, load_record, record_text, write_record
from frbench.leaderboard.render import page_data, render_table
from frbench.leaderboard.verify import RELATIVE_TOLERANCE, compare_episode, sample_indices
from frbench.policies.registry import shipped_checkpoint

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_factory import empty_board_copy  # noqa: E402

REPO_BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
GRID = dict(robots=["go2"], backends=["mujoco"], terrains=["flat"], levels=[1], seeds=[0], episodes=2, jobs=1)


def evaluate(policy: str) -> dict:
    request = EvaluationRequest(policy=policy, **GRID)
    return build_results(request, validate(request), run_grid(request))


@pytest.fixture(scope="module")
def policies(tmp_path_factory) -> dict[str, Path]:
    """Checkpoints of one's own: shipped ones loaded and saved again, so their bytes (and sha256) are not shipped."""
    import torch

    folder = tmp_path_factory.mktemp("policies")
    out = {}
    for name in ("frnet-3m", "ppo-3m"):
        out[name] = folder / f"{name}.pt"
        torch.save(torch.load(shipped_checkpoint(name), weights_only=False), out[name])
        assert sha256_file(out[name]) != sha256_file(shipped_checkpoint(name))
    return out


@pytest.fixture(scope="module")
def honest(policies) -> dict:
    """Results of the frnet-3m checkpoint on the one-cell grid."""
    return evaluate(str(policies["frnet-3m"]))


@pytest.fixture
def root(tmp_path: Path) -> Path:
    return empty_board_copy(REPO_BOARD, tmp_path / "leaderboard")


def cli(capsys, *args) -> tuple[int, str, str]:
    status = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return status, out, err


def write(path: Path, results: dict) -> Path:
    path.write_text(json.dumps(results), encoding="utf-8")
    return path


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None for p in sorted(folder.rglob("*"))}


def submitted(capsys, root: Path, tmp_path: Path, results: dict, policy: Path | None) -> Path:
    extra = ["--policy-file", policy] if policy else []
    status, out, err = cli(capsys, "submit", write(tmp_path / "results.json", results), "--root", root, *extra)
    assert (status, err) == (0, ""), err
    return next((root / "records").glob("*.json.gz"))


def verify(capsys, record: Path, *extra) -> tuple[int, str, str]:
    return cli(capsys, "verify", record, "--sample", 2, *extra)


# --------------------------------------------------------------------------- submit --policy-file


def test_the_policy_file_is_stored_by_its_sha256_and_the_board_shows_it(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, policies["frnet-3m"])
    record = load_record(path)
    sha = sha256_file(policies["frnet-3m"])
    assert record["policy_file"] == {"sha256": sha, "bytes": policies["frnet-3m"].stat().st_size, "file": f"policies/{sha}.pt"}
    assert (root / "policies" / f"{sha}.pt").read_bytes() == policies["frnet-3m"].read_bytes()
    assert record["id"] == json.loads(record_text(build_record(honest, record["submission"])))["id"]  # id: results only
    assert f"[{sha[:12]}](policies/{sha}.pt)" in (root / "README.md").read_text()
    assert page_data([record])["records"][0]["policy_file"] == f"policies/{sha}.pt"
    assert "  yes  " in render_table([record])
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


def test_an_oversize_policy_file_is_refused_before_reading_and_nothing_is_written(capsys, root, tmp_path, honest):
    big = tmp_path / "big.pt"
    with open(big, "wb") as handle:  # sparse: 16 MiB + 1 byte without writing them
        handle.truncate(MAX_POLICY_BYTES + 1)
    before = snapshot(root)
    status, out, err = cli(capsys, "submit", write(tmp_path / "r.json", honest), "--root", root, "--policy-file", big)
    assert (status, out) == (2, "")
    assert err == f"frbench submit: error: --policy-file: {big} is 16.0 MiB, above the 16.0 MiB limit of an attached policy\n"
    assert snapshot(root) == before


@pytest.mark.parametrize("case", ["other checkpoint", "built-in policy", "directory", "missing", "odd suffix"])
def test_a_policy_file_that_cannot_be_the_results_policy_is_refused(case, capsys, root, tmp_path, policies, honest):
    results, policy = honest, policies["ppo-3m"]
    expected = "is not the checkpoint these results were evaluated with"
    if case == "built-in policy":
        results = copy.deepcopy(honest)
        results["policy"] = {"name": "scripted", "checkpoint": None, "sha256": None}
        expected = "built-in policy 'scripted'"
    elif case == "directory":
        policy, expected = tmp_path, "is a directory"
    elif case == "missing":
        policy, expected = tmp_path / "absent.pt", "no such file"
    elif case == "odd suffix":
        policy = tmp_path / "policy.p t"
        policy.write_bytes(b"x")
        expected = "suffix '.p t' is not allowed"
    before = snapshot(root)
    status, out, err = cli(capsys, "submit", write(tmp_path / "r.json", results), "--root", root, "--policy-file", policy)
    assert (status, out) == (2, "") and err.count("\n") == 1 and expected in err, err
    assert snapshot(root) == before


def test_a_policy_file_is_attached_to_results_already_on_the_board_once(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, None)
    status, out, err = cli(capsys, "submit", tmp_path / "results.json", "--root", root, "--policy-file", policies["frnet-3m"])
    assert status == 0 and out.startswith("attached policies/") and sorted((root / "records").glob("*.json*")) == [path]
    assert load_record(path)["policy_file"]["sha256"] == sha256_file(policies["frnet-3m"])
    status, _, err = cli(capsys, "submit", tmp_path / "results.json", "--root", root, "--policy-file", policies["frnet-3m"])
    assert status == 2 and "carries a policy file already" in err


def test_a_shipped_checkpoint_is_referred_to_by_its_hash_not_stored_again(capsys, root, tmp_path, monkeypatch):
    shipped = shipped_checkpoint("frnet-3m")
    results = evaluate(str(shipped))
    status, out, err = cli(capsys, "submit", write(tmp_path / "results.json", results), "--root", root,
                           "--policy-file", shipped)
    assert (status, err) == (0, "") and ("attached policy file shipped: frnet-3m (860469 bytes) (a checkpoint shipped in "
                                         "frbench: referred to by its sha256, not stored again)") in out
    path = next((root / "records").glob("*.json.gz"))
    record = load_record(path)
    sha = sha256_file(shipped)
    assert record["policy_file"] == {"sha256": sha, "bytes": shipped.stat().st_size, "shipped": "frnet-3m"}
    assert not (root / "policies").exists() or not list((root / "policies").iterdir())  # nothing stored
    assert page_data([record])["records"][0]["policy_file"] == "shipped: frnet-3m"
    assert f"the checkpoint shipped in frbench as frnet-3m (sha256 {sha[:12]})" in (root / "README.md").read_text()
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0
    status, out, _ = verify(capsys, path)
    assert status == 0 and "policy: shipped frnet-3m" in out, out
    # an frbench that no longer ships that checkpoint: --check and verify say so
    monkeypatch.setattr(policy_files, "SHIPPED_CHECKPOINTS", {})
    missing = (f"policy file: no checkpoint shipped with this frbench has the record's sha256 {sha[:16]}... "
               "(it was shipped as 'frnet-3m')")
    status, _, err = cli(capsys, "leaderboard", "--check", "--root", root)
    assert status == 1 and missing in err
    status, out, _ = verify(capsys, path)
    assert status == 1 and missing in out


# --------------------------------------------------------------------------- verify


def test_an_honest_record_verifies_and_save_marks_it(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, policies["frnet-3m"])
    status, out, err = verify(capsys, path, "--save", "--seed", 3)
    assert status == 0, out + err
    assert "policy: attached" in out and "compared bit-identical" in out and "2 of 2 sampled episodes reproduced" in out
    record = load_record(path)
    (entry,) = record["verifications"]
    assert (entry["sample"], entry["cells"], entry["seed"], entry["mode"], entry["policy"]) == (2, 1, 3, "exact", "attached")
    assert "2 exact" in (root / "README.md").read_text()
    assert page_data([record])["records"][0]["verified"]["sample"] == 2
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0


def test_a_built_in_policy_is_re_run_by_name(capsys, root, tmp_path):
    path = submitted(capsys, root, tmp_path, evaluate("zero"), None)
    status, out, _ = verify(capsys, path)
    assert status == 0 and "policy: built-in zero" in out and "re-run with this checkout's code" in out


def _rebuilt(results: dict, submission: dict, edit) -> dict:
    """``results`` edited by ``edit`` with cells, summary and sim_to_sim recomputed: a record that checks."""
    results = copy.deepcopy(results)
    edit(results)
    results["cells"] = aggregate_cells(results["episodes"])
    results["summary"] = summarize(results["cells"])
    results["sim_to_sim"] = sim_to_sim(results["summary"])
    return build_record(results, submission)


def _replace(root: Path, old: Path, record: dict) -> Path:
    old.unlink()
    new = write_record(root, record)
    lb.regenerate(root)
    return new


def test_edited_episodes_are_caught(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, policies["frnet-3m"])
    original = load_record(path)

    def edit(results):  # flip episode 1's outcome
        episode = results["episodes"][1]
        episode["success"], episode["time_to_recover"] = not episode["success"], None if episode["success"] else 1.5
    tampered = _rebuilt(honest, original["submission"], edit)
    tampered["policy_file"] = original["policy_file"]
    path = _replace(root, path, tampered)
    assert load_record(path)["scores"]["overall"] != original["scores"]["overall"]  # it checks, with another score
    status, out, _ = verify(capsys, path)
    was = honest["episodes"][1]
    assert status == 1
    assert (f"mismatch: go2 mujoco flat level 1 seed 0 episode 1: success {not was['success']} -> {was['success']}; "
            f"time_to_recover {None if was['success'] else 1.5} -> {was['time_to_recover']}") in out
    naive = json.loads(gzip.decompress(path.read_bytes()))
    naive["results"]["episodes"][0]["energy"] += 1.0  # edited without recomputing: the record does not check
    path.write_bytes(gzip.compress(json.dumps(naive).encode()))
    status, out, err = verify(capsys, path)
    assert status == 2 and err.count("\n") == 1 and "differs from the mean of its episodes' energy" in err


def test_a_swapped_policy_file_is_caught_by_its_hash_and_else_by_its_outcomes(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, policies["frnet-3m"])
    stored = root / load_record(path)["policy_file"]["file"]
    stored.write_bytes(policies["ppo-3m"].read_bytes())
    status, out, _ = verify(capsys, path)
    assert status == 1 and "does not have the record's sha256" in out and "it was replaced" in out
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 1
    # fixed up: the file stored under its own hash, the record and results naming it, the id recomputed
    stored.unlink()
    swapped = sha256_file(policies["ppo-3m"])
    shutil.copy(policies["ppo-3m"], root / "policies" / f"{swapped}.pt")
    original = load_record(path)
    tampered = _rebuilt(honest, original["submission"], lambda r: r["policy"].update(sha256=swapped))
    tampered["policy_file"] = {**original["policy_file"], "sha256": swapped, "file": f"policies/{swapped}.pt"}
    path = _replace(root, path, tampered)
    assert cli(capsys, "leaderboard", "--check", "--root", root)[0] == 0  # nothing left to see without re-running
    status, out, _ = verify(capsys, path)
    assert status == 1 and out.count("mismatch: go2 mujoco flat level 1 seed 0 episode") == 2, out


def test_records_of_another_protocol_are_caught(capsys, root, tmp_path, policies, honest, monkeypatch):
    labelled = copy.deepcopy(honest)
    labelled["protocol_version"] = "1.0"
    path = submitted(capsys, root, tmp_path, labelled, policies["frnet-3m"])
    status, out, _ = verify(capsys, path)
    assert status == 1 and "ran under protocol 1.0, this frbench runs protocol 1.4 and reproduces episodes from 1.2 on" in out
    # episodes judged by other rules (standing at 30 % of the nominal height, not 75 %), labelled with this protocol
    import frbench.tasks.success as success

    with monkeypatch.context() as patch:
        patch.setattr(success, "MIN_HEIGHT_FRACTION", 0.3)
        other = evaluate("scripted")
    path = submitted(capsys, empty_board_copy(REPO_BOARD, tmp_path / "other"), tmp_path, other, None)
    status, out, _ = verify(capsys, path)
    assert status == 1 and "mismatch: go2 mujoco flat level 1 seed 0 episode" in out


def test_a_record_of_other_library_versions_is_compared_within_the_tolerance(capsys, root, tmp_path, policies, honest):
    path = submitted(capsys, root, tmp_path, honest, policies["frnet-3m"])
    original = load_record(path)
    older = _rebuilt(honest, original["submission"], lambda r: r["versions"].update(mujoco="3.9.9"))
    older["policy_file"] = original["policy_file"]
    path = _replace(root, path, older)
    status, out, _ = verify(capsys, path, "--save")
    assert status == 0, out
    assert "note: version of mujoco: 3.9.9 in the record, " in out and "compared within tolerance" in out
    entry = load_record(path)["verifications"][0]
    assert (entry["mode"], entry["tier"]) == ("tolerance", "exact")  # compared within tolerance, found bit-identical
    assert "2 exact" in (root / "README.md").read_text()


@pytest.mark.parametrize("args, message", [
    (["missing.json"], "missing.json: no such file"),
    (["--sample", "0"], "--sample 0: expected at least 1 episode"),
    (["--seed", "-1"], "--seed -1: expected 0 to 4294967295"),
    (["deadbeefdeadbeef"], "record 'deadbeefdeadbeef': no record in"),
])
def test_bad_input_is_one_line_and_exit_2(args, message, capsys, root, tmp_path):
    path = submitted(capsys, root, tmp_path, evaluate("zero"), None)
    if args[0].startswith("--"):
        args = [path, *args]
    status, out, err = cli(capsys, "verify", *args, "--root", root)
    assert status == 2 and err.count("\n") == 1 and message in err, err


def test_the_sample_is_seeded_and_the_comparison_modes_differ():
    assert sample_indices(100, 5, 7) == sample_indices(100, 5, 7) != sample_indices(100, 5, 8)
    assert sample_indices(3, 10, 0) == [0, 1, 2]
    recorded = {"success": True, "time_to_recover": 1.0, "energy": 100.0, "initial_pose": "supine"}
    close = {**recorded, "energy": 100.0 * (1 + RELATIVE_TOLERANCE / 2), "time_to_recover": 1.02}
    assert compare_episode(recorded, recorded, exact=True) == []
    assert compare_episode(recorded, close, exact=True) == [f"energy 100.0 -> {close['energy']!r}", "time_to_recover 1.0 -> 1.02"]
    assert compare_episode(recorded, close, exact=False) == []
    assert compare_episode(recorded, {**close, "success": False}, exact=False) == ["success True -> False"]
    assert compare_episode(recorded, {**recorded, "energy": 101.0}, exact=False) == ["energy 100.0 -> 101.0"]


# --------------------------------------------------------------------------- policies trained elsewhere


def test_a_foreign_onnx_policy_with_its_spec_file_is_attached_with_its_layout_and_verifies(capsys, root, tmp_path):
    """`torch.onnx.export` of a plain MLP, evaluated with `--spec layout.json`: the layout travels as the sidecar."""
    from policy_factory import export_onnx, mlp

    onnx = export_onnx(mlp(seed=5), tmp_path / "foreign.onnx")
    status, layout_text, _ = cli(capsys, "spec", "--robot", "go2", "--json")
    assert status == 0
    layout = tmp_path / "layout.json"
    layout.write_text(layout_text)
    out = tmp_path / "foreign-results.json"
    status, _, err = cli(capsys, "evaluate", "--policy", onnx, "--spec", layout, "--robots", "go2", "--backends", "mujoco",
                         "--terrains", "flat", "--levels", "1", "--seeds", "0", "--episodes", "2", "--jobs", "1", "--out", out)
    assert status == 0, err
    results = json.loads(out.read_text())
    path = submitted(capsys, root, tmp_path, results, onnx)
    entry = load_record(path)["policy_file"]
    assert entry["file"].endswith(".onnx") and entry["sidecar_sha256"] == sha256_file(layout)
    assert (root / (entry["file"] + ".json")).read_bytes() == layout.read_bytes()
    status, out_text, _ = verify(capsys, path)
    assert status == 0 and "policy: attached" in out_text, out_text
    (root / (entry["file"] + ".json")).write_text("{}")  # the layout replaced: caught by its hash
    status, out_text, _ = verify(capsys, path)
    assert status == 1 and "attached policy sidecar" in out_text


def test_a_python_file_policy_is_attached_and_re_run_by_its_attribute(capsys, root, tmp_path):
    from policy_factory import POLICY_FILE

    source = tmp_path / "mine.py"
    source.write_text(POLICY_FILE)
    results = evaluate(f"{source}:Zero")
    path = submitted(capsys, root, tmp_path, results, source)
    assert load_record(path)["policy_file"]["file"].endswith(".py")
    status, out, _ = verify(capsys, path)
    assert status == 0 and "policy: attached" in out and out.count(".py:Zero") == 1, out


def test_records_from_1_2_on_are_reproducible_and_earlier_or_later_ones_are_not():
    from frbench.leaderboard.verify import reproducible

    assert [reproducible(v) for v in ("1.0", "1.1", "1.2", "1.3", "1.4", "1.5")] == [False, False, True, True, True, False]
