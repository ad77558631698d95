"""How close a policy comes to standing: pelvis heights over episodes, beyond the success test's yes/no.

For each policy, runs one cell's episodes (robot, simulator, terrain, level 1, seed; the protocol's starts)
through the episode runner and prints: how many episodes ever reached the success test's standing height
(``--height``, the G1's 0.7 m by default), the mean time [s] spent at or above it, how many end above it,
and each episode's highest and final root height [m].

Run: ``python benchmarks/standing_reach.py mpc-distilled-g1 runs/distill-g1/checkpoints/round0.pt``.
"""

from __future__ import annotations

import argparse

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.policies.registry import load_policy
from frbench.robots import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.tasks.protocol import CONTROL_DT
from frbench.terrains import make_terrain


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policies", nargs="+", help="policy names or checkpoint paths")
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--backend", default="mujoco")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--height", type=float, default=0.7, help="standing root height [m]")
    args = parser.parse_args()
    spec, terrain = get_robot(args.robot), make_terrain(args.terrain, 1, args.seed)
    starts = draw_starts(spec, terrain, args.terrain, 1, args.seed, range(args.episodes))
    for reference in args.policies:
        heights = []
        task = run_episodes(spec, args.backend, terrain, starts, load_policy(reference), seed=args.seed,
                            on_step=lambda t, _: heights.append(t.state.base_pos[:, 2].copy()))
        h = np.array(heights)
        up = h >= args.height
        print(f"{reference}: reached {args.height} m in {int(up.any(0).sum())}/{args.episodes} episodes, "
              f"mean {up.sum(0).mean() * CONTROL_DT:.2f} s there, {int(up[-1].sum())} end there, "
              f"successes {int(task.success.success.sum())}; highest {np.round(h.max(0), 2).tolist()}, "
              f"final {np.round(h[-1], 2).tolist()}", flush=True)


if __name__ == "__main__":
    main()
