"""Confidence intervals for success rates: Wilson per cell, stratified bootstrap for aggregates.

* A cell (or any pooled count) of ``k`` successes in ``n`` episodes gets the 95 % Wilson score interval
  (Wilson 1927; Brown, Cai & DasGupta 2001 recommend it over the normal interval, which gives
  "0.0 ± 0.0" at k = 0).
* An aggregate over cells (per family, robot, backend, overall, the sim-to-sim gap) gets a 95 %
  percentile interval from a *stratified bootstrap*, the procedure of rliable (Agarwal et al. 2021,
  "Deep Reinforcement Learning at the Edge of the Statistical Precipice", NeurIPS; rliable's
  ``StratifiedBootstrap`` resamples the runs of each task independently, keeping the tasks fixed). Here
  the strata ("tasks") are the grid's cells (robot, backend, terrain, level, seed: the protocol fixes
  each cell's terrain instance and starts) and the "runs" are a cell's episodes: each replicate resamples
  every cell's episodes with replacement (a binomial draw with the cell's success rate) and recomputes
  the statistic from the resampled cell rates. rliable itself is not used: it wants a dense runs × tasks
  score matrix, while this needs only each cell's counts and runs in a few milliseconds.

Everything is deterministic: the generator is seeded (`BOOTSTRAP_SEED`) and cells are sorted by key first.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

#: Two-sided 95 % normal quantile.
Z95 = 1.959963984540054
#: Bootstrap replicates and the generator's seed.
BOOTSTRAP_REPLICATES = 2000
BOOTSTRAP_SEED = 20210
CELL_KEYS = ("robot", "backend", "terrain", "level", "seed")


def wilson_interval(successes: int, episodes: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval (low, high) of a success rate, both in [0, 1]; (0, 1) for no episodes."""
    if episodes <= 0:
        return 0.0, 1.0
    p = successes / episodes
    denominator = 1.0 + z * z / episodes
    centre = (p + z * z / (2 * episodes)) / denominator
    half = z * math.sqrt(p * (1 - p) / episodes + z * z / (4 * episodes * episodes)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def sorted_cells(cells: Sequence[Mapping]) -> list[Mapping]:
    """Cells in key order (the bootstrap's and every statistic's column order)."""
    return sorted(cells, key=lambda c: tuple(str(c[k]) if k in ("robot", "backend", "terrain") else int(c[k])
                                             for k in CELL_KEYS))


def bootstrap_rates(cells: Sequence[Mapping], replicates: int = BOOTSTRAP_REPLICATES,
                    seed: int = BOOTSTRAP_SEED) -> np.ndarray:
    """Resampled cell success rates, shape (replicates, len(cells)), columns in ``sorted_cells`` order:
    each cell's episodes drawn with replacement (the module docstring)."""
    cells = sorted_cells(cells)
    rng = np.random.default_rng(seed)
    successes = np.array([c["successes"] for c in cells], dtype=float)
    episodes = np.array([c["episodes"] for c in cells], dtype=int)
    return rng.binomial(episodes, successes / episodes, size=(replicates, len(cells))) / episodes


def percentile_interval(replicates: np.ndarray, successes: int | None = None,
                        episodes: int | None = None) -> tuple[float, float]:
    """The 2.5 and 97.5 percentiles of bootstrap replicates (R,).

    When every replicate is equal (every episode pooled in the statistic had the same outcome, e.g. 0 / 96)
    the bootstrap has no spread to show; given the pooled ``successes`` / ``episodes``, the Wilson interval
    of that count is returned instead, so no score is ever shown as exact.
    """
    low, high = np.percentile(replicates, [2.5, 97.5])
    if low == high and episodes:
        return wilson_interval(int(successes), int(episodes))
    return float(low), float(high)


def sim_to_sim_gaps(cells: Sequence[Mapping], rates: np.ndarray, first: str = "mujoco",
                    second: str = "pybullet") -> np.ndarray | None:
    """Per replicate (rows of ``rates``, columns in ``sorted_cells`` order) the signed sim-to-sim gap ``first`` −
    ``second`` (MuJoCo − PyBullet by default): the mean over (robot, terrain, level) with both simulators of mean
    over seeds (first) − mean over seeds (second); None without such pairs. (The mean *absolute* gap is biased upward by sampling noise — with 4 seeds × 8
    episodes per cell its bootstrap distribution lies wholly above the point estimate — so its interval would
    mislead; the signed mean gap is unbiased.)"""
    cells = sorted_cells(cells)
    groups: dict[tuple, dict[str, list[int]]] = {}
    for j, c in enumerate(cells):
        groups.setdefault((c["robot"], c["terrain"], c["level"]), {}).setdefault(c["backend"], []).append(j)
    pairs = [g for g in groups.values() if first in g and second in g]
    if not pairs:
        return None
    gaps = [rates[:, g[first]].mean(axis=1) - rates[:, g[second]].mean(axis=1) for g in pairs]
    return np.mean(gaps, axis=0)


def episodes_for_half_width(half_width: float, rate: float = 0.5, z: float = Z95) -> int:
    """Episodes needed for a normal-approximation 95 % half-width of ``half_width`` at success rate ``rate``
    when every episode is independent (the worst case is rate 0.5); pooling cells by stratum only narrows it."""
    return math.ceil(z * z * rate * (1 - rate) / (half_width * half_width))
