"""Control steps per second on each terrain family at level 10, beside flat ground.

Go2 starts fallen (random orientation and joints) above the family's spawn
point and tracks random targets; each step is ``backend.step`` +
``backend.contacts()`` (what the task does). The families are timed in turn,
``--repeats`` rounds, and the medians printed with the cost ratio
flat steps/s ÷ family steps/s (target: no family above 1.3), followed by the
range of the ratios measured within each round (flat and the family timed
seconds apart, so a load change on the machine moves both less).

``--phases`` instead prints, for MuJoCo, where a physics step's time goes on
each family: one ``MjData`` runs the same fallen starts and targets for
``PHASE_STEPS`` control steps each, and MuJoCo's own timers (``mjTIMER_*``,
with OpenMP's ``omp_get_wtime`` as the clock) give µs per physics step, next to
the contacts, constraint rows and Newton iterations per step.

Run: ``python benchmarks/terrain_throughput.py [--seconds 1] [--repeats 3] [--phases]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import fallen, median_rates

from frbench.backends import make_backend
from frbench.robots import get_robot
from frbench.terrains import FAMILIES, make_terrain, support_height

SIZES = {"mujoco": 64, "pybullet": 4}
#: Control steps per start in ``--phases``: about what one timed second covers.
PHASE_STEPS = 110


def _starts(spec, terrain, n: int):
    """The benchmark's fallen starts and joint targets on ``terrain`` (seed 0)."""
    rng = np.random.default_rng(0)
    ground = support_height(terrain, terrain.spawn_xy, 0.6)
    start = fallen(spec, n, rng, xy=terrain.spawn_xy, z=ground + 0.5)
    targets = rng.uniform(spec.joint_lower, spec.joint_upper, size=(n, spec.n_joints))
    return start, targets


def measure(backend_name: str, level: int, seconds: float, repeats: int) -> dict[str, list[float]]:
    """Control steps/s (summed over the batch) per family, one value per round."""
    spec = get_robot("go2")
    n = SIZES[backend_name]
    loops, resets, closers = {}, {}, []
    for family in FAMILIES:
        terrain = make_terrain(family, level, 0)
        backend = make_backend(backend_name, spec, n, terrain=terrain)
        closers.append(backend.close)
        start, targets = _starts(spec, terrain, n)

        def loop(backend=backend, targets=targets):
            backend.step(targets)
            backend.contacts()

        loops[family] = loop
        resets[family] = (backend, start)

    def reset_all():
        for backend, start in resets.values():
            backend.reset(np.arange(n), start)

    rounds = [median_rates(loops, reset_all, seconds, 1) for _ in range(repeats)]
    for close in closers:
        close()
    return {family: [r[family] * n for r in rounds] for family in FAMILIES}


_PHASES = (
    ("step", "mjTIMER_STEP"),
    ("kinematics", "mjTIMER_POS_KINEMATICS"),
    ("broad", "mjTIMER_COL_BROAD"),
    ("mid+narrow", "mjTIMER_COL_NARROW"),
    ("solver", "mjTIMER_CONSTRAINT"),
)


def phases(level: int, n: int = 64, steps: int = PHASE_STEPS) -> dict[str, dict[str, float]]:
    """Per family: µs per physics step by MuJoCo timer, and contacts, constraint rows and
    solver iterations per physics step (means over ``n`` starts × ``steps`` control steps)."""
    import ctypes
    import ctypes.util

    import mujoco

    from frbench.backends.base import PhysicsParams, actuator_torque
    from frbench.backends.mujoco_model import build_model, joint_addresses
    from frbench.tasks.protocol import CONTROL_DT

    library = ctypes.util.find_library("gomp")
    if library is None:
        raise SystemExit("--phases needs libgomp (OpenMP) for a native clock")
    clock = ctypes.CFUNCTYPE(ctypes.c_double)(("omp_get_wtime", ctypes.CDLL(library)))
    timers = [int(getattr(mujoco.mjtTimer, name)) for _, name in _PHASES]
    spec = get_robot("go2")
    params, limits = PhysicsParams.nominal(spec, 1), np.asarray(spec.torque_limits)
    out = {}
    mujoco.set_mjcb_time(clock)
    try:
        for family in FAMILIES:
            terrain = make_terrain(family, level, 0)
            model = build_model(spec, terrain)
            data = mujoco.MjData(model)
            qadr, dadr = joint_addresses(model, spec)
            substeps = round(CONTROL_DT / model.opt.timestep)
            start, targets = _starts(spec, terrain, n)
            seconds, counts, total = np.zeros(len(timers)), np.zeros(3), 0
            for i in range(n):
                mujoco.mj_resetData(model, data)
                data.qpos[0:3] = start.base_pos[i]
                data.qpos[3:7] = start.base_quat[i] / np.linalg.norm(start.base_quat[i])
                data.qpos[qadr] = start.q[i]
                mujoco.mj_forward(model, data)
                for k in timers:
                    data.timer[k].duration = 0.0
                for _ in range(steps * substeps):  # the backend's physics steps per control step, PD at each
                    q, qd = data.qpos[qadr][None], data.qvel[dadr][None]
                    data.ctrl[:] = actuator_torque(params, limits, targets[i : i + 1], q, qd, 0)
                    mujoco.mj_step(model, data)
                    counts += (data.ncon, data.nefc, data.solver_niter[0])
                total += steps * substeps
                seconds += [data.timer[k].duration for k in timers]
            row = {name: 1e6 * s / total for (name, _), s in zip(_PHASES, seconds)}
            row.update(zip(("contacts", "rows", "iterations"), counts / total))
            row["boxes"] = len(terrain.boxes)
            out[family] = row
    finally:
        mujoco.set_mjcb_time(None)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--level", type=int, default=10)
    parser.add_argument("--phases", action="store_true", help="MuJoCo's time split per family instead")
    args = parser.parse_args()
    if args.phases:
        rows = phases(args.level)
        print(f"mujoco, one MjData, 64 starts x {PHASE_STEPS} control steps, level {args.level}: "
              "us per physics step by timer; contacts, constraint rows, Newton iterations per step")
        for family in FAMILIES:
            r = rows[family]
            print(f"  {family:<7} boxes {r['boxes']:>3}  " + "  ".join(f"{name} {r[name]:5.2f}" for name, _ in _PHASES)
                  + f"  | contacts {r['contacts']:.2f}  rows {r['rows']:.2f}  iterations {r['iterations']:.2f}")
        return
    for backend in ("mujoco", "pybullet"):
        rounds = measure(backend, args.level, args.seconds, args.repeats)
        rates = {family: float(np.median(values)) for family, values in rounds.items()}
        print(f"{backend} ({SIZES[backend]} envs, level {args.level}): control steps/s and cost vs flat "
              f"(median, then the range over the {args.repeats} rounds)")
        for family in FAMILIES:
            ratios = np.array(rounds["flat"]) / np.array(rounds[family])
            print(f"  {family:<7} {rates[family]:>9.0f}  cost x{rates['flat'] / rates[family]:.2f}"
                  f"  (x{ratios.min():.2f}-{ratios.max():.2f})")


if __name__ == "__main__":
    main()
