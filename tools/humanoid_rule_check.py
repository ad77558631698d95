"""Which humanoid recoveries under protocol 1.0's rule still pass protocol 1.1's upright rule.

Protocol 1.0 scored humanoids with HoST's rule (the pelvis rises above 0.7 m·h/0.78 and never drops below
0.5 m·h/0.78 afterwards, displacement < 1 m when it rises), which a hand or head stand passes. Protocol 1.1
requires pelvis and torso upright, pelvis height, feet-only support, held 0.5 s (frbench/tasks/success.py).
This runs a policy from protocol 1.0's starts (no start screening, as in 1.0) and scores every episode
with both rules on the same trajectory:

    PYTHONPATH=. python tools/humanoid_rule_check.py --policy keyframe-humanoid --levels 1,5,10 --seeds 0,1 --episodes 8

It prints, per backend, the 1.0 successes, how many of them pass 1.1, and the 1.1-only successes.
"""

from __future__ import annotations

import argparse

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.policies.registry import load_policy
from frbench.robots import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.tasks.success import HUMANOID_REFERENCE_HEIGHT, MAX_DISPLACEMENT
from frbench.terrains import make_terrain

HOST_UP, HOST_FLOOR = 0.7, 0.5


class HostRule:
    """Protocol 1.0's humanoid rule (HoST), online over N episodes."""

    def __init__(self, n: int, nominal: float):
        scale = nominal / HUMANOID_REFERENCE_HEIGHT
        self.up, self.floor = HOST_UP * scale, HOST_FLOOR * scale
        self.reached = np.zeros(n, dtype=bool)
        self.fell = np.zeros(n, dtype=bool)

    def update(self, height: np.ndarray, displacement: np.ndarray, alive: np.ndarray) -> None:
        self.reached |= (height > self.up) & (displacement < MAX_DISPLACEMENT) & alive
        self.fell |= self.reached & (height < self.floor)

    @property
    def success(self) -> np.ndarray:
        return self.reached & ~self.fell


def run(policy_name: str, backend: str, family: str, level: int, seed: int, episodes: int) -> tuple[np.ndarray, np.ndarray]:
    """(1.0 success, 1.1 success) per episode of one cell, from protocol 1.0's starts."""
    spec = get_robot("g1")
    terrain = make_terrain(family, level, seed)
    starts = draw_starts(spec, terrain, family, level, seed, range(episodes), protocol_version="1.0")
    starts.cell = None  # protocol 1.0 had no start screening
    policy = load_policy(policy_name)
    host = HostRule(episodes, spec.nominal_height)

    def record(task, _targets):
        host.update(task.signals.height, task.signals.displacement, task.alive)

    task = run_episodes(spec, backend, terrain, starts, policy, seed=seed, on_step=record)
    alive = task.alive
    return host.success & alive, task.success.success & alive


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="keyframe-humanoid")
    parser.add_argument("--backends", default="mujoco,pybullet")
    parser.add_argument("--terrains", default="flat")
    parser.add_argument("--levels", default="1,5,10")
    parser.add_argument("--seeds", default="0,1")
    parser.add_argument("--episodes", type=int, default=8)
    args = parser.parse_args()
    for backend in args.backends.split(","):
        old_total = both = new_only = total = 0
        for family in args.terrains.split(","):
            for level in map(int, args.levels.split(",")):
                for seed in map(int, args.seeds.split(",")):
                    old, new = run(args.policy, backend, family, level, seed, args.episodes)
                    old_total += int(old.sum())
                    both += int((old & new).sum())
                    new_only += int((new & ~old).sum())
                    total += len(old)
        print(f"{backend}: {total} episodes; protocol 1.0 rule {old_total} successes, of which {both} pass the 1.1 rule "
              f"({old_total - both} do not); {new_only} pass 1.1 only", flush=True)


if __name__ == "__main__":
    main()
