"""Wilson intervals, the stratified bootstrap and the standard grid's size."""

from __future__ import annotations

import numpy as np
import pytest

from frbench.evaluation.intervals import (
    bootstrap_rates,
    episodes_for_half_width,
    percentile_interval,
    sim_to_sim_gaps,
    sorted_cells,
    wilson_interval,
)
from frbench.tasks.protocol import (
    STANDARD_BACKENDS,
    STANDARD_EPISODES,
    STANDARD_LEVELS,
    STANDARD_ROBOTS,
    STANDARD_SEEDS,
    STANDARD_TERRAINS,
)


def test_wilson_matches_published_values():
    # Brown, Cai & DasGupta (2001) / statsmodels proportion_confint(method="wilson")
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.27753), abs=1e-5)
    assert wilson_interval(10, 10) == pytest.approx((0.72247, 1.0), abs=1e-5)
    assert wilson_interval(5, 10) == pytest.approx((0.23659, 0.76341), abs=1e-5)
    assert wilson_interval(3, 4)[0] > 0.3 and wilson_interval(3, 4)[1] < 1.0  # never "75.0 ± 0.0"


def _cells(rates, seeds=4, episodes=8, backends=("mujoco",)):
    cells = []
    for b in backends:
        for t, rate in enumerate(rates):
            for s in range(seeds):
                k = int(round(rate * episodes))
                cells.append({"robot": "go2", "backend": b, "terrain": f"t{t}", "level": 1, "seed": s,
                              "successes": k, "episodes": episodes, "success_rate": k / episodes})
    return cells


def test_bootstrap_is_seeded_and_centred_on_the_mean():
    cells = _cells([0.25, 0.5, 0.75])
    a, b = bootstrap_rates(cells), bootstrap_rates(list(reversed(cells)))
    assert np.array_equal(a, b)  # deterministic and independent of the cells' order
    assert a.mean() == pytest.approx(0.5, abs=0.01)
    low, high = percentile_interval(a.mean(axis=1))
    assert low < 0.5 < high and high - low < 0.2


def test_bootstrap_stays_within_its_stratum():
    cells = _cells([0.0, 1.0])  # cells of all failures and cells of all successes
    rates = bootstrap_rates(cells)
    ordered = sorted_cells(cells)
    zero = [j for j, c in enumerate(ordered) if c["terrain"] == "t0"]
    assert rates[:, zero].max() == 0.0 and rates.mean() == 0.5
    # no spread to resample: the pooled Wilson interval instead of an exact-looking [0.5, 0.5]
    low, high = percentile_interval(rates.mean(axis=1), 32, 64)
    assert (low, high) == pytest.approx(wilson_interval(32, 64))


def test_signed_gap_is_unbiased_where_the_absolute_gap_is_not():
    cells = _cells([0.5, 0.5], backends=("mujoco", "pybullet"))
    gaps = sim_to_sim_gaps(cells, bootstrap_rates(cells))
    assert abs(gaps.mean()) < 0.01 and percentile_interval(gaps)[0] < 0 < percentile_interval(gaps)[1]


def test_the_standard_grid_holds_enough_episodes_for_plus_minus_two_points():
    needed = episodes_for_half_width(0.02)
    assert needed == 2401
    per_simulator = len(STANDARD_ROBOTS) * len(STANDARD_TERRAINS) * len(STANDARD_LEVELS) * len(STANDARD_SEEDS)
    assert len(STANDARD_BACKENDS) == 3 and per_simulator * 3 * STANDARD_EPISODES == 3780 >= needed
    # the episode count was fixed on two simulators (protocol 1.2): the smallest that holds, kept with three
    assert per_simulator * 2 * STANDARD_EPISODES >= needed > per_simulator * 2 * (STANDARD_EPISODES - 1)


def test_bootstrap_half_width_on_a_standard_grid_at_fifty_percent():
    rng = np.random.default_rng(0)
    cells = []
    for key in np.ndindex(5, 2, 7, 3, 4):
        k = int(rng.binomial(STANDARD_EPISODES, 0.5))
        cells.append({"robot": f"r{key[0]}", "backend": ("mujoco", "pybullet")[key[1]], "terrain": f"t{key[2]}",
                      "level": key[3], "seed": key[4], "successes": k, "episodes": STANDARD_EPISODES,
                      "success_rate": k / STANDARD_EPISODES})
    low, high = percentile_interval(bootstrap_rates(cells).mean(axis=1))
    assert (high - low) / 2 <= 0.02
