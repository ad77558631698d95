"""`RewardInputs`: what frbench's reward terms (`frbench.training.rewards`) read at one control step.

`frbench.training.step_reward.StepReward` builds it from the episode engine after each step; tests build it by
hand. Arrays have N rows (environments), SI units: numpy arrays (evaluation, the CPU trainer) or torch tensors on
one device (the training env on MuJoCo Warp, `frbench.training.env`); the reward terms compute in the namespace of
``projected_gravity`` (`frbench.arrays`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frbench.arrays import float_dtype, like, namespace


@dataclass
class RewardInputs:
    """What the reward terms read at one control step; arrays with N rows, SI units.

    Attributes:
        projected_gravity: (N, 3) unit gravity direction in the body frame; (0, 0, −1) upright.
        q: (N, J) joint angles [rad].
        qd: (N, J) joint velocities [rad/s].
        qd_prev: (N, J) joint velocities one control step earlier [rad/s].
        tau: (N, J) applied torques [N·m].
        action: (N, J) policy action a_t (offset units, whatever the policy emits).
        action_prev: (N, J) the previous action a_{t−1}.
        q_stand: (J,) or (N, J) target standing posture [rad].
        q_lower, q_upper: (J,) or (N, J) joint position limits [rad].
        foot_contact: (N, F) bool, each foot touches something.
        body_contact: (N,) bool, any non-foot link touches anything.
        knee_force_xy: (N, K) horizontal contact force norm on each knee group [N].
        base_xy: (N, 2) base position [m].
        init_xy: (N, 2) base position at the episode start [m].
        dt: control period [s].
        base_height: (N,) base height above the terrain beneath it [m] (only
            the frbench ``base_height`` term reads it).
        nominal_height: (N,) or scalar standing base height [m].
        head_height: (N,) head height above the terrain beneath it [m] (humanoid terms).
        nominal_head_height: (N,) or scalar standing head height [m].
        action_prev2: (N, J) the action before the previous one, a_{t−2} (``action_jerk``).
        upper_body: (J,) bool, the joints of the waist and arms (``upper_body_posture``).
    """

    projected_gravity: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qd_prev: np.ndarray
    tau: np.ndarray
    action: np.ndarray
    action_prev: np.ndarray
    q_stand: np.ndarray
    q_lower: np.ndarray
    q_upper: np.ndarray
    foot_contact: np.ndarray
    body_contact: np.ndarray
    knee_force_xy: np.ndarray
    base_xy: np.ndarray
    init_xy: np.ndarray
    dt: float = 0.02
    base_height: np.ndarray | None = None
    nominal_height: np.ndarray | float | None = None
    head_height: np.ndarray | None = None
    nominal_head_height: np.ndarray | float | None = None
    action_prev2: np.ndarray | None = None
    upper_body: np.ndarray | None = None

    @property
    def xp(self):
        """The array namespace the terms compute in: that of ``projected_gravity``."""
        return namespace(self.projected_gravity)

    def as_float(self, value):
        """``value`` (an array, sequence or scalar) as an array of the terms' namespace, device and float dtype
        (float64 for numpy; ``projected_gravity``'s for torch); no copy when it already is one."""
        ref = self.projected_gravity
        return like(value, ref, float_dtype(self.xp, ref))

    def as_bool(self, value):
        """``value`` as a boolean array of the terms' namespace and device."""
        return like(value, self.projected_gravity, self.xp.bool)

    @property
    def num_envs(self) -> int:
        """N."""
        return int(np.shape(self.projected_gravity)[0])

    def check(self) -> None:
        """Raise ``ValueError`` naming the first array whose shape does not fit (N, J) etc."""
        n = self.num_envs
        if np.shape(self.projected_gravity) != (n, 3):
            raise ValueError(f"projected_gravity has shape {np.shape(self.projected_gravity)}, expected (N, 3)")
        j = np.shape(self.q)[-1] if np.ndim(self.q) == 2 else -1
        for name in ("q", "qd", "qd_prev", "tau", "action", "action_prev"):
            if np.shape(getattr(self, name)) != (n, j):
                raise ValueError(f"{name} has shape {np.shape(getattr(self, name))}, expected ({n}, {j})")
        for name in ("q_stand", "q_lower", "q_upper"):
            if np.shape(getattr(self, name)) not in ((j,), (n, j)):
                raise ValueError(f"{name} has shape {np.shape(getattr(self, name))}, expected ({j},) or ({n}, {j})")
        for name, shape in (("body_contact", (n,)), ("base_xy", (n, 2)), ("init_xy", (n, 2))):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name} has shape {np.shape(getattr(self, name))}, expected {shape}")
        for name in ("foot_contact", "knee_force_xy"):
            value = getattr(self, name)
            if np.ndim(value) != 2 or np.shape(value)[0] != n:
                raise ValueError(f"{name} has shape {np.shape(value)}, expected ({n}, k)")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be positive, got {self.dt!r}")
