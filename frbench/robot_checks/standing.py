"""The measured standing height of a robot: settle it in both simulators, average.

The robot starts upright at its default pose with its feet 1 cm over flat
ground and holds the pose with its PD for `SETTLE_SECONDS`; the root height
is averaged over the last `AVERAGE_SECONDS` in MuJoCo and in PyBullet. The
nominal height is the mean of the two. Results are cached in
``<cache>/standing/`` by the spec's content (the cache is pruned like the
simulation URDFs, see `frbench.robots.sim_urdf.prune_cache`).
:func:`frbench.robot_checks.lookup.get_robot` gives a robot added by path this
height; `frbench.robots` only derives the kinematic one (it runs no simulator).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from frbench.backends.base import CONTROL_DT
from frbench.backends.hold import hold_default_pose
from frbench.io import atomic_write_text, sha256_text
from frbench.robots.paths import cache_dir
from frbench.robots.sim_urdf import prune_cache, sim_robot_file
from frbench.robots.spec import RobotSpec

SETTLE_SECONDS = 2.0
AVERAGE_SECONDS = 0.2
BACKEND_NAMES = ("mujoco", "pybullet")
MEASURE_VERSION = 1


def settle(spec: RobotSpec, backend_name: str, seconds: float = SETTLE_SECONDS) -> dict:
    """Hold the default pose on flat ground; the root height [m] averaged at the end, and divergence."""
    held = hold_default_pose(spec, backend_name, seconds, max(1, int(round(AVERAGE_SECONDS / CONTROL_DT))))
    height, diverged = float(np.mean(held.heights)), held.diverged
    return {"height": height if np.isfinite(height) else float("nan"), "diverged": diverged or not np.isfinite(height)}


def measured_height(spec: RobotSpec) -> dict:
    """{"nominal_height": mean [m], "mujoco": {...}, "pybullet": {...}} for ``spec`` (cached)."""
    fields = dataclasses.asdict(spec)
    for key in ("name", "source", "license", "notes", "extra", "nominal_height"):
        fields.pop(key, None)
    key = sha256_text(f"v{MEASURE_VERSION}:{sim_robot_file(spec).sha256}:{spec.nominal_height:.6f}:{fields!r}")[:20]
    path = cache_dir() / "standing" / f"{key}.json"
    if path.is_file():
        try:
            path.touch()
            return json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            pass
    result = {name: settle(spec, name) for name in BACKEND_NAMES}
    heights = [result[name]["height"] for name in BACKEND_NAMES]
    result["nominal_height"] = float(np.mean(heights)) if all(np.isfinite(heights)) else float("nan")
    atomic_write_text(path, json.dumps(result))
    prune_cache(path.parent)
    return result
