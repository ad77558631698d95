"""Which property of a generated robot a policy fails on: a morphology-preset robot and its variants side by side.

A policy that recovers Go2 but not ``spot_like`` may fail on Spot's gains, its proportions or its masses. This
evaluates each policy on the preset robot (`frbench.robots.morphology_presets`) and on copies of it with chosen
fields of its `MorphologyParams` replaced (gains, lengths, masses, torque limits), on the same cells and starts
(`frbench.evaluation.runner.run_cell`: the benchmark's episodes, success test and start draws), and prints the
successes per policy and variant with their 95 % Wilson intervals::

    python benchmarks/robot_variants.py --robot spot_like --policy scripted,runs/kickstart-floor/seed1/policy.pt \\
        --variant kp=80,kd=2 --variant hip_length=0.045 --variant trunk_length=0.6,hip_x=0.2

A variant is ``FIELD=VALUE[,FIELD=VALUE...]``; the first row is always the preset itself. Cells: ``--terrains``
x ``--levels`` x ``--backends`` x ``--seeds``, ``--episodes`` each (default: flat, rough, slopes, stairs at level
1, MuJoCo and PyBullet, seed 0, 6 episodes: 48 episodes per row).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from frbench.errors import FrbenchError
from frbench.evaluation.intervals import wilson_interval
from frbench.evaluation.grid import EvaluationRequest
from frbench.evaluation.runner import run_cell
from frbench.robots import morphology_presets
from frbench.robots.morphology import MorphologyParams, validate
from frbench.robots.morphology_urdf import cached_spec
from frbench.robots.paths import cache_dir

#: The preset robots of the registry and their `morphology_presets` names.
PRESETS = {"spot_like": "SPOT_LIKE", "lite3_like": "LITE3_LIKE"}


def parse_variant(text: str) -> dict[str, float]:
    """``"kp=80,kd=2"`` -> {"kp": 80.0, "kd": 2.0}; a ValueError naming the part and the fields expected."""
    fields = {f.name for f in dataclasses.fields(MorphologyParams)}
    changes = {}
    for part in text.split(","):
        name, sep, value = part.partition("=")
        name = name.strip()
        if not sep or name not in fields:
            raise ValueError(f"--variant {text!r}: {part!r} is not FIELD=VALUE with a field of MorphologyParams")
        try:
            changes[name] = float(value)
        except ValueError:
            raise ValueError(f"--variant {text!r}: {value!r} is not a number") from None
    return changes


def variant_spec(robot: str, changes: dict[str, float], index: int):
    """The `RobotSpec` of preset ``robot`` with ``changes``; its URDF under the cache (one file per variant).
    Every variant keeps the robot's name, so its episodes draw the preset's start seeds (`episode_rng`)."""
    params = dataclasses.replace(getattr(morphology_presets, PRESETS[robot]), **changes)
    validate(params)
    return cached_spec(params, robot, Path(cache_dir()) / "robot-variants" / f"{robot}-{index}.urdf",
                       source=f"{robot} with {changes}")


def successes(spec, policy: str, args) -> tuple[int, int]:
    """(successes, episodes) of ``policy`` on ``spec`` over the cells of ``args``."""
    request = EvaluationRequest(policy=policy, robots=[spec], backends=args.backends.split(","),
                                terrains=args.terrains.split(","), levels=list(map(int, args.levels.split(","))),
                                seeds=list(map(int, args.seeds.split(","))), episodes=args.episodes)
    records = [r for cell in request.cells() for r in run_cell(cell, policy)]
    return sum(r["success"] for r in records), len(records)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="spot_like", choices=sorted(PRESETS))
    parser.add_argument("--policy", default="scripted", help="comma-separated policy names or files")
    parser.add_argument("--variant", action="append", default=[], help="FIELD=VALUE[,FIELD=VALUE...] (repeatable)")
    parser.add_argument("--terrains", default="flat,rough,slopes,stairs")
    parser.add_argument("--levels", default="1")
    parser.add_argument("--backends", default="mujoco,pybullet")
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--episodes", type=int, default=6)
    args = parser.parse_args(argv)
    try:
        variants = [{}] + [parse_variant(v) for v in args.variant]
        specs = [variant_spec(args.robot, changes, i) for i, changes in enumerate(variants)]
    except (ValueError, FrbenchError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for policy in args.policy.split(","):
        for changes, spec in zip(variants, specs):
            start = time.perf_counter()
            won, total = successes(spec, policy, args)
            low, high = wilson_interval(won, total)
            label = ",".join(f"{k}={v:g}" for k, v in changes.items()) or "(the preset)"
            print(f"{policy:>40}  {args.robot} {label:<32} {won:3d}/{total} = {won / total:.3f} "
                  f"[{low:.3f}, {high:.3f}]  {time.perf_counter() - start:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
