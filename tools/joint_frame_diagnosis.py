"""Why a learned policy in the canonical joint frame still fails on an unseen robot: one factor changed at a time.

For each robot, the policy (default: frnet-30m's policy file) runs the unseen grid's level-1 flat and rough cells
(``--terrains``, ``--levels``; seeds 0-1, 3 episodes each; MuJoCo) in variants of the robot that change one thing and nothing else:

* ``as is``: the robot as the protocol scores it (the canonical frame: what the board's re-score runs);
* ``robot frame``: the policy in the robot file's own convention (what the records before the frame ran);
* ``mirrored legs``: a robot whose four knees point forward not turned around but each leg mirrored front to
  back (`frbench.robots.joint_frame.joint_frame` with ``turn=False``; the same as ``as is`` for other robots);
* ``torque x2``: every torque limit doubled (is the robot too weak for the policy's motions?);
* ``training gains``: kp 40 N·m/rad, kd 1.0 N·m·s/rad on every joint, the gains of the training robots (do the
  robot's own PD gains, derived from its size, change the dynamics the policy learned?);
* ``limits ±π``: every joint range opened to ±π around the default pose (do the file's joint limits clip the
  policy's targets?).

These are diagnoses, not protocol changes: the board scores the robot ``as is``. Prints successes per variant:

    .venv/bin/python tools/joint_frame_diagnosis.py [--robots spirit40,anymal_c] [--policy FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FRNET_30M = ROOT / "leaderboard" / "policies" / "00408d899d9213b7dd35e1bc8be6537f8c40666cdb4c49571bb9b333c3418fe4.pt"
VARIANTS = ("as is", "robot frame", "mirrored legs", "torque x2", "training gains", "limits ±π")
def cells(terrains: str, levels: str) -> list[tuple[str, int, int]]:
    """(family, level, seed) of the diagnosis: seeds 0-1."""
    return [(t, int(level), seed) for t in terrains.split(",") for level in levels.split(",") for seed in (0, 1)]


def variant_spec(spec, variant: str):
    """``spec`` with the one change ``variant`` names (see the module docstring)."""
    n = spec.n_joints
    if variant == "torque x2":
        return dataclasses.replace(spec, torque_limits=tuple(2.0 * t for t in spec.torque_limits))
    if variant == "training gains":
        return dataclasses.replace(spec, kp=(40.0,) * n, kd=(1.0,) * n)
    if variant == "limits ±π":
        default = np.asarray(spec.default_pose)
        return dataclasses.replace(spec, joint_lower=tuple(default - np.pi), joint_upper=tuple(default + np.pi))
    return spec


def successes(spec, policy, variant: str, chosen_cells) -> int:
    """Episodes recovered over ``chosen_cells`` (3 episodes each, MuJoCo)."""
    from frbench.evaluation.episodes import run_episodes
    from frbench.robots.joint_frame import joint_frame
    from frbench.tasks.initial_states import draw_starts
    from frbench.terrains import make_terrain

    total = 0
    chosen = variant_spec(spec, variant)
    frame = {"robot frame": "robot", "mirrored legs": joint_frame(spec, turn=False)}.get(variant)
    for family, level, seed in chosen_cells:
        terrain = make_terrain(family, level, seed)
        starts = draw_starts(spec, terrain, family, level, seed, range(3))
        task = run_episodes(chosen, "mujoco", terrain, starts, policy, seed=seed,
                            joint_frame=frame)
        total += int((task.success.success & ~(task.metrics.diverged | task.settle_diverged)).sum())
    return total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="solo12,mini_cheetah,spirit40,vision60,anymal_b,anymal_c")
    parser.add_argument("--policy", default=str(FRNET_30M))
    parser.add_argument("--terrains", default="flat,rough")
    parser.add_argument("--levels", default="1")
    parser.add_argument("--variants", default=",".join(VARIANTS), help="which of: " + ", ".join(VARIANTS))
    args = parser.parse_args(argv)
    import torch

    from frbench.policies.registry import load_policy
    from frbench.robots import get_robot

    torch.set_num_threads(1)
    policy = load_policy(args.policy)
    chosen_cells = cells(args.terrains, args.levels)
    print(f"policy {policy.name}; MuJoCo, {args.terrains} level {args.levels}, seeds 0-1, 3 episodes: successes of "
          f"{3 * len(chosen_cells)}")
    print(f"{'robot':<14}" + "".join(f"{v:>16}" for v in VARIANTS if v in args.variants.split(",")))
    for name in args.robots.split(","):
        spec = get_robot(name)
        row = [successes(spec, policy, v, chosen_cells) for v in VARIANTS if v in args.variants.split(",")]
        print(f"{name:<14}" + "".join(f"{s:>16}" for s in row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
