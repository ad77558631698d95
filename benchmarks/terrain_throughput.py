"""Control steps per second on each terrain family at level 10, beside flat ground.

Go2 starts fallen (random orientation and joints) above the family's spawn
point and tracks random targets; each step is ``backend.step`` +
``backend.contacts()`` (what the task does). The families are timed in turn,
``--repeats`` times, and the medians printed with the cost ratio
flat steps/s ÷ family steps/s (target: no family above 1.3).

Run: ``python benchmarks/terrain_throughput.py [--seconds 1] [--repeats 3]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import fallen, median_rates

from frbench.backends import make_backend
from frbench.robots import get_robot
from frbench.terrains import FAMILIES, make_terrain, support_height

SIZES = {"mujoco": 64, "pybullet": 4}


def measure(backend_name: str, level: int, seconds: float, repeats: int) -> dict[str, float]:
    """Median control steps/s (summed over the batch) per family."""
    spec = get_robot("go2")
    n = SIZES[backend_name]
    loops, resets, closers = {}, {}, []
    for family in FAMILIES:
        terrain = make_terrain(family, level, 0)
        backend = make_backend(backend_name, spec, n, terrain=terrain)
        closers.append(backend.close)
        rng = np.random.default_rng(0)
        ground = support_height(terrain, terrain.spawn_xy, 0.6)
        start = fallen(spec, n, rng, xy=terrain.spawn_xy, z=ground + 0.5)
        targets = rng.uniform(spec.joint_lower, spec.joint_upper, size=(n, spec.n_joints))

        def loop(backend=backend, targets=targets):
            backend.step(targets)
            backend.contacts()

        loops[family] = loop
        resets[family] = (backend, start)

    def reset_all():
        for backend, start in resets.values():
            backend.reset(np.arange(n), start)

    rates = median_rates(loops, reset_all, seconds, repeats)
    for close in closers:
        close()
    return {family: rate * n for family, rate in rates.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--level", type=int, default=10)
    args = parser.parse_args()
    for backend in ("mujoco", "pybullet"):
        rates = measure(backend, args.level, args.seconds, args.repeats)
        print(f"{backend} ({SIZES[backend]} envs, level {args.level}): control steps/s and cost vs flat")
        for family in FAMILIES:
            print(f"  {family:<7} {rates[family]:>9.0f}  cost x{rates['flat'] / rates[family]:.2f}")


if __name__ == "__main__":
    main()
