"""Success-vs-level tables and plots from results files (frbench.analysis.success_plots)."""

from __future__ import annotations

import json

import pytest

from frbench.analysis.success_plots import load_results, markdown_table, plot_families, success_table
from frbench.errors import FrbenchError


def _results(name: str, rates: dict) -> dict:
    cells = [{"robot": robot, "backend": backend, "terrain": "flat", "level": 1, "seed": seed, "success_rate": rate}
             for (robot, backend, seed), rate in rates.items()]
    return {"policy": {"name": name}, "cells": cells}


A = _results("a", {("go2", "mujoco", 0): 1.0, ("go2", "mujoco", 1): 0.5, ("go1", "mujoco", 0): 0.0,
                   ("go1", "mujoco", 1): 0.5})


def test_per_robot_mean_and_std_over_seeds():
    table = success_table([A], series="robot")
    assert table[("go2", "mujoco", "flat", 1)] == (0.75, 0.25, 2)
    assert table[("go1", "mujoco", "flat", 1)] == (0.25, 0.25, 2)


def test_per_policy_averages_robots_within_a_seed_first():
    table = success_table([A, _results("b", {("go2", "mujoco", 0): 0.0})], series="policy")
    # seed 0: (1 + 0)/2 = 0.5, seed 1: (0.5 + 0.5)/2 = 0.5 -> mean 0.5, std 0
    assert table[("a", "mujoco", "flat", 1)] == (0.5, 0.0, 2)
    assert table[("b", "mujoco", "flat", 1)] == (0.0, 0.0, 1)


def test_table_and_figures(tmp_path):
    table = success_table([A])
    text = markdown_table(table)
    assert "| go2 | flat | 75.0 ± 25.0 |" in text
    paths = plot_families(table, tmp_path)
    assert [p.name for p in paths] == ["success_flat.png"] and paths[0].stat().st_size > 5000


def test_bad_files_are_named(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(FrbenchError, match="bad.json: not JSON"):
        load_results([bad])
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"x": 1}))
    with pytest.raises(FrbenchError, match="other.json: not an frbench evaluate results file"):
        load_results([other])
    with pytest.raises(FrbenchError, match="series 'x'"):
        success_table([A], series="x")
