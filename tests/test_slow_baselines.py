"""Slow regression checks of the shipped baselines (``make test-slow``)."""

from __future__ import annotations

import pytest

from frbench.evaluation.runner import Cell, run_cell


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["mujoco", "pybullet"])
@pytest.mark.parametrize("robot", ["go2", "go1", "aliengo"])
def test_scripted_gets_the_unitree_robots_up_on_flat_ground(robot, backend):
    records = [r for seed in range(4) for r in run_cell(Cell(robot, backend, "flat", 1, seed, 8), "scripted")]
    rate = sum(r["success"] for r in records) / len(records)
    assert rate >= 0.9, f"{robot} {backend}: {rate:.2f}"


@pytest.mark.slow
def test_zero_almost_never_gets_up():
    records = [r for seed in range(4) for r in run_cell(Cell("go2", "mujoco", "flat", 1, seed, 8), "zero")]
    assert sum(r["success"] for r in records) / len(records) <= 0.2
