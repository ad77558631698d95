"""Records that left the tree (`RECORDS_ELSEWHERE`): the commit named holds as many records of that protocol version
as the board's README says, none of them is still in the tree, and the README says whether `frbench verify` re-runs
them."""

from __future__ import annotations

import gzip
import json
import re
import shutil
import subprocess
from collections import Counter
from pathlib import Path

import pytest

from frbench.leaderboard.markdown import RECORDS_ELSEWHERE, records_elsewhere_text

ROOT = Path(__file__).resolve().parents[1]
RECORDS = "leaderboard/records"


def _git(*args: str, stdin: bytes | None = None) -> bytes:
    return subprocess.run(["git", "-C", str(ROOT), *args], input=stdin, capture_output=True, check=True).stdout


def _has_commit(commit: str) -> bool:
    return subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{commit}^{{commit}}"],
                          capture_output=True).returncode == 0


def _versions_of_blobs(blobs: list[str]) -> dict[str, tuple[str, str]]:
    """Blob sha -> (protocol version, track) of each gzip record blob, read in one ``git cat-file --batch``."""
    out, at, found = _git("cat-file", "--batch", stdin="".join(b + "\n" for b in blobs).encode()), 0, {}
    for blob in blobs:
        header_end = out.index(b"\n", at)
        size = int(out[at:header_end].split()[2])
        record = json.loads(gzip.decompress(out[header_end + 1:header_end + 1 + size]))
        found[blob] = (record["results"]["protocol_version"], record["track"])
        at = header_end + 1 + size + 1
    return found


def test_each_entry_names_a_full_commit_and_a_count():
    assert list(RECORDS_ELSEWHERE) == ["1.0", "1.1", "1.2", "1.3"]
    for version, (what, commit) in RECORDS_ELSEWHERE.items():
        assert re.fullmatch(r"[0-9a-f]{40}", commit), version
        assert re.match(r"\d+ records \(", what), version


def test_the_readme_says_verify_re_runs_only_the_reproducible_versions():
    lines = [line for line in records_elsewhere_text() if line]
    assert len(lines) == 4
    for line, version in zip(lines, RECORDS_ELSEWHERE):
        assert line.startswith(f"Protocol {version}'s ")
        re_runs = line.endswith("which `frbench verify` re-runs).")
        assert re_runs == (version in ("1.2", "1.3")), line[-120:]
    assert lines[0].endswith("only from protocol 1.2 on: the frbench commit the record names re-runs it).")


def test_no_record_of_a_version_that_left_is_in_the_tree():
    paths = sorted((ROOT / RECORDS).glob("*.json.gz"))
    versions = Counter(json.loads(gzip.decompress(p.read_bytes()))["results"]["protocol_version"] for p in paths)
    assert not set(versions) & set(RECORDS_ELSEWHERE), versions
    assert sum(versions.values()) == len(paths) > 0


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_the_named_commit_holds_the_stated_records():
    commits = {commit for _, commit in RECORDS_ELSEWHERE.values()}
    if not all(_has_commit(commit) for commit in commits):
        pytest.skip("a shallow clone: the commits that hold the records are not here (git fetch --unshallow)")
    present = {Path(name).name for name in _git("ls-files", RECORDS).decode().split()}
    left: dict[str, list[str]] = {}  # commit -> blobs of its records that are no longer in the tree
    for commit in commits:
        rows = _git("ls-tree", commit, RECORDS + "/").decode().splitlines()
        left[commit] = [row.split()[2] for row in rows if Path(row.split("\t")[1]).name not in present]
    kinds = _versions_of_blobs(sorted({blob for blobs in left.values() for blob in blobs}))
    for version, (what, commit) in RECORDS_ELSEWHERE.items():
        held = Counter(track for blob in left[commit] for v, track in [kinds[blob]] if v == version)
        assert sum(held.values()) == int(what.split()[0]), (version, held)
        split = re.match(r"\d+ records \(its (\d+) main-board and (\d+) (partial|humanoid-track) records", what)
        if split:  # the tracks the text names, counted
            assert (held["main"], held[split[3].split("-")[0]]) == (int(split[1]), int(split[2])), (version, held)
