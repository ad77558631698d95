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
