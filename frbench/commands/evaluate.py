"""``frbench evaluate``: score a policy over robots × backends × terrains × levels × seeds × episodes."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from frbench.errors import FrbenchError


def _list(text: str) -> list[str]:
    return [item.strip() for item in text.split(",") if item.strip()]


def _ints(text: str) -> list[int]:
    try:
        return [int(item) for item in _list(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of integers") from None


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``evaluate`` to the CLI."""
    from frbench.evaluation.grid import EvaluationRequest

    d = EvaluationRequest()
    p = sub.add_parser("evaluate", help="score a recovery policy in MuJoCo and PyBullet",
                       description="With no arguments: the best shipped policy on Go2, in MuJoCo, PyBullet and PhysX, every terrain.")
    p.add_argument("--policy", default=d.policy, help=f"policy name, checkpoint file, run folder, ONNX or TorchScript "
                   f"file, Stable-Baselines3 zip, module:attr or file.py:attr (see `frbench policies --help`; "
                   f"default {d.policy})")
    p.add_argument("--spec", default=None, help="a layout file (JSON, `frbench spec --json`) for an ONNX, TorchScript, "
                   "Stable-Baselines3 or Python policy (default: its sidecar <file>.json, else frbench's layout)")
    p.add_argument("--grid", default=None, help="a named grid of the protocol instead of the axes below: standard "
                   "(the five training-distribution quadrupeds, 840 cells), unseen (real quadrupeds no policy trains on, "
                   "576 cells, + the humanoid set for a humanoid policy), standard,unseen, or humanoid (protocol 1.3 on: the G1, 144 "
                   "cells, + the humanoid set; docs/protocol.md)")
    p.add_argument("--robots", type=_list, default=None, help="comma-separated robot names or URDF paths (default go2)")
    p.add_argument("--backends", type=_list, default=None, help="default mujoco,pybullet,physx (physx with the physx extra, "
                   "which make install installs; mujoco-warp with the gpu extra)")
    p.add_argument("--terrains", type=_list, default=None, help="terrain families (default: all seven)")
    p.add_argument("--levels", type=_ints, default=None, help="difficulty levels 1-10 (default 1,5,10)")
    p.add_argument("--seeds", type=_ints, default=None, help="evaluation seeds (default 0,1)")
    p.add_argument("--episodes", type=int, default=None, help=f"episodes per cell (default {d.episodes})")
    p.add_argument("--noise", action="store_true", help="add sensor noise to the observations")
    p.add_argument("--device", default=d.device, metavar="DEVICE",
                   help="cpu (default), cuda or cuda:N: where a device simulator (mujoco-warp) runs; the CPU "
                        "simulators run on cpu")
    p.add_argument("--jobs", type=int, default=0, help="worker processes (default: one per core)")
    p.add_argument("--executor", default=d.executor, help="local (a process pool, default) or ray (Ray tasks; "
                   "docs/scale.md)")
    p.add_argument("--address", default=None, help="--executor ray: the Ray cluster (default $RAY_ADDRESS, else a "
                   "local instance of --jobs CPUs)")
    p.add_argument("--out", type=Path, default=None, help="results JSON (default results/<policy>.json)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Validate, run the grid with a progress bar, print the table, write the results atomically."""
    from tqdm import tqdm

    from frbench.evaluation.grid import (
        EvaluationRequest,
        build_results,
        run_grid,
        validate,
    )
    from frbench.evaluation.provenance import frbench_info
    from frbench.evaluation.results import aggregate_table, initial_pose_table, results_table
    from frbench.io import atomic_write_text, check_output_path

    from frbench.policies.references import resolve_reference

    axes = ("robots", "backends", "terrains", "levels", "seeds", "episodes")
    given = {name: getattr(args, name) for name in axes if getattr(args, name) is not None}
    grid = []
    if args.grid is not None:
        from frbench.evaluation.grids import parse_grids

        grid = parse_grids(args.grid)
        if given:
            raise FrbenchError(f"--grid {args.grid} fixes the robots, backends, terrains, levels, seeds and episodes: "
                               f"drop --{', --'.join(given)}")
    from frbench.backends.devices import parse_device

    request = EvaluationRequest(policy=resolve_reference(args.policy, args.spec), noise=args.noise, jobs=args.jobs,
                                executor=args.executor, address=args.address, grid=grid,
                                device=parse_device(args.device), **given)
    default_stem = f"{Path(args.policy).stem or 'policy'}" + (f"-{'-'.join(grid)}" if grid else "")
    out = args.out or Path("results") / f"{default_stem}.json"
    check_output_path(out)
    policy = validate(request)
    from frbench.robot_checks.check import checks_for_evaluation

    robot_checks = checks_for_evaluation(request.robots)
    for name, check in robot_checks.items():
        if not check["ok"]:
            print(f"frbench evaluate: warning: robot {name!r} fails `frbench robot check`: {'; '.join(check['problems'])}", file=sys.stderr)
    cells = request.cells()
    for name, reason in request.not_scored.items():
        print(f"frbench evaluate: robot {name!r} of the grid is not scored: {reason}", file=sys.stderr)
    for backend, robots in request.refused.items():
        for name, reason in robots.items():
            print(f"frbench evaluate: robot {name!r} does not run in {backend}: {reason}", file=sys.stderr)
    print(
        f"frbench evaluate: policy {policy.name!r}{' on the ' + '+'.join(grid) + ' grid' if grid else ''}, "
        f"{len(cells)} cells x {request.episodes} episodes "
        f"({', '.join(request.robots)} | {', '.join(request.backends)} | {len(request.terrains)} terrains | "
        f"levels {','.join(map(str, request.levels))} | seeds {','.join(map(str, request.seeds))})",
        file=sys.stderr,
    )
    code = frbench_info()  # the commit the episodes run, before they start
    with tqdm(total=len(cells), unit="cell", file=sys.stderr, dynamic_ncols=True) as bar:
        episodes = run_grid(request, progress=lambda cell: bar.update(1))
    results = build_results(request, policy, episodes, code=code)
    for name, check in robot_checks.items():
        results["robots"][name]["check"] = check
    print(results_table(results["summary"], results["sim_to_sim"]))
    print("\nMean cell success with its stratified-bootstrap 95 % interval:\n" + aggregate_table(results["cells"]))
    print("\nSuccess by initial pose:\n" + initial_pose_table(episodes))
    atomic_write_text(out, json.dumps(results, indent=1) + "\n")
    total = sum(c["successes"] for c in results["cells"])
    print(f"\n{total}/{len(episodes)} episodes succeeded. Results written to {out}")
    if request.refused:  # the other cells ran; the command still reports the robots a simulator refused
        return 2
    return 0
