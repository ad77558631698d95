"""Action transforms: how a policy's action becomes joint targets, shared by the training env and the Gymnasium
envs. `DirectTargets` is the paper's rule, q* = q̊ + scale·a; the residual over a base controller, which needs the
policies, is `frbench.training.residual.ResidualController`; held actions are `frbench.training.action_hold`.

Each transform has ``reset(spec, num_envs)`` and ``targets(state, action) -> (N, J) [rad]`` (actions (N, J) in
policy units, numpy or torch: the targets come in the action's namespace; the episode engine clips them to the
joint limits).
"""

from __future__ import annotations

import numpy as np

from frbench.arrays import resident
from frbench.backends.base import RobotState
from frbench.robots.spec import RobotSpec

#: q* = q̊ + ACTION_SCALE · a: the shipped policies' scale (their checkpoints' and ONNX sidecars' action_scale)
#: and the Gymnasium envs' default.
ACTION_SCALE = 1.0


class DirectTargets:
    """q* = q̊ + ``scale``·a for a robot whose default pose is ``default_pose`` (J,) [rad]."""

    def __init__(self, default_pose: np.ndarray, scale: float):
        self.default_pose, self.scale = np.asarray(default_pose), float(scale)

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """A new episode for every environment (nothing to do)."""

    def targets(self, state: RobotState, action):
        """Joint targets (N, J) [rad] of ``action`` (N, J), numpy or torch."""
        return resident(self.default_pose, action) + self.scale * action
