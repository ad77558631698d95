"""Evaluation throughput (episodes/s) per backend beside the raw backend throughput.

One cell of N episodes (Go2, flat, policy ``zero``) through ``run_cell`` —
starts, settling, the policy, success test and metrics — against the same
number of bare ``backend.step`` calls (settle + episode) on the same batch.
Single process; ``frbench evaluate`` runs one such cell per core in parallel.

Run: ``python benchmarks/evaluation_throughput.py [--episodes 16] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from frbench.backends import make_backend
from frbench.evaluation.runner import Cell, run_cell
from frbench.robots import get_robot
from frbench.tasks.recovery import EPISODE_STEPS, SETTLE_STEPS


def episodes_per_second(backend: str, episodes: int) -> tuple[float, float]:
    """(frbench evaluation episodes/s, raw backend episodes/s)."""
    cell = Cell("go2", backend, "flat", 1, 0, episodes)
    start = time.perf_counter()
    run_cell(cell, "zero")
    ours = episodes / (time.perf_counter() - start)
    spec = get_robot("go2")
    start = time.perf_counter()
    sim = make_backend(backend, spec, episodes)
    targets = np.tile(spec.default_pose, (episodes, 1))
    for _ in range(SETTLE_STEPS + EPISODE_STEPS):
        sim.step(targets)
    sim.close()
    raw = episodes / (time.perf_counter() - start)
    return ours, raw


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"{'backend':<9} {'episodes':>8} {'evaluate ep/s':>14} {'raw ep/s':>9} {'ratio':>6}")
    for backend in ("mujoco", "pybullet"):
        runs = [episodes_per_second(backend, args.episodes) for _ in range(args.repeats)]
        ours, raw = float(np.median([r[0] for r in runs])), float(np.median([r[1] for r in runs]))
        print(f"{backend:<9} {args.episodes:>8} {ours:>14.2f} {raw:>9.2f} {ours / raw:>6.2f}")


if __name__ == "__main__":
    main()
