"""Success-vs-level tables and plots from results files (frbench.analysis.success_plots)."""

from __future__ import annotations

import json

import pytest

from frbench.analysis.success_plots import load_results, markdown_table, plot_families, success_table
from frbench.errors import FrbenchError


def _results(name: str, rates: dict, episodes: int = 4) -> dict:
    cells = [{"robot": robot, "backend": backend, "terrain": "flat", "level": 1, "seed": seed, "success_rate": rate,
              "successes": int(round(rate * episodes)), "episodes": episodes}
             for (robot, backend, seed), rate in rates.items()]
    return {"policy": {"name": name}, "cells": cells}


A = _results("a", {("go2", "mujoco", 0): 1.0, ("go2", "mujoco", 1): 0.5, ("go1", "mujoco", 0): 0.0,
                   ("go1", "mujoco", 1): 0.5})


def test_per_robot_pooled_rate_and_wilson_interval():
    from frbench.evaluation.intervals import wilson_interval

    table = success_table([A], series="robot")
    assert table[("go2", "mujoco", "flat", 1)] == (0.75, *wilson_interval(6, 8), 8)
    assert table[("go1", "mujoco", "flat", 1)] == (0.25, *wilson_interval(2, 8), 8)


def test_per_policy_averages_robots_within_a_seed_first():
    table = success_table([A, _results("b", {("go2", "mujoco", 0): 0.0})], series="policy")
    # pooled over robots and seeds: 8 of 16; a single seed of 0/4 still gets an interval, not "0 ± 0"
    assert table[("a", "mujoco", "flat", 1)][:2] == (0.5, pytest.approx(0.28, abs=0.01))
    rate, low, high, n = table[("b", "mujoco", "flat", 1)]
    assert (rate, low, n) == (0.0, 0.0, 4) and high == pytest.approx(0.49, abs=0.01)


def test_table_and_figures(tmp_path):
    table = success_table([A])
    text = markdown_table(table)
    assert "| go2 | flat | 75.0 (41–93) |" in text
    paths = plot_families(table, tmp_path)
    assert [p.name for p in paths] == ["success_flat.png"] and paths[0].stat().st_size > 5000


def test_bad_files_are_named(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(FrbenchError, match="bad.json: not valid JSON"):
        load_results([bad])
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"x": 1}))
    with pytest.raises(FrbenchError, match="other.json: schema_version: required field is missing; expected 1"):
        load_results([other])
    with pytest.raises(FrbenchError, match="series 'x'"):
        success_table([A], series="x")
