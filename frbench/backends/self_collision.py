"""Self-collision of a robot at given joint angles, by MuJoCo's collision detection.

The protocol's start draw (`frbench.tasks.initial_states`) redraws joint angles
whose links overlap; the test runs here, in the backends layer, with the same
self-collision exclusions the simulations use, so that the tasks never import a
simulator.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain


@lru_cache(maxsize=32)
def _self_collision_model(spec: RobotSpec):
    """MuJoCo model and data of the robot alone, with the backends' self-collision exclusions."""
    import mujoco

    from frbench.backends.mujoco_model import build_model, joint_addresses
    model = build_model(spec, make_terrain("flat", 1, 0))
    return model, mujoco.MjData(model), joint_addresses(model, spec)[0]


def self_intersects(spec: RobotSpec, q: np.ndarray) -> bool:
    """Whether two links of the robot overlap at joint angles ``q`` (n_joints,) [rad]."""
    import mujoco

    model, data, qadr = _self_collision_model(spec)
    data.qpos[:] = model.qpos0
    data.qpos[2] = 100.0  # far above the floor: only self-contacts remain
    data.qpos[qadr] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    return bool(np.any(data.contact.dist[: data.ncon] < 0))
