"""Joint targets from the policy's action: direct, or a residual over a base controller.

* `DirectTargets` (`frbench.tasks.actions`): q* = q̊ + action_scale·a (the paper's; legged_gym's scale);
* `ResidualController`: q* = base(o) + action_scale·a over a base controller's
  joint targets (residual policy learning), or base(o) + gate·action_scale·a
  with the controller's ``residual_gate(phases)`` (N,) when gated, so that
  exploration cannot break the motion outside the gate's phases (the rule
  training and deployment share, `frbench.policies.learned.residual_targets`).

Shapes: actions (N, J) in policy units, targets (N, J) [rad] (clipped later,
by the episode engine).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from frbench.arrays import to_host
from frbench.backends.base import RobotState
from frbench.policies.learned import residual_targets
from frbench.policies.registry import load_base_controller
from frbench.robots.spec import RobotSpec
from frbench.tasks.observations import proprioception


class ResidualController:
    """q* = base(o) [+ gate]·``scale``·a over the base controller ``name`` (a policy name, e.g.
    ``keyframe-humanoid``) with its tunable ``parameters``; see the module docstring.

    Raises ValueError when the controller does not support ``spec`` or, with ``gated``, has no
    ``residual_gate()``.
    """

    def __init__(self, name: str, parameters: Mapping[str, float], spec: RobotSpec, scale: float,
                 gated: bool = False, phases: tuple[str, ...] | None = None):
        self.name, self.parameters = name, dict(parameters)
        self.controller = load_base_controller(name, self.parameters)
        if gated and not hasattr(self.controller, "residual_gate"):
            raise ValueError(f"residual_gate: base controller {name!r} has no residual_gate()")
        if not self.controller.supports(spec):
            raise ValueError(f"base_controller {name!r} does not support {spec.name!r}")
        self.default_pose = np.asarray(spec.default_pose)
        self.scale, self.gated, self.phases = float(scale), bool(gated), phases

    def fresh_copy(self):
        """A new instance of the same base controller and parameters (its own phase state)."""
        return load_base_controller(self.name, self.parameters)

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """A new episode for every environment: the base controller starts its motion over."""
        self.controller.reset(spec, num_envs)

    def targets(self, state: RobotState, action) -> np.ndarray:
        """Joint targets (N, J) [rad]: the base controller's for ``state`` plus the (gated) residual ``action``. The
        controller runs on the host: a device's state and action come to it (the engine sends the targets back)."""
        base = np.asarray(self.controller.act(proprioception(state.on_host(), self.default_pose)), dtype=np.float64)
        return residual_targets(base, to_host(action), self.scale, self.controller, self.gated, self.phases)

    def enter_gate(self, ids: np.ndarray, targets: np.ndarray, q: np.ndarray, paths: np.ndarray) -> None:
        """Put environments ``ids`` in the phase where the gate opened (rise starts): their recorded controller
        ``targets`` (M, J) [rad], the current joint angles ``q`` (N, J) and ways to the crouch ``paths`` (M,)."""
        self.controller.enter_gate(ids, targets, q, paths)
