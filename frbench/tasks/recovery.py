"""The fall-recovery episode engine: N episodes of one robot in one backend.

The engine never owns a simulator's details: it talks to the backend protocol
only, so it runs unchanged on MuJoCo, PyBullet and the split batch. It is the
one episode of frbench: ``frbench evaluate``, the gymnasium env and the
training env (`frbench.training.env`) all drive it. One episode:

1. ``reset(starts)``: place the drawn fallen configurations, settle them for
   ``settle_steps`` control steps (`SETTLE_STEPS` = `SETTLE_SECONDS` in the
   benchmark) with the joints held at the drawn angles on gains scaled by
   `SETTLE_GAIN_SCALE`, redraw the starts that already lie upright
   (`frbench.tasks.start_screening`), then t = 0 (success tracking and metrics
   start, displacement and the start surface are measured from here);
2. ``step(targets)`` `EPISODE_STEPS` times (training: its own episode length):
   targets are joint angles q* [rad] in canonical order, clipped to the joint
   limits, tracked by the backend's PD; each step computes the `StepSignals`
   the success test reads;
3. read ``success``, ``time_to_recover`` and ``metrics``.

Training adds, between 1 and 2, ``restart(ids, state)``: some episodes start
from recorded states instead (demo and rise starts, `frbench.training.start_sources`).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from frbench.backends import make_backend
from frbench.backends.contact_layout import vector_norm
from frbench.backends.base import PhysicsParams, RobotState
from frbench.robots.spec import RobotSpec
from frbench.tasks.initial_states import SETTLE_GAIN_SCALE, SETTLE_SECONDS, FallenStarts
from frbench.tasks.observations import projected_gravity, proprioception
from frbench.tasks.protocol import CONTROL_DT, EPISODE_SECONDS
from frbench.tasks.start_screening import screen_starts
from frbench.tasks.success import EpisodeMetrics, StartSurface, StepSignals, SuccessTracker, torso_frame
from frbench.terrains import height_at

EPISODE_STEPS = int(round(EPISODE_SECONDS / CONTROL_DT))
SETTLE_STEPS = int(round(SETTLE_SECONDS / CONTROL_DT))


def settle_params(params: PhysicsParams) -> PhysicsParams:
    """The settle's physics: ``params``' gains scaled by `SETTLE_GAIN_SCALE` ("held softly"), its strength,
    friction and payload, no motor friction."""
    return PhysicsParams(params.kp * SETTLE_GAIN_SCALE, params.kd * SETTLE_GAIN_SCALE, params.motor_strength,
                         params.friction, params.payload)


class RecoveryTask:
    """Batched recovery episodes (see the module docstring).

    Args:
        spec: the robot (its joint limits clip the targets; its kind picks the success test).
        backend: a backend instance (the `frbench.backends.base.Backend` protocol) with ``num_envs``
            simulations, or a backend name (``"mujoco"``, ``"pybullet"``), built here on ``terrain``.
        terrain: a `frbench.terrains.Terrain` (the ground height under the base is read from it), or None
            when ``ground_height`` is given.
        num_envs: episodes run side by side.
        noise_rng: a generator for sensor noise, or None for none (the default).
        ground_height: (N, 2) world xy [m] → (N,) terrain height [m] under each base; default: ``terrain``'s.
        nominal_height: the standing height [m] of the success test, one value or (N,) when robots differ;
            default: the spec's.
        track_metrics: keep the per-episode `EpisodeMetrics` (the benchmark's; training does without).
        surface_rules: apply protocol 1.1's surface rule (`StartSurface`, on ``terrain``) and a humanoid's
            torso-tilt rule (`TorsoFrame`); the training env, on a world of many terrain tiles, passes False and
            its curriculum reads the tilt, height, contact and displacement conditions only.

    After ``reset``: ``state`` (`RobotState`), ``contacts`` (`Contacts`), ``params`` (the episode's
    `PhysicsParams`), ``success`` (`SuccessTracker`), ``metrics`` (`EpisodeMetrics` or None),
    ``settle_diverged`` (N,) and ``t`` (control steps since t = 0). After each ``step`` also ``signals``
    (the `StepSignals` the success test read), ``gravity`` (N, 3) (the projected gravity) and ``alive`` (N,)
    (not diverged, settle included).
    """

    def __init__(self, spec: RobotSpec, backend, terrain, num_envs: int, noise_rng=None,
                 ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
                 nominal_height: "float | np.ndarray | None" = None, track_metrics: bool = True,
                 surface_rules: bool = True):
        self.spec = spec
        self.terrain = terrain
        self.num_envs = num_envs
        self.backend = make_backend(backend, spec, num_envs, terrain=terrain) if isinstance(backend, str) else backend
        if self.backend.num_envs != num_envs:
            raise ValueError(f"backend has {self.backend.num_envs} simulations, the task {num_envs} episodes")
        self.noise_rng = noise_rng
        self.ground_height = ground_height or self._height_of_terrain
        self._terrain_ground = ground_height is None
        self._gravity_state = None  # the state ``gravity`` was computed from
        self.nominal_height = spec.nominal_height if nominal_height is None else nominal_height
        self.track_metrics = track_metrics
        self.surface_rules = surface_rules
        self.torso = torso_frame(spec) if surface_rules else None
        self.start_surface = None
        self.lower, self.upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
        self.default_pose = np.asarray(spec.default_pose)
        self.nominal = PhysicsParams.nominal(spec, num_envs)
        self.t = 0

    def close(self) -> None:
        """Free the simulator."""
        self.backend.close()

    def _height_of_terrain(self, xy: np.ndarray) -> np.ndarray:
        return height_at(self.terrain, xy)

    def settle(self, starts: FallenStarts, settle_steps: int = SETTLE_STEPS) -> None:
        """Place the starts (one per environment) and settle them for ``settle_steps`` control steps with the
        joints held softly (`settle_params` of ``self.params``)."""
        n = self.num_envs
        self.backend.set_params(settle_params(self.params))
        self.backend.reset(np.arange(n), RobotState.at_rest(starts.base_pos, starts.base_quat, starts.q))
        for _ in range(settle_steps):
            self.backend.step(starts.q)
        self.backend.set_params(self.params)
        self.state, self.contacts = self.backend.state(), self.backend.contacts()
        self._measure_start()

    def _measure_start(self) -> None:
        self.start_xy = self.state.base_pos[:, :2].copy()
        if self.surface_rules:
            self.start_surface = StartSurface(self.terrain, self.start_xy)

    def settled_upright(self) -> np.ndarray:
        """(N,) whether each settled start already lies within the success test's upright bound."""
        tracker = SuccessTracker(self.num_envs, self.spec.kind, self.nominal_height)
        return tracker.up_pose(self._signals(self.contacts))

    def reset(self, starts: FallenStarts, params: PhysicsParams | None = None,
              settle_steps: int = SETTLE_STEPS) -> dict[str, np.ndarray]:
        """Place and settle the starts (one per environment) under ``params`` (default: the spec's nominal
        physics), for ``settle_steps`` control steps, redrawing those already upright (`screen_starts`;
        ``self.starts`` then holds the starts the episodes run from); return the first observation."""
        n = self.num_envs
        self.params = self.nominal if params is None else params
        self.settle(starts, settle_steps)
        self.starts = screen_starts(self, starts, settle_steps)
        self.previous_action = np.tile(self.default_pose, (n, 1))
        self.success = SuccessTracker(n, self.spec.kind, self.nominal_height)
        self.metrics = EpisodeMetrics(n, self.spec.n_joints) if self.track_metrics else None
        self.settle_diverged = self.backend.diverged.copy()
        self.t = 0
        return self.observation()

    def restart(self, ids: np.ndarray, state: RobotState) -> None:
        """Before the first step: start episodes ``ids`` from ``state`` (len(ids) rows) instead of their
        settled fallen starts (displacement is measured from there)."""
        self.backend.reset(ids, state)
        self.state, self.contacts = self.backend.state(), self.backend.contacts()
        self._measure_start()
        self.settle_diverged[ids] = False

    def _signals(self, contacts) -> StepSignals:
        """What the success test reads in the current state (``gravity`` is refreshed here)."""
        s = self.state
        self.gravity, self._gravity_state = projected_gravity(s.base_quat), s
        xy = s.base_pos[:, :2]
        ground = self.ground_height(xy)
        surface_drop = None
        if self.start_surface is not None:  # the terrain's height under the base is ``ground`` unless given
            surface_drop = self.start_surface.drop(xy, ground if self._terrain_ground else None)
        return StepSignals(
            gravity_z=self.gravity[:, 2],
            height=s.base_pos[:, 2] - ground,
            body_contact=contacts.group_contact.any(axis=1),
            displacement=vector_norm(xy - self.start_xy),
            surface_drop=surface_drop,
            torso_gravity_z=self.torso.gravity_z(s.base_quat, s.q) if self.torso is not None else None,
        )

    def observation(self) -> dict[str, np.ndarray]:
        """The policy's proprioception (see `frbench.tasks.observations`)."""
        gravity = self.gravity if self._gravity_state is self.state else None  # computed for this state already
        return proprioception(self.state, self.previous_action, self.noise_rng, gravity)

    def advance(self, targets: np.ndarray) -> None:
        """Advance one control step towards ``targets`` (N, n_joints) [rad] (clipped to the joint limits):
        physics, then ``state``, ``contacts``, ``signals``, ``alive``, success and metrics."""
        targets = np.clip(targets, self.lower, self.upper)
        self.backend.step(targets)
        self.previous_action = targets
        self.state = self.backend.state()
        self.contacts = contacts = self.backend.contacts()
        diverged = self.backend.diverged | self.settle_diverged
        self.alive = ~diverged
        self.signals = signals = self._signals(contacts)
        self.success.update(signals, alive=self.alive)
        if self.metrics is not None:
            self.metrics.update(
                self.state.q, self.state.qd, self.state.tau, self.state.base_angvel[:, 0],
                contacts.body_force_max, signals.displacement, diverged,
            )
        self.t += 1

    def step(self, targets: np.ndarray) -> dict[str, np.ndarray]:
        """`advance` one control step towards ``targets`` (N, n_joints) [rad]; return the observation."""
        self.advance(targets)
        return self.observation()
