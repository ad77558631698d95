"""Hold a robot's default pose with its PD on flat ground: a physics-only routine below the tasks.

The measured standing height and the robot check (`frbench.robot_checks`) and the training's feasibility filter
(`frbench.training.feasibility`) all run it; it steps a backend it builds and closes itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.backends import make_backend
from frbench.backends.base import CONTROL_DT, Contacts, PhysicsParams, RobotState
from frbench.robots.spec import RobotSpec


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
