"""Method-comparison tables from results files (frbench.analysis.comparison), on hand-made results."""

from __future__ import annotations

from frbench.analysis.comparison import (
    displacement_table,
    level10_table,
    sim_to_sim_table,
)


def _cell(robot, backend, terrain, level, seed, rate):
    return {"robot": robot, "backend": backend, "terrain": terrain, "level": level, "seed": seed, "success_rate": rate}


def _episode(backend, terrain, level, displacement):
    return {"backend": backend, "terrain": terrain, "level": level, "max_displacement": displacement}


FRNET = {
    "policy": {"name": "frnet-no-mass-3m"},
    "cells": [_cell("go2", "mujoco", "gaps", 10, 0, 0.5), _cell("go2", "pybullet", "gaps", 10, 0, 0.25),
              _cell("go1", "mujoco", "gaps", 10, 0, 0.0), _cell("go1", "pybullet", "gaps", 10, 0, 0.25),
              _cell("go2", "mujoco", "gaps", 1, 0, 1.0), _cell("go2", "pybullet", "gaps", 1, 0, 1.0)],
    "episodes": [_episode("mujoco", "stairs", 10, d) for d in (0.1, 0.2, 0.3, 0.4)]
    + [_episode("mujoco", "stairs", 5, 9.0), _episode("pybullet", "slopes", 10, 1.5)],
}


def test_level10_success_sits_beside_the_papers_number_for_the_method():
    text = level10_table([FRNET])
    # level 10 only: (0.5 + 0.25 + 0.0 + 0.25) / 4 = 25 %; the paper's frnet-no-mass gaps number is 35.5
    assert "| frnet-no-mass-3m | 25.0 / 35.5 |" in text


def test_sim_to_sim_pairs_backends_per_robot_and_level():
    text = sim_to_sim_table([FRNET])
    # MuJoCo (0.5 + 0 + 1) / 3 = 50 %, PyBullet (0.25 + 0.25 + 1) / 3 = 50 %; |gaps| 0.25, 0.25, 0 -> 16.7 points
    assert "| frnet-no-mass-3m | 50.0 / 50.0 (+0.0) | 16.7 |" in text


def test_displacement_on_level_10_stairs_and_slopes_per_backend():
    text = displacement_table([FRNET])
    header, _, row = text.strip().split("\n")
    assert header == ("| policy | stairs L10 mujoco | stairs L10 pybullet | slopes L10 mujoco | slopes L10 pybullet |")
    # stairs MuJoCo: mean 0.25, 90th percentile 0.37 (the level-5 episode is not counted)
    assert row == "| frnet-no-mass-3m | 0.25 (p90 0.37, n 4) |  |  | 1.50 (p90 1.50, n 1) |"
