"""Env steps per second of the PhysX backend against the MuJoCo backend, same robot, terrain and batch, one run.

For each robot and terrain, ``--envs`` simulations start fallen (random orientation and joints, 0.5 m up,
`common.fallen`) and track random joint targets; one env step is what the task asks of a backend every
control step: ``backend.step(targets)`` then ``backend.contacts()``. The loops are timed in turn,
``--repeats`` times, medians printed (the machine is noisy):

* physx: `frbench.backends.physx_backend.PhysxBackend` (one SAPIEN scene per simulation, one thread);
* physx 10/1: the same with 10 position and 1 velocity solver iterations instead of the backend's 4 and 0
  (legged_gym's ``LeggedRobotCfg.sim.physx``), what more solver iterations would cost (a measurement only);
* physx raw: the backend's scenes stepped ``substeps`` times with no PD, state or contacts: PhysX's own cost, the
  ceiling of the backend;
* mujoco 1 thread: `MujocoBackend` with ``nthread=1``, as each ``frbench evaluate`` worker runs it;
* mujoco N threads: `MujocoBackend` on every core (its default, e.g. the Gymnasium env and training).

Ratio = physx / mujoco at 1 thread and at N threads; the goal is >= 0.8 (the raw ratio: what PhysX alone allows).

Run: ``python benchmarks/physx_throughput.py [--envs 8] [--seconds 1] [--repeats 5]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import fallen, median_rates

from frbench.backends import make_backend
from frbench.backends.mujoco_backend import MujocoBackend, default_threads
from frbench.backends.physx_backend import PhysxBackend
from frbench.backends.physx_scene import PhysxSettings
from frbench.robots import get_robot
from frbench.terrains import make_terrain

CASES = (("go2", "flat", 1), ("go2", "rough", 5), ("g1", "flat", 1))


def measure(robot: str, family: str, level: int, envs: int, seconds: float, repeats: int) -> dict[str, float]:
    """Median env steps/s (summed over the batch) of each backend on one robot and terrain."""
    spec = get_robot(robot)
    terrain = make_terrain(family, level, 0)
    rng = np.random.default_rng(0)
    targets = rng.uniform(spec.joint_lower, spec.joint_upper, size=(envs, spec.n_joints))
    start = fallen(spec, envs, rng, xy=terrain.spawn_xy, z=terrain.top_z + 0.5)
    backends = {
        "physx": make_backend("physx", spec, envs, terrain=terrain),
        "physx 10/1": PhysxBackend(spec, envs, terrain=terrain,
                                   settings=PhysxSettings(position_iterations=10, velocity_iterations=1)),
        "mujoco 1 thread": MujocoBackend(spec, envs, terrain=terrain, nthread=1),
        f"mujoco {default_threads()} threads": MujocoBackend(spec, envs, terrain=terrain, nthread=default_threads()),
    }

    def env_step(backend):
        def loop():
            backend.step(targets)
            backend.contacts()
        return loop

    def reset():
        for backend in backends.values():
            backend.reset(np.arange(envs), start)

    loops = {name: env_step(b) for name, b in backends.items()}
    physx = backends["physx"]

    def raw():
        for sim in physx.sims:
            for _ in range(physx.substeps):
                sim.scene.step()

    loops["physx raw"] = raw
    rates = median_rates(loops, reset, seconds, repeats)
    for backend in backends.values():
        backend.close()
    return {name: rate * envs for name, rate in rates.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=8, help="simulations per backend (default 8, a cell's episodes)")
    parser.add_argument("--seconds", type=float, default=1.0, help="timing window per measurement")
    parser.add_argument("--repeats", type=int, default=5, help="measurements per loop (median reported)")
    args = parser.parse_args()
    threads = default_threads()
    print(f"env steps/s (step + contacts) summed over {args.envs} simulations, medians of {args.repeats}")
    print(f"{'robot':<5} {'terrain':<9} {'physx':>8} {'mujoco 1t':>10} {f'mujoco {threads}t':>10} {'ratio 1t':>9} "
          f"{f'ratio {threads}t':>9} {'physx 10/1':>10} {'ratio 1t':>9} {'physx raw':>10} {'ratio 1t':>9}")
    for robot, family, level in CASES:
        r = measure(robot, family, level, args.envs, args.seconds, args.repeats)
        one, many = r["mujoco 1 thread"], r[f"mujoco {threads} threads"]
        print(f"{robot:<5} {family + ' L' + str(level):<9} {r['physx']:>8.0f} {one:>10.0f} {many:>10.0f} "
              f"{r['physx'] / one:>9.2f} {r['physx'] / many:>9.2f} {r['physx 10/1']:>10.0f} {r['physx 10/1'] / one:>9.2f} "
              f"{r['physx raw']:>10.0f} {r['physx raw'] / one:>9.2f}")


if __name__ == "__main__":
    main()
