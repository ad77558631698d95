"""The re-score's helpers: the description a re-scored record is submitted with, and the generalisation table."""

from __future__ import annotations

from frbench.leaderboard.records import DESCRIPTION_MAX, check_text
from tools.generalisation_table import with_interval
from tools.rescore import rescored_description

RECORD = "818ea921bdafc0ffee" + "0" * 46


def test_a_short_description_is_kept_whole_and_names_the_source_record():
    text = rescored_description("FR-Net at 3 M env steps", RECORD)
    assert text == ("FR-Net at 3 M env steps; re-scored under protocol 1.2 (standard and unseen grids) "
                    "from record 818ea921bdaf")


def test_a_long_description_is_shortened_to_the_board_limit_with_an_ellipsis():
    text = rescored_description("x" * 300, RECORD)
    assert len(text) == DESCRIPTION_MAX
    assert text.endswith("x\u2026; re-scored under protocol 1.2 (standard and unseen grids) from record 818ea921bdaf")
    assert check_text(text, "--description", DESCRIPTION_MAX) == text  # the board accepts it


def test_the_table_prints_percent_and_signed_points():
    assert with_interval([0.6104, 0.5972, 0.6229]) == "61.0 % [59.7, 62.3]"
    assert with_interval([-0.109, -0.129, -0.089], signed=True) == "-10.9 [-12.9, -8.9]"


def test_a_chunk_is_claimed_once_while_its_claimer_lives_and_never_once_written(tmp_path):
    import os

    from tools.rescore import claim_chunk

    chunk = tmp_path / "mpc" / "chunks" / "humanoid-icub-mujoco-flat.json"
    claim = claim_chunk(chunk)
    assert claim == chunk.with_name(".humanoid-icub-mujoco-flat.json.claim")
    assert claim.read_text() == str(os.getpid())
    assert [f.name for f in chunk.parent.iterdir()] == [claim.name]  # the pid file written aside is gone
    assert claim_chunk(chunk) is None  # held by a live process (this one)
    claim.unlink()
    chunk.write_text("{}")
    assert claim_chunk(chunk) is None  # written: nothing to run
    assert not claim.exists()


def test_a_claim_left_by_a_finished_process_is_taken_over(tmp_path):
    import os
    import subprocess
    import sys

    from tools.rescore import claim_chunk

    finished = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                              text=True, check=True)
    chunk = tmp_path / "humanoid-talos-pybullet-stairs.json"
    stale = chunk.with_name(f".{chunk.name}.claim")
    stale.write_text(finished.stdout.strip())
    claim = claim_chunk(chunk)
    assert claim == stale and claim.read_text() == str(os.getpid())
