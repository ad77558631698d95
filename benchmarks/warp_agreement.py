"""How closely MuJoCo Warp (``mujoco-warp``) follows MuJoCo C on frbench's episodes (docs/gpu.md).

**Trajectories.** For each robot, terrain family and level: ``--starts`` of the protocol's fallen starts
(seed 0, `draw_starts`) are placed and settled in MuJoCo C (`RecoveryTask.reset`: the benchmark's settle and
screening); from those settled states (velocities included, `RecordedStarts`) both simulators then run
``--seconds`` of the robot's hand-written controller (``scripted``; the G1 ``scripted-humanoid``): closed loop in
MuJoCo C, and the same joint targets replayed in Warp. Printed: the base position error ‖Δp‖ [m] at 0.1 / 0.5 /
1 / 2 s, median and 95th percentile over the starts (and the worlds either simulator flagged diverged).

**Speed.** ``--speed N``: world-steps per second (physics steps × worlds) of ``N`` worlds in MuJoCo Warp
(on its device: the GPU when present, else the CPU) and in MuJoCo C (its thread pool), each robot and terrain
family at level 5, the robots lying where their settled starts put them and tracking those angles.

**Success.** ``--scripted results.json``: a results file of ``frbench evaluate --policy scripted --backends
mujoco,mujoco-warp ...`` summarised per terrain and level: successes of each simulator pooled over seeds, with
Wilson 95 % intervals and whether each rate lies in the other's interval; then the episodes paired (the same
seed and episode index: the same drawn start, settled in each simulator): how many ended the same way, the
discordant pairs, and McNemar's exact p of the difference.

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
#: Seconds each ``--speed`` measurement steps for (after one warm-up step).
SPEED_SECONDS = 5.0


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


def speed_table(args) -> list[dict]:
    """World-steps per second of ``args.speed`` worlds in each simulator (module docstring); printed."""
    from common import timed

    from frbench.backends import make_backend
    from frbench.robots import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask
    from frbench.terrains import make_terrain

    n, rows = args.speed, []
    print(f"{'robot':6} {'terrain':8} {'worlds':>6} {'Warp':>12} {'MuJoCo C':>12}  world-steps/s")
    for robot in args.robots.split(","):
        spec = get_robot(robot)
        for family in args.terrains.split(","):
            terrain = make_terrain(family, 5, 0)
            rates = {}
            for name in ("mujoco-warp", "mujoco"):
                backend = make_backend(name, spec, n, terrain=terrain)
                task = RecoveryTask(spec, backend, terrain, n)
                task.reset(draw_starts(spec, terrain, family, 5, 0, range(n)))
                hold = task.state.q.copy()
                rates[name] = timed(lambda: backend.step(hold), SPEED_SECONDS) * backend.substeps * n  # noqa: B023
                backend.close()
            print(f"{robot:6} {family:8} {n:>6} {rates['mujoco-warp']:>12.0f} {rates['mujoco']:>12.0f}  "
                  f"(Warp on {_warp_device()})", flush=True)
            rows.append({"robot": robot, "terrain": family, "worlds": n, "warp_world_steps_per_s": rates["mujoco-warp"],
                         "mujoco_world_steps_per_s": rates["mujoco"], "warp_device": _warp_device()})
    return rows


def _warp_device() -> str:
    from frbench.backends.warp_model import warp_device

    return warp_device()


def mcnemar_p(only_first: int, only_second: int) -> float:
    """Two-sided exact McNemar p-value of paired outcomes: ``only_first`` pairs where only the first simulator
    succeeded, ``only_second`` where only the second did (a binomial test of the discordant pairs at 1/2)."""
    from math import comb

    n, k = only_first + only_second, min(only_first, only_second)
    if n == 0:
        return 1.0
    return min(1.0, 2 * sum(comb(n, i) for i in range(k + 1)) / 2 ** n)


def success_table(paths: str) -> list[dict]:
    """Successes per (robot, terrain, level) and simulator in results files (``paths``, comma-separated), pooled
    over seeds (module docstring), and the episodes paired by seed and index: how many ended the same way and
    McNemar's p of the difference; printed as a table."""
    from frbench.evaluation.intervals import wilson_interval

    episodes = [e for path in paths.split(",") for e in json.loads(open(path).read())["episodes"]]
    outcome = {(e["robot"], e["terrain"], int(e["level"]), e["backend"], int(e["seed"]), int(e["episode"])):
               bool(e["success"]) for e in episodes}
    groups = sorted({key[:3] for key in outcome})
    rows = []
    print(f"{'robot':6} {'terrain':8} {'lvl':>3} {'MuJoCo C':>22} {'Warp':>22}  within  same outcome  "
          f"C only / W only  McNemar p")
    for robot, family, level in groups:
        pairs = [(outcome[key], outcome.get((*key[:3], "mujoco-warp", *key[4:])))
                 for key in outcome if key[:4] == (robot, family, level, "mujoco")]
        pairs = [(c, w) for c, w in pairs if w is not None]
        n = len(pairs)
        sc, sw = sum(c for c, _ in pairs), sum(w for _, w in pairs)
        only_c, only_w = sum(c and not w for c, w in pairs), sum(w and not c for c, w in pairs)
        ic, iw = wilson_interval(sc, n), wilson_interval(sw, n)
        within = ic[0] <= sw / n <= ic[1] and iw[0] <= sc / n <= iw[1]
        p = mcnemar_p(only_c, only_w)
        print(f"{robot:6} {family:8} {level:>3} {sc:>4}/{n:<4}[{100 * ic[0]:5.1f},{100 * ic[1]:6.1f}] "
              f"{sw:>4}/{n:<4}[{100 * iw[0]:5.1f},{100 * iw[1]:6.1f}]  {'yes' if within else 'no':>6}  "
              f"{n - only_c - only_w:>5}/{n:<5}  {only_c:>8} / {only_w:<6}  {p:9.2f}")
        rows.append({"robot": robot, "terrain": family, "level": level, "episodes": n, "mujoco": [sc, *ic],
                     "mujoco-warp": [sw, *iw], "within": within, "same_outcome": n - only_c - only_w,
                     "only_mujoco": only_c, "only_warp": only_w, "mcnemar_p": p})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default="go2,g1")
    parser.add_argument("--terrains", default="flat,rough,stairs,slopes")
    parser.add_argument("--levels", default="1,5")
    parser.add_argument("--starts", type=int, default=16, help="settled starts per cell")
    parser.add_argument("--seconds", type=float, default=max(TIMES), help="trajectory length [s]")
    parser.add_argument("--scripted", help="summarise these results files (comma-separated) instead of measuring "
                                           "trajectories")
    parser.add_argument("--speed", type=int, help="time this many worlds instead")
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()
    rows = (success_table(args.scripted) if args.scripted else speed_table(args) if args.speed
            else trajectory_table(args))
    if args.json:
        from frbench.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
