"""The standing analysis: its step accounting by hand, and its episodes are frbench evaluate's."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.analysis.standing import StandingTally, format_report, standing_analysis


def test_the_tally_counts_only_steps_at_which_the_robot_is_up():
    tally = StandingTally(("base", "FL_calf", "FR_calf"))
    up = np.array([True, True, False])
    contact = np.array([[False, True, False], [False, False, False], [True, True, True]])
    tally.add_step(up, contact, None)
    tally.add_step(up, np.zeros((3, 3), dtype=bool), np.array([0.2, 0.4, 9.0]))
    tally.episodes, tally.successes = 3, 1
    row = tally.summary()
    assert row["up_steps"] == 4 and row["body_contact_share"] == pytest.approx(0.25)
    assert row["group_contact_share"] == {"base": 0.0, "FL_calf": 0.25, "FR_calf": 0.0}
    assert row["mean_target_change_rad"] == pytest.approx(0.3)  # the third env (not up) is ignored
    assert "body contact 0.25 (most: FL_calf 0.25)" in format_report({"mujoco": row})
    never = StandingTally(("base",)).summary()
    assert never["body_contact_share"] is None and "never up" in format_report({"pybullet": never})


def test_the_analysis_runs_the_same_episodes_as_frbench_evaluate():
    from frbench.evaluation.runner import Cell, run_cell

    report = standing_analysis("scripted", "go2", backends=("mujoco",), seeds=(0,), episodes=2)["mujoco"]
    records = run_cell(Cell("go2", "mujoco", "flat", 1, 0, 2), "scripted")
    assert report["episodes"] == 2 and report["successes"] == sum(r["success"] for r in records)
    assert report["successes"] >= 1 and report["up_steps"] >= 25  # scripted stands Go2 up, for ≥ 0.5 s
    assert 0.0 <= report["body_contact_share"] <= 1.0 and report["mean_target_change_rad"] > 0.0
