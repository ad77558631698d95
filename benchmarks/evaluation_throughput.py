"""Evaluation throughput (episodes/s) per backend beside the raw backend throughput.

One cell of N episodes (Go2, flat, policy ``zero``) through ``run_cell`` —
starts, settling, the policy, success test and metrics — against the bare
backend doing the same physics: the same drawn starts, settled the same way,
then ``backend.step`` towards the default pose for the episode.
Single process; ``frbench evaluate`` runs one such cell per core in parallel.

Run: ``python benchmarks/evaluation_throughput.py [--episodes 16] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from frbench.backends import make_backend
from frbench.backends.base import PhysicsParams, RobotState
from frbench.evaluation.runner import Cell, run_cell
from frbench.robots import get_robot
from frbench.tasks.initial_states import SETTLE_GAIN_SCALE, draw_starts
from frbench.tasks.recovery import EPISODE_STEPS, SETTLE_STEPS
from frbench.terrains import make_terrain


def episodes_per_second(backend: str, episodes: int) -> tuple[float, float]:
    """(frbench evaluation episodes/s, raw backend episodes/s)."""
    cell = Cell("go2", backend, "flat", 1, 0, episodes)  # seed 0: the same starts as below
    start = time.perf_counter()
    run_cell(cell, "zero")
    ours = episodes / (time.perf_counter() - start)
    spec = get_robot("go2")
    terrain = make_terrain("flat", 1, 0)
    starts = draw_starts(spec, terrain, "flat", 1, 0, range(episodes))
    start = time.perf_counter()
    sim = make_backend(backend, spec, episodes, terrain=terrain)
    soft = PhysicsParams.nominal(spec, episodes)
    soft.kp, soft.kd = soft.kp * SETTLE_GAIN_SCALE, soft.kd * SETTLE_GAIN_SCALE
    sim.set_params(soft)
    sim.reset(np.arange(episodes), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
    for _ in range(SETTLE_STEPS):
        sim.step(starts.q)
    sim.set_params(PhysicsParams.nominal(spec, episodes))
    targets = np.tile(spec.default_pose, (episodes, 1))
    for _ in range(EPISODE_STEPS):
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
