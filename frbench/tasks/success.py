"""The success test and the per-episode metrics, on trajectories of any length.

Quadrupeds (docs/protocol.md): at some time within the episode the robot is
*stably upright* — body tilt at most `MAX_TILT_DEG` from vertical, base at least
`MIN_HEIGHT_FRACTION` of its nominal height above the terrain beneath it, no
body part but the feet touching anything — for `HOLD_SECONDS` without a break,
and its horizontal displacement from the start is under `MAX_DISPLACEMENT` at
the end of that hold.

Humanoids use HoST's rule, scaled to the robot: the base rises above
0.7 m·(nominal/0.78) at some time and never drops below 0.5 m·(nominal/0.78)
afterwards, with the same displacement limit.

`EpisodeMetrics` accumulates, per environment and control step: energy
∫|τ·q̇|dt [J], smoothness (mean |Δ²q| [rad]), peak non-foot contact force [N],
roll (∫ω_x dt, rolled over when its magnitude exceeds π at any time), final and
maximum displacement [m], divergence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.tasks.protocol import CONTROL_DT

MAX_TILT_DEG = 30.0
MIN_HEIGHT_FRACTION = 0.75
HOLD_SECONDS = 0.5
MAX_DISPLACEMENT = 1.0
HUMANOID_UP_HEIGHT = 0.7
HUMANOID_FLOOR_HEIGHT = 0.5
HUMANOID_REFERENCE_HEIGHT = 0.78
HOLD_STEPS = int(round(HOLD_SECONDS / CONTROL_DT))


@dataclass
class StepSignals:
    """What the success test and the metrics read at one control step, each with N rows.

    Attributes:
        gravity_z: projected gravity z (N,) (−1 upright).
        height: base height above the terrain beneath it (N,) [m].
        body_contact: any non-foot link touches something (N,).
        displacement: horizontal distance of the base from its start (N,) [m].
    """

    gravity_z: np.ndarray
    height: np.ndarray
    body_contact: np.ndarray
    displacement: np.ndarray


class SuccessTracker:
    """Online success test for N episodes (see the module docstring)."""

    def __init__(self, num_envs: int, kind: str, nominal_height: "float | np.ndarray"):
        """``nominal_height`` [m]: one value, or one per environment (N,) when robots differ."""
        self.kind = kind
        self.nominal_height = nominal_height
        self.success = np.zeros(num_envs, dtype=bool)
        self.time_to_recover = np.full(num_envs, np.nan)
        self._streak = np.zeros(num_envs, dtype=int)
        self._reached = np.full(num_envs, -1, dtype=int)  # humanoid: step the base first got up
        self._fell_after = np.zeros(num_envs, dtype=bool)
        self._step = 0
        scale = nominal_height / HUMANOID_REFERENCE_HEIGHT
        self.up_height, self.floor_height = HUMANOID_UP_HEIGHT * scale, HUMANOID_FLOOR_HEIGHT * scale

    def up_pose(self, s: StepSignals) -> np.ndarray:
        """(N,) tilt and height conditions of the quadruped test (body contact not considered)."""
        tilt_ok = s.gravity_z <= -np.cos(np.radians(MAX_TILT_DEG))
        return tilt_ok & (s.height >= MIN_HEIGHT_FRACTION * self.nominal_height)

    def upright(self, s: StepSignals) -> np.ndarray:
        """(N,) the quadruped stability condition at this step."""
        return self.up_pose(s) & ~s.body_contact

    def update(self, s: StepSignals, alive: np.ndarray | None = None) -> None:
        """Feed one control step (``alive`` False for diverged episodes, which cannot succeed)."""
        alive = np.ones_like(self.success) if alive is None else alive
        self._step += 1
        if self.kind == "humanoid":
            newly_up = (self._reached < 0) & (s.height > self.up_height) & alive & (s.displacement < MAX_DISPLACEMENT)
            self._reached[newly_up] = self._step
            self._fell_after |= (self._reached >= 0) & (s.height < self.floor_height)
            self.success = (self._reached >= 0) & ~self._fell_after & alive
            self.time_to_recover = np.where(self.success, self._reached * CONTROL_DT, np.nan)
            return
        up = self.upright(s) & alive
        self._streak = np.where(up, self._streak + 1, 0)
        done = (self._streak >= HOLD_STEPS) & ~self.success & (s.displacement < MAX_DISPLACEMENT)
        self.time_to_recover[done] = (self._step - HOLD_STEPS + 1) * CONTROL_DT
        self.success |= done
        self.success &= alive


class EpisodeMetrics:
    """Per-episode metrics of N environments (see the module docstring)."""

    def __init__(self, num_envs: int, n_joints: int):
        self.energy = np.zeros(num_envs)
        self.peak_contact_force = np.zeros(num_envs)
        self.max_displacement = np.zeros(num_envs)
        self.final_displacement = np.zeros(num_envs)
        self.roll = np.zeros(num_envs)
        self.rolled_over = np.zeros(num_envs, dtype=bool)
        self.diverged = np.zeros(num_envs, dtype=bool)
        self._second_diff_sum = np.zeros(num_envs)
        self._second_diff_count = 0
        self._q_prev = None
        self._q_prev2 = None

    def update(self, q, qd, tau, angvel_x, body_force_max, displacement, diverged) -> None:
        """Feed one control step: q, qd, tau (N, n_joints); angvel_x, body_force_max, displacement (N,)."""
        ok = ~diverged
        self.energy += np.where(ok, np.abs(tau * qd).sum(axis=1) * CONTROL_DT, 0.0)
        self.peak_contact_force = np.maximum(self.peak_contact_force, np.where(ok, body_force_max, 0.0))
        self.max_displacement = np.maximum(self.max_displacement, np.where(ok, displacement, 0.0))
        self.final_displacement = np.where(ok, displacement, self.final_displacement)
        self.roll += np.where(ok, angvel_x * CONTROL_DT, 0.0)
        self.rolled_over |= np.abs(self.roll) > np.pi
        self.diverged |= diverged
        if self._q_prev2 is not None:
            self._second_diff_sum += np.where(ok, np.abs(q - 2 * self._q_prev + self._q_prev2).mean(axis=1), 0.0)
            self._second_diff_count += 1
        self._q_prev2, self._q_prev = self._q_prev, q.copy()

    @property
    def smoothness(self) -> np.ndarray:
        """Mean |Δ²q| per episode [rad] (0 for episodes shorter than three steps)."""
        return self._second_diff_sum / max(self._second_diff_count, 1)
