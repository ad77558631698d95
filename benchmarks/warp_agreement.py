"""How closely MuJoCo Warp (``mujoco-warp``) follows MuJoCo C on frbench's episodes (docs/gpu.md).

**Trajectories.** For each robot, terrain family and level: ``--starts`` of the protocol's fallen starts
(seed 0, `draw_starts`) are placed and settled in MuJoCo C (`RecoveryTask.reset`: the benchmark's settle and
screening); from those settled states (velocities included, `RecordedStarts`) both simulators then run
``--seconds`` of the robot's hand-written controller (``scripted``; the G1 ``scripted-humanoid``): closed loop in
MuJoCo C, and the same joint targets replayed in Warp. Printed: the base position error ‖Δp‖ [m] at 0.1 / 0.5 /
1 / 2 s, median and 95th percentile over the starts (and the worlds either simulator flagged diverged).

**Success.** ``--scripted results.json``: a results file of ``frbench evaluate --policy scripted --backends
mujoco,mujoco-warp ...`` summarised per terrain and level: successes of each simulator pooled over seeds, with
Wilson 95 % intervals, and whether each lies in the other's interval.

Run (both parts, ≈ 15 min on 2 CPU cores with Warp on the CPU):

    python benchmarks/warp_agreement.py --robots go2,g1 --terrains flat,rough,stairs,slopes --levels 1,5 \
        --starts 16 --json agreement.json
    frbench evaluate --policy scripted --backends mujoco,mujoco-warp --robots go2 \
        --terrains flat,rough,stairs --levels 1,5 --seeds 0,1 --episodes 64 --jobs 1 --out scripted.json
    python benchmarks/warp_agreement.py --scripted scripted.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

#: Times [s] at which the base position error is read.
TIMES = (0.1, 0.5, 1.0, 2.0)


def controller(spec):
    """The built-in hand-written controller of ``spec``'s kind."""
    from frbench.policies.registry import load_policy

    return load_policy("scripted-humanoid" if spec.kind == "humanoid" else "scripted")


def trajectories(robot: str, family: str, level: int, starts: int, seconds: float) -> dict:
    """Base positions (steps, N, 3) [m] in MuJoCo C (closed loop) and Warp (the same targets replayed), from the
    settled starts of one cell, with each simulator's diverged flags (N,)."""
    from frbench.backends import make_backend
    from frbench.robots import get_robot
    from frbench.tasks.initial_states import RecordedStarts, draw_starts
    from frbench.tasks.protocol import CONTROL_DT
    from frbench.tasks.recovery import RecoveryTask
    from frbench.terrains import make_terrain

    spec = get_robot(robot)
    terrain = make_terrain(family, level, 0)
    steps = int(round(seconds / CONTROL_DT))
    out = {}
    mujoco = make_backend("mujoco", spec, starts, terrain=terrain)
    task = RecoveryTask(spec, mujoco, terrain, starts)
    task.reset(draw_starts(spec, terrain, family, level, 0, range(starts)))
    settled = RecordedStarts(task.state.copy(), previous_action=np.tile(spec.default_pose, (starts, 1)))
    policy = controller(spec)
    policy.reset(spec, starts)
    obs = task.begin(settled)
    targets, positions = [], []
    for _ in range(steps):
        action = policy.act(obs)
        targets.append(action)
        obs = task.step(action)
        positions.append(task.state.base_pos.copy())
    out["mujoco"], out["mujoco_diverged"] = np.array(positions), mujoco.diverged.copy()
    mujoco.close()
    warp = make_backend("mujoco-warp", spec, starts, terrain=terrain)
    task = RecoveryTask(spec, warp, terrain, starts)
    task.begin(settled)
    positions = []
    for action in targets:
        task.step(action)
        positions.append(task.state.base_pos.copy())
    out["warp"], out["warp_diverged"] = np.array(positions), warp.diverged.copy()
    warp.close()
    return out


def position_errors(run: dict) -> dict:
    """{time [s]: (median, 95th percentile) of ‖Δp‖ [m]} over the worlds neither simulator flagged."""
    from frbench.tasks.protocol import CONTROL_DT

    keep = ~(run["mujoco_diverged"] | run["warp_diverged"])
    errors = np.linalg.norm(run["mujoco"] - run["warp"], axis=2)[:, keep]
    out = {}
    for t in TIMES:
        step = int(round(t / CONTROL_DT)) - 1
        if step < len(errors) and errors.shape[1]:
            out[t] = (float(np.median(errors[step])), float(np.percentile(errors[step], 95)))
    return out


def trajectory_table(args) -> list[dict]:
    """Measure every (robot, family, level) of ``args`` and print one row each."""
    rows = []
    heads = "".join(f"{f'{t:g} s med / p95':>22}" for t in TIMES)
    print(f"{'robot':6} {'terrain':8} {'lvl':>3} {'n':>3} {'div C/W':>8}{heads}", flush=True)
    for robot in args.robots.split(","):
        for family in args.terrains.split(","):
            for level in (int(v) for v in args.levels.split(",")):
                start = time.perf_counter()
                run = trajectories(robot, family, level, args.starts, args.seconds)
                errors = position_errors(run)
                cells = "".join(f"{errors[t][0]:>10.1e} / {errors[t][1]:<9.1e}" if t in errors else f"{'-':>22}"
                                for t in TIMES)
                diverged = f"{int(run['mujoco_diverged'].sum())}/{int(run['warp_diverged'].sum())}"
                print(f"{robot:6} {family:8} {level:>3} {args.starts:>3} {diverged:>8}{cells}"
                      f"   ({time.perf_counter() - start:.0f} s)", flush=True)
                rows.append({"robot": robot, "terrain": family, "level": level, "starts": args.starts,
                             "diverged_mujoco": int(run["mujoco_diverged"].sum()),
                             "diverged_warp": int(run["warp_diverged"].sum()),
                             "error_m": {f"{t:g}": list(v) for t, v in errors.items()}})
    return rows


def success_table(path: str) -> list[dict]:
    """Successes per (robot, terrain, level) and simulator in a results file, pooled over seeds (module
    docstring); printed as a table."""
    from frbench.evaluation.intervals import wilson_interval

    cells = json.loads(open(path).read())["cells"]
    pooled: dict[tuple, dict[str, list[int]]] = {}
    for cell in cells:
        key = (cell["robot"], cell["terrain"], int(cell["level"]))
        counts = pooled.setdefault(key, {}).setdefault(cell["backend"], [0, 0])
        counts[0] += int(cell["successes"])
        counts[1] += int(cell["episodes"])
    rows = []
    print(f"{'robot':6} {'terrain':8} {'lvl':>3} {'MuJoCo C':>24} {'Warp':>24}  each in the other's interval")
    for (robot, family, level), counts in sorted(pooled.items()):
        (sc, nc), (sw, nw) = counts["mujoco"], counts["mujoco-warp"]
        ic, iw = wilson_interval(sc, nc), wilson_interval(sw, nw)
        within = ic[0] <= sw / nw <= ic[1] and iw[0] <= sc / nc <= iw[1]
        print(f"{robot:6} {family:8} {level:>3} {sc:>4}/{nc:<4} [{100 * ic[0]:4.1f}, {100 * ic[1]:5.1f}] "
              f"{sw:>4}/{nw:<4} [{100 * iw[0]:4.1f}, {100 * iw[1]:5.1f}]  {'yes' if within else 'NO'}")
        rows.append({"robot": robot, "terrain": family, "level": level, "mujoco": [sc, nc, *ic],
                     "mujoco-warp": [sw, nw, *iw], "within": within})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default="go2,g1")
    parser.add_argument("--terrains", default="flat,rough,stairs,slopes")
    parser.add_argument("--levels", default="1,5")
    parser.add_argument("--starts", type=int, default=16, help="settled starts per cell")
    parser.add_argument("--seconds", type=float, default=max(TIMES), help="trajectory length [s]")
    parser.add_argument("--scripted", help="summarise this results file instead of measuring trajectories")
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()
    rows = success_table(args.scripted) if args.scripted else trajectory_table(args)
    if args.json:
        from frbench.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
