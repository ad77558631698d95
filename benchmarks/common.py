"""Helpers shared by the benchmark scripts: timing loops and fallen starting states."""

from __future__ import annotations

import time

import numpy as np

from frbench.backends.base import RobotState
from frbench.robot_checks.check import random_configurations


def timed(step, seconds: float) -> float:
    """Calls of ``step`` per second over about ``seconds`` (after one warm-up call)."""
    step()
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        count += 1
    return count / (time.perf_counter() - start)


def fallen(spec, n: int, rng: np.random.Generator, xy=(0.0, 0.0), z: float = 0.5) -> RobotState:
    """N random orientations and joint angles, ``z`` [m] above (x, y), at rest."""
    pos, quat, q = random_configurations(spec, rng, n)
    pos[:, :2] = xy
    pos[:, 2] = z
    return RobotState.at_rest(pos, quat, q)


def median_rates(loops: dict, reset, seconds: float, repeats: int) -> dict[str, float]:
    """Median calls/s of each loop, the loops timed in turn ``repeats`` times, ``reset()`` before each."""
    rates: dict[str, list[float]] = {name: [] for name in loops}
    for _ in range(repeats):
        for name, loop in loops.items():
            reset()
            rates[name].append(timed(loop, seconds))
    return {name: float(np.median(values)) for name, values in rates.items()}
