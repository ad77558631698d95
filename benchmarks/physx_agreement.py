"""PhysX against MuJoCo and PyBullet: the drop tests, and PhysX's determinism across processes.

1. Drop tests (`frbench.backends.hold.DROP_TESTS`): Go2 at rest in its default pose, dropped upright from
   0.45 m, lying on its side from 0.25 m, and upright from 0.45 m over a 5 cm two-box step, holds the pose with
   its PD for 2 s; the base height at the end in each simulator.
2. Determinism: one evaluation cell (``scripted``, Go2, stairs level 5, seed 0, 8 episodes) run in PhysX in
   two fresh processes; the episode records must be equal, every float bit for bit.

Run: ``python benchmarks/physx_agreement.py [--robot go2]``.
"""

from __future__ import annotations

import argparse
import multiprocessing

from frbench.backends.hold import DROP_TESTS, drop_height
from frbench.robots import get_robot

SIMULATORS = ("physx", "mujoco", "pybullet")


def _cell_records(robot: str) -> list[dict]:
    from frbench.evaluation.runner import Cell, run_cell

    return run_cell(Cell(robot, "physx", "stairs", 5, 0, 8), "scripted")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robot", default="go2", help="a quadruped (default go2)")
    args = parser.parse_args()
    spec = get_robot(args.robot)
    print(f"{args.robot}: base height [m] after 2 s holding the default pose")
    print(f"{'start':<24}" + "".join(f"{name:>10}" for name in SIMULATORS))
    for drop in DROP_TESTS:
        print(f"{drop:<24}" + "".join(f"{drop_height(spec, name, drop):>10.4f}" for name in SIMULATORS))
    with multiprocessing.get_context("spawn").Pool(1, maxtasksperchild=1) as pool:
        first, second = (pool.apply(_cell_records, (args.robot,)) for _ in range(2))
    same = first == second
    successes = sum(record["success"] for record in first)
    print(f"\nphysx, scripted, stairs L5 seed 0, 8 episodes ({successes} succeeded) in two fresh processes: "
          f"{'identical' if same else 'DIFFERENT'} episode records")


if __name__ == "__main__":
    main()
