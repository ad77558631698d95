"""Hold a robot's default pose with its PD on flat ground: a physics-only routine below the tasks.

The measured standing height and the robot check (`frbench.robot_checks`) and the training's feasibility filter
(`frbench.training.feasibility`) all run it; it steps a backend it builds and closes itself. The drop tests
that compare the simulators (`drop_height`, docs/physx.md) hold the pose from other starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.backends import make_backend
from frbench.backends.base import CONTROL_DT, Contacts, PhysicsParams, RobotState
from frbench.robots.spec import RobotSpec
from frbench.terrains.geometry import Box, Terrain

#: Drop tests: name → (base position [m], base quaternion w, x, y, z, on the two-box step (else flat ground)).
DROP_TESTS = {
    "upright from 0.45 m": ((0.0, 0.0, 0.45), (1.0, 0.0, 0.0, 0.0), False),
    "side-lying from 0.25 m": ((0.0, 0.0, 0.25), (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0), False),
    "over a two-box step": ((0.0, 0.0, 0.45), (1.0, 0.0, 0.0, 0.0), True),
}


@dataclass(frozen=True)
class HeldPose:
    """The end of `hold_default_pose`: root heights [m] of the last steps (T,), the final `RobotState` and
    `Contacts` (one simulation) and whether the simulation diverged."""

    heights: tuple[float, ...]
    state: RobotState
    contacts: Contacts
    diverged: bool


def hold_default_pose(spec: RobotSpec, backend_name: str, seconds: float, tail_steps: int = 1,
                      params: PhysicsParams | None = None, start: RobotState | None = None,
                      terrain=None) -> HeldPose:
    """Start ``spec`` upright at its default pose over flat ground in ``backend_name`` and hold the pose with its PD
    for ``seconds``; the root height of each of the last ``tail_steps`` control steps. ``params``: the physics
    (gains, friction, ...) for one environment (None: the robot's nominal); ``start``: another start (one
    simulation, e.g. a drop from higher up or on the side); ``terrain``: another terrain than flat ground."""
    backend = make_backend(backend_name, spec, 1, terrain=terrain)
    steps = int(round(seconds / CONTROL_DT))
    heights = []
    try:
        if params is not None:
            backend.set_params(params)
        backend.reset(np.arange(1), RobotState.standing(spec, 1) if start is None else start)
        targets = np.asarray(spec.default_pose)[None]
        for step in range(steps):
            backend.step(targets)
            if step >= steps - tail_steps:
                heights.append(float(backend.state().base_pos[0, 2]))
        return HeldPose(tuple(heights), backend.state(), backend.contacts(), bool(backend.diverged[0]))
    finally:
        backend.close()


def two_box_step() -> Terrain:
    """Two boxes 1 m × 2 m, tops at 0.02 m (x < 0) and 0.07 m (x > 0): a 5 cm step whose edge runs under a robot
    placed at the origin, so that its front and rear feet land on different boxes."""
    boxes = (Box((-0.5, 0.0, 0.01), (0.5, 1.0, 0.01)), Box((0.5, 0.0, 0.035), (0.5, 1.0, 0.035)))
    return Terrain("stairs", 1, -1, boxes=boxes, floor_z=0.0, spawn_xy=(0.0, 0.0), spawn_yaw=0.0,
                   description="two-box step (drop test)")


def drop_height(spec: RobotSpec, backend_name: str, drop: str, seconds: float = 2.0) -> float:
    """The root height [m] after ``spec``, at rest in its default pose, is dropped as `DROP_TESTS` ``drop`` says and
    holds the pose with its PD for ``seconds`` in ``backend_name``."""
    pos, quat, on_step = DROP_TESTS[drop]
    start = RobotState.at_rest([pos], quat, [spec.default_pose])
    held = hold_default_pose(spec, backend_name, seconds, start=start, terrain=two_box_step() if on_step else None)
    return held.heights[-1]
