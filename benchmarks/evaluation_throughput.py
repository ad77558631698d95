"""Evaluation throughput (episodes/s) per backend beside the raw backend throughput, interleaved.

One cell of N episodes (Go2, flat, policy ``zero``) through ``run_cell`` —
starts, settling, the policy, success test and metrics — against the bare
simulator doing the same physics: the same drawn starts, settled the same way,
then the episode towards the default pose with nothing else (MuJoCo: the
native actuators' controls and one ``Batch.step(nstep=substeps)`` per control
step; PyBullet: the backend's own step, whose PD is computed in Python at
every physics step). The two loops alternate for ``--repeats`` rounds, both
backends in each round; prints the rounds, then ``evaluate / raw <backend>: R``
(median ratio of the rounds). Targets: >= 0.85 in MuJoCo, >= 0.8 in PyBullet.
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


def evaluate_rate(backend: str, episodes: int) -> float:
    """Episodes/s of ``run_cell`` (policy ``zero``) on the Go2 flat cell, seed 0."""
    start = time.perf_counter()
    run_cell(Cell("go2", backend, "flat", 1, 0, episodes), "zero")
    return episodes / (time.perf_counter() - start)


def raw_rate(backend: str, episodes: int) -> float:
    """Episodes/s of the bare simulator on the same starts (see the module docstring)."""
    spec = get_robot("go2")
    terrain = make_terrain("flat", 1, 0)
    starts = draw_starts(spec, terrain, "flat", 1, 0, range(episodes))
    start = time.perf_counter()
    sim = make_backend(backend, spec, episodes, terrain=terrain)
    soft = PhysicsParams.nominal(spec, episodes)
    soft.kp, soft.kd = soft.kp * SETTLE_GAIN_SCALE, soft.kd * SETTLE_GAIN_SCALE
    sim.set_params(soft)
    sim.reset(np.arange(episodes), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
    targets = np.tile(spec.default_pose, (episodes, 1))
    if backend == "mujoco":
        ctrl, batch, j = sim.batch.bind("ctrl"), sim.batch, spec.n_joints
        ctrl[:, :j] = starts.q
        for _ in range(SETTLE_STEPS):
            batch.step(nstep=sim.substeps)
        sim.set_params(PhysicsParams.nominal(spec, episodes))
        for _ in range(EPISODE_STEPS):
            ctrl[:, :j] = targets
            batch.step(nstep=sim.substeps)
    else:
        for _ in range(SETTLE_STEPS):
            sim.step(starts.q)
        sim.set_params(PhysicsParams.nominal(spec, episodes))
        for _ in range(EPISODE_STEPS):
            sim.step(targets)
    sim.close()
    return episodes / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    backends = ("mujoco", "pybullet")
    for backend in backends:  # warm-up: imports, robot files, compiled models
        evaluate_rate(backend, 2)
    ratios: dict[str, list[float]] = {b: [] for b in backends}
    for repeat in range(args.repeats):
        for backend in backends:
            ours, raw = evaluate_rate(backend, args.episodes), raw_rate(backend, args.episodes)
            ratios[backend].append(ours / raw)
            print(f"round {repeat} {backend}: evaluate {ours:.2f} ep/s, raw {raw:.2f} ep/s, ratio {ours / raw:.2f}",
                  flush=True)
    for backend in backends:
        print(f"evaluate / raw {backend}: {np.median(ratios[backend]):.2f}")


if __name__ == "__main__":
    main()
