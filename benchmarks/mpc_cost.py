"""Compute cost of the ``mpc`` planner: seconds per episode (wall and CPU) for planner settings.

One cell (robot, backend, flat level 1, seed 0, ``--episodes`` episodes) through ``run_cell`` per setting;
each setting is a ``$FRBENCH_MPC`` text (``""`` = the defaults). Prints per setting: episodes, successes,
wall seconds per episode, CPU seconds per episode of this process (the planner's rollouts run in its
own thread pool of ``threads`` threads, one by default, so CPU time is the planner's work even on a
loaded machine) and CPU seconds per replanning.

Run: ``python benchmarks/mpc_cost.py --robot g1 --backend mujoco --episodes 2 --settings "" "samples=16"``.
"""

from __future__ import annotations

import argparse
import os
import time

from frbench.evaluation import runner
from frbench.evaluation.runner import Cell, run_cell
from frbench.policies.mpc import CONFIG_ENV, config_from_text
from frbench.tasks.recovery import EPISODE_STEPS


def measure(robot: str, backend: str, episodes: int, setting: str) -> dict:
    """Run one cell with the planner ``setting``; its timings and successes."""
    os.environ[CONFIG_ENV] = setting
    runner._policy.cache_clear()  # the policy reads its setting when built
    config, _ = config_from_text(setting)
    wall, cpu = time.perf_counter(), time.process_time()
    records = run_cell(Cell(robot, backend, "flat", 1, 0, episodes), "mpc")
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    replans = episodes * -(-EPISODE_STEPS // config.replan_steps)
    return {"setting": setting or "defaults", "episodes": episodes, "successes": sum(r["success"] for r in records),
            "wall_s_per_episode": wall / episodes, "cpu_s_per_episode": cpu / episodes,
            "cpu_ms_per_replan": 1e3 * cpu / replans}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--backend", default="mujoco")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--settings", nargs="+", default=[""], help="$FRBENCH_MPC texts ('' = defaults)")
    args = parser.parse_args()
    for setting in args.settings:
        row = measure(args.robot, args.backend, args.episodes, setting)
        print(f"{args.robot} {args.backend} {row['setting']:<28} {row['successes']}/{row['episodes']} up, "
              f"{row['wall_s_per_episode']:6.1f} s wall / episode, {row['cpu_s_per_episode']:6.1f} s CPU / episode, "
              f"{row['cpu_ms_per_replan']:6.0f} ms CPU / replanning", flush=True)


if __name__ == "__main__":
    main()
