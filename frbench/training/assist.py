"""The assist force: a vertical push on the base, a fraction of the robot's weight, fading out.

HoST's curriculum for humanoids: early in training the robot is helped up by
an upward force of ``fraction`` × its weight at the base's centre of mass,
the fraction falling linearly to 0 at ``until`` env steps. Evaluation never
applies it. The force is set for a whole episode at its start.
"""

from __future__ import annotations

import numpy as np

from frbench.training.demo_starts import assist_probability

#: Standard gravity [m/s²] (both backends simulate g = 9.81 downwards).
GRAVITY = 9.81


class AssistForce:
    """An assist of ``initial`` × weight fading to 0 at ``until`` env steps, for robots of ``masses`` (N, G) [kg]
    (group masses, payload included; their sum is each robot's mass)."""

    def __init__(self, initial: float, until: float, masses: np.ndarray):
        self.initial, self.until = float(initial), float(until)
        self.mass = np.asarray(masses).sum(axis=1)
        self.fraction = 0.0

    def clear(self, env) -> None:
        """No force on the robots of ``env`` (the core env, `frbench.tasks.core_env.CoreEnv`; before a start is
        settled)."""
        env.set_base_force(np.zeros((env.num_envs, 3)))

    def apply(self, env, env_steps: int) -> None:
        """The episode's force on the robots of ``env`` (the core env), upwards [N], for a run at ``env_steps`` env
        steps."""
        self.fraction = assist_probability(self.initial, self.until, env_steps)
        force = np.zeros((env.num_envs, 3))
        force[:, 2] = self.fraction * self.mass * GRAVITY
        env.set_base_force(force)
