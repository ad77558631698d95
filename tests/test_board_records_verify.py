"""Every main-board record of the current protocol verifies on the machine that runs the tests.

`frbench verify RECORD --sample 4 --seed 1` for each of them, in-process: its policy (the attached file, the
shipped checkpoint of the same sha256, or the built-in policy) re-runs 4 sampled episodes (the `mpc`
planner's record: 1, and 4 under `make test-slow`), which must be bit-identical to the record's. Protocol 1.2
evaluates learned policies with portable float64 inference (`frbench.policies.learned.portable_actions`), so this
holds on any x86-64 processor, not only on the one that made the record; a record that verified only where it was
made fails here.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest

from frbench.leaderboard.records import load_record, record_files
from frbench.leaderboard.verify import sample_indices, verify
from frbench.tasks.protocol import PROTOCOL_VERSION

BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
#: The main board's records under protocol 1.4: the 17 re-scored 1.3 records (each 1.3 record's episodes, its 12
#: episodes whose start 1.4 redraws run again, tools/rescore_starts.py) and 3 evaluated under 1.4 (the
#: kickstart-scripted seeds); no 1.4 record ran a learned policy in the robot's own joint frame.
EXPECTED_MAIN_RECORDS = 20
#: The G1-only 1.4 records of keyframe-humanoid and scripted-humanoid (re-scored from 1.3), superseded by the records
#: of the same controllers with the humanoid set (the same G1 cells, driven through the G1 joint frame).
EXPECTED_SUPERSEDED = 2
#: The humanoid track's records: mpc, keyframe-humanoid and scripted-humanoid (G1 grid and humanoid set), zero
#: (re-scored from 1.3 by tools/rescore_starts.py) and mpc-distilled-g1 (G1 only), all by tools/humanoid_records.py.
EXPECTED_HUMANOID_RECORDS = 5
SAMPLE = 4
SEED = 1
#: Policies whose episodes cost up to minutes of CPU each (the `mpc` planner: about 28 CPU-s per G1 episode, 60-100
#: per iCub or Talos episode; verify re-runs a sampled episode's whole cell, 3 episodes): `make test` re-runs one
#: sampled episode of their records, a G1 one (seed 27 samples the G1's MuJoCo flat level-1 cell of the humanoid
#: grid: about 85 s), and `make test-slow` the full sample.
PLANNERS = frozenset({"mpc"})
PLANNER_SAMPLE, PLANNER_SEED = 1, 27


def main_board_files() -> tuple[list[Path], int]:
    """The record files of the current protocol's main board and humanoid track (read directly: no checks, no
    scores), and the number of those records a canonical-frame re-score superseded
    (`frbench.leaderboard.render.superseded`)."""
    from frbench.leaderboard.render import superseded

    records = {}
    for path in record_files(BOARD)[0]:
        record = json.loads(gzip.decompress(path.read_bytes()))
        if record["track"] in ("main", "humanoid") and record["results"]["protocol_version"] == PROTOCOL_VERSION:
            records[path] = record
    replaced = superseded(list(records.values()))
    return [p for p, r in records.items() if r["id"] not in replaced], len(replaced)


MAIN_BOARD, SUPERSEDED = main_board_files()


def test_the_main_board_holds_the_re_scored_records_and_the_humanoid_track_its_records():
    tracks = [json.loads(gzip.decompress(path.read_bytes()))["track"] for path in MAIN_BOARD]
    assert (tracks.count("main"), tracks.count("humanoid"), SUPERSEDED) == (
        EXPECTED_MAIN_RECORDS, EXPECTED_HUMANOID_RECORDS, EXPECTED_SUPERSEDED)


def verification_cases() -> list:
    """(record file, episodes to re-run, sampling seed) for each board record: ``SAMPLE`` episodes, or
    ``PLANNER_SAMPLE`` for a planner's record, with its full ``SAMPLE`` marked slow."""
    cases = []
    for path in MAIN_BOARD:
        policy = json.loads(gzip.decompress(path.read_bytes()))["results"]["policy"]["name"]
        if policy in PLANNERS:
            cases.append(pytest.param(path, PLANNER_SAMPLE, PLANNER_SEED, id=f"{path.name[:12]}-{PLANNER_SAMPLE}"))
            cases.append(pytest.param(path, SAMPLE, SEED, id=f"{path.name[:12]}-{SAMPLE}", marks=pytest.mark.slow))
        else:
            cases.append(pytest.param(path, SAMPLE, SEED, id=path.name[:12]))
    return cases


@pytest.mark.parametrize(("path", "sample", "seed"), verification_cases())
def test_a_main_board_record_verifies_bit_identically_here(path, sample, seed):
    record = load_record(path)
    if sample == PLANNER_SAMPLE and record["results"]["policy"]["name"] in PLANNERS:
        sampled = sample_indices(len(record["results"]["episodes"]), sample, seed)
        assert [record["results"]["episodes"][i]["robot"] for i in sampled] == ["g1"]
    report = verify(record, BOARD, sample=sample, seed=seed)
    assert report.failures == [], report.failures
    assert report.mode == "exact" and report.statistical is None
    assert len(report.sample) == sample and report.verified
