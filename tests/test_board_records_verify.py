"""Every main-board record of the current protocol verifies on the machine that runs the tests.

`frbench verify RECORD --sample 4 --seed 1` for each of them, in-process: its policy (the attached file, the
shipped checkpoint of the same sha256, or the built-in policy) re-runs 4 sampled episodes, which must be
bit-identical to the record's. Protocol 1.2 evaluates learned policies with portable float64 inference
(`frbench.policies.learned.portable_actions`), so this holds on any x86-64 processor, not only on the one that
made the record; a record that verified only where it was made fails here.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest

from frbench.leaderboard.records import load_record, record_files
from frbench.leaderboard.verify import verify
from frbench.tasks.protocol import PROTOCOL_VERSION

BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
#: The main board's records under protocol 1.4: the 17 re-scored 1.3 records (each 1.3 record's episodes, its 12
#: episodes whose start 1.4 redraws run again, tools/rescore_starts.py) and 3 evaluated under 1.4 (the
#: kickstart-scripted seeds); no 1.4 record ran a learned policy in the robot's own joint frame.
EXPECTED_MAIN_RECORDS = 20
#: The G1-only 1.4 records of keyframe-humanoid and scripted-humanoid (re-scored from 1.3), superseded by the records
#: of the same controllers with the humanoid set (the same G1 cells, driven through the G1 joint frame).
EXPECTED_SUPERSEDED = 2
#: The humanoid track's records: keyframe-humanoid and scripted-humanoid (G1 grid and humanoid set), zero (re-scored
#: from 1.3 by tools/rescore_starts.py) and mpc-distilled-g1 (G1 only), all by tools/humanoid_records.py.
EXPECTED_HUMANOID_RECORDS = 4
SAMPLE = 4


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


@pytest.mark.parametrize("path", MAIN_BOARD, ids=lambda p: p.name[:12])
def test_a_main_board_record_verifies_bit_identically_here(path):
    record = load_record(path)
    report = verify(record, BOARD, sample=SAMPLE, seed=1)
    assert report.failures == [], report.failures
    assert report.mode == "exact" and report.statistical is None
    assert len(report.sample) == SAMPLE and report.verified
