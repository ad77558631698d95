"""The fall-recovery task: N episodes of one robot on one terrain in one backend.

The task never owns a simulator's details: it talks to the backend protocol
only, so it runs unchanged on MuJoCo and PyBullet. One episode:

1. ``reset(starts)``: place the drawn fallen configurations, settle them for
   `SETTLE_SECONDS` with the joints held softly at the drawn angles, then
   t = 0 (metrics start, displacement is measured from here);
2. ``step(targets)`` `EPISODE_STEPS` times: targets are joint angles q* [rad]
   in canonical order, clipped to the joint limits, tracked by the backend's PD;
3. read ``success``, ``time_to_recover`` and ``metrics``.
"""

from __future__ import annotations

import numpy as np

from frbench.backends import make_backend
from frbench.backends.base import CONTROL_DT, PhysicsParams, RobotState
from frbench.robots.spec import RobotSpec
from frbench.tasks.initial_states import SETTLE_GAIN_SCALE, SETTLE_SECONDS, FallenStarts
from frbench.tasks.observations import projected_gravity, proprioception
from frbench.tasks.protocol import EPISODE_SECONDS
from frbench.tasks.start_screening import screen_starts
from frbench.tasks.success import EpisodeMetrics, StartSurface, StepSignals, SuccessTracker, torso_frame

EPISODE_STEPS = int(round(EPISODE_SECONDS / CONTROL_DT))
SETTLE_STEPS = int(round(SETTLE_SECONDS / CONTROL_DT))


class RecoveryTask:
    """Batched recovery episodes (see the module docstring).

    Args:
        spec: the robot.
        backend: backend name (``"mujoco"`` or ``"pybullet"``).
        terrain: a `frbench.terrains.Terrain`.
        num_envs: episodes run side by side.
        noise_rng: a generator for sensor noise, or None for none (the default).

    After each ``step``: ``state`` (`RobotState`), ``contacts`` (`Contacts`) and ``signals`` (the
    `StepSignals` the success test read) of that step.
    """

    def __init__(self, spec: RobotSpec, backend: str, terrain, num_envs: int, noise_rng=None):
        self.spec = spec
        self.terrain = terrain
        self.num_envs = num_envs
        self.backend = make_backend(backend, spec, num_envs, terrain=terrain)
        self.noise_rng = noise_rng
        self.lower, self.upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
        self.default_pose = np.asarray(spec.default_pose)
        self.nominal = PhysicsParams.nominal(spec, num_envs)
        self.torso = torso_frame(spec)
        self.t = 0

    def close(self) -> None:
        """Free the simulator."""
        self.backend.close()

    def _height_above_terrain(self, base_pos: np.ndarray) -> np.ndarray:
        from frbench.terrains import height_at

        return base_pos[:, 2] - height_at(self.terrain, base_pos[:, :2])

    def settle(self, starts: FallenStarts) -> None:
        """Place the starts (one per environment) and settle them with the joints held softly."""
        n = self.num_envs
        soft = PhysicsParams.nominal(self.spec, n)
        soft.kp, soft.kd = soft.kp * SETTLE_GAIN_SCALE, soft.kd * SETTLE_GAIN_SCALE
        self.backend.set_params(soft)
        self.backend.reset(np.arange(n), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
        for _ in range(SETTLE_STEPS):
            self.backend.step(starts.q)
        self.backend.set_params(self.nominal)
        self.state = self.backend.state()
        self.start_xy = self.state.base_pos[:, :2].copy()
        self.start_surface = StartSurface(self.terrain, self.start_xy)

    def settled_upright(self) -> np.ndarray:
        """(N,) whether each settled start already lies within the success test's upright bound."""
        tracker = SuccessTracker(self.num_envs, self.spec.kind, self.spec.nominal_height)
        return tracker.up_pose(self._signals(self.backend.contacts()))

    def reset(self, starts: FallenStarts) -> dict[str, np.ndarray]:
        """Place and settle the starts, redrawing those already upright (`screen_starts`); the first observation."""
        n = self.num_envs
        self.settle(starts)
        self.starts = screen_starts(self, starts)
        self.previous_action = np.tile(self.default_pose, (n, 1))
        self.success = SuccessTracker(n, self.spec.kind, self.spec.nominal_height)
        self.metrics = EpisodeMetrics(n, self.spec.n_joints)
        self.settle_diverged = self.backend.diverged.copy()
        self.t = 0
        return self.observation()

    def _signals(self, contacts) -> StepSignals:
        """What the success test reads in the current state."""
        s = self.state
        return StepSignals(
            gravity_z=projected_gravity(s.base_quat)[:, 2],
            height=self._height_above_terrain(s.base_pos),
            body_contact=contacts.group_contact.any(axis=1),
            displacement=np.linalg.norm(s.base_pos[:, :2] - self.start_xy, axis=1),
            surface_drop=self.start_surface.drop(s.base_pos[:, :2]),
            torso_gravity_z=self.torso.gravity_z(s.base_quat, s.q) if self.torso else None,
        )

    def observation(self) -> dict[str, np.ndarray]:
        """The policy's proprioception (see `frbench.tasks.observations`)."""
        return proprioception(self.state, self.previous_action, self.noise_rng)

    def step(self, targets: np.ndarray) -> dict[str, np.ndarray]:
        """Advance one control step towards ``targets`` (N, n_joints) [rad]; return the observation."""
        targets = np.clip(targets, self.lower, self.upper)
        self.backend.step(targets)
        self.previous_action = targets
        self.state = self.backend.state()
        self.contacts = contacts = self.backend.contacts()
        diverged = self.backend.diverged | self.settle_diverged
        self.signals = signals = self._signals(contacts)
        self.success.update(signals, alive=~diverged)
        self.metrics.update(
            self.state.q, self.state.qd, self.state.tau, self.state.base_angvel[:, 0],
            contacts.body_force_max, signals.displacement, diverged,
        )
        self.t += 1
        return self.observation()
