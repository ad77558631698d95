"""The fall-recovery episode engine: N episodes of one robot in one backend.

The engine never owns a simulator's details: it talks to the backend protocol
only, so it runs unchanged on MuJoCo, PyBullet and the split batch. It is the
one episode of frbench: the episode runner (`frbench.evaluation.episodes`) and
the core environment (`frbench.tasks.core_env`, under the gymnasium env and the
training env) drive it. Like a dm_control task it receives the physics it works
on: a built backend, which whoever built it (`open_backend`, the core
environment) closes; the task never builds or closes one. One episode:

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

Instead of 1, ``begin(starts)`` starts the episodes at recorded states
(`RecordedStarts`: velocities included, no settle; the key frames' rise stage,
`tools/keyframe_search.py`). Training adds, between 1 and 2,
``restart(ids, state)``: some episodes start from recorded states instead
(demo and rise starts, `frbench.training.start_sources`).
"""

from __future__ import annotations

from dataclasses import fields
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np

from frbench.arrays import copy_of, is_host, like, namespace, resident
from frbench.backends import make_backend
from frbench.backends.contact_layout import vector_norm
from frbench.backends.base import PhysicsParams, RobotState, SummarizedContacts
from frbench.robots.spec import RobotSpec
from frbench.tasks.initial_states import SETTLE_GAIN_SCALE, SETTLE_SECONDS, FallenStarts, RecordedStarts
from frbench.tasks.observations import projected_gravity, proprioception
from frbench.tasks.protocol import CONTROL_DT, EPISODE_SECONDS
from frbench.tasks.start_screening import screen_starts
from frbench.tasks.success import EpisodeMetrics, StartSurface, StepSignals, SuccessTracker, torso_frame
from frbench.terrains import height_at

EPISODE_STEPS = int(round(EPISODE_SECONDS / CONTROL_DT))
SETTLE_STEPS = int(round(SETTLE_SECONDS / CONTROL_DT))
#: ``metrics`` before the first episode (None is an episode without metrics).
_NO_EPISODE = object()
#: Kept steps (class docstring) at which the success test and the metrics catch up unasked: bounds the memory
#: of a long run that never reads them (any count gives the same numbers).
CATCH_UP_STEPS = 128


@contextmanager
def open_backend(name: str, spec: RobotSpec, num_envs: int, terrain=None, device: str | None = None) -> Iterator:
    """The backend ``name`` (`frbench.backends.make_backend`) with ``num_envs`` simulations of ``spec`` on
    ``terrain`` (a device simulator on ``device``, default ``cpu``, its arrays on the host), closed when the
    ``with`` block ends: for a caller that builds the physics a `RecoveryTask` works on (the task never closes
    it)."""
    backend = make_backend(name, spec, num_envs, terrain=terrain, device=device)
    try:
        yield backend
    finally:
        backend.close()


def settle_params(params: PhysicsParams) -> PhysicsParams:
    """The settle's physics: ``params``' gains scaled by `SETTLE_GAIN_SCALE` ("held softly"), its strength,
    friction and payload, no motor friction."""
    return PhysicsParams(params.kp * SETTLE_GAIN_SCALE, params.kd * SETTLE_GAIN_SCALE, params.motor_strength,
                         params.friction, params.payload)


class RecoveryTask:
    """Batched recovery episodes (see the module docstring).

    Args:
        spec: the robot (its joint limits clip the targets; its kind picks the success test).
        backend: a built backend (the `frbench.backends.base.Backend` protocol) with ``num_envs`` simulations
            (`open_backend`); its builder owns it and closes it, the task does not.
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
        env_specs: each episode's robot (N) when the backend simulates several (morphology variants), or None:
            ``spec`` in every one. Where their joint limits, standing poses or gains differ (files of different
            joint conventions or sizes), ``lower``, ``upper``, ``default_pose`` and the nominal gains are (N, J)
            rows, else the (J,) values of ``spec``.

    After ``reset`` (or ``begin``): ``state`` (`RobotState`), ``contacts`` (`Contacts`), ``params`` (the episode's
    `PhysicsParams`), ``success`` (`SuccessTracker`), ``metrics`` (`EpisodeMetrics` or None),
    ``settle_diverged`` (N,) and ``t`` (control steps since t = 0). After each ``step`` also ``signals``
    (the `StepSignals` the success test read), ``gravity`` (N, 3) (the projected gravity) and ``alive`` (N,)
    (not diverged, settle included).

    A step keeps its state, contacts and divergence; the success test and the metrics take the steps kept
    when ``success``, ``metrics`` or ``signals`` is read (or `CATCH_UP_STEPS` have gathered), all at once:
    the per-step signals of k steps are computed as (k, N) arrays, element for element what each step
    would have computed, and `SuccessTracker.update_steps` / `EpisodeMetrics.update_steps` give the numbers
    of k single steps. An evaluation reads them at the end; training reads ``signals`` after every step.
    """

    def __init__(self, spec: RobotSpec, backend, terrain, num_envs: int, noise_rng=None,
                 ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
                 nominal_height: "float | np.ndarray | None" = None, track_metrics: bool = True,
                 surface_rules: bool = True, env_specs=None):
        self.spec = spec
        self.terrain = terrain
        self.num_envs = num_envs
        if isinstance(backend, str):
            raise TypeError(f"RecoveryTask(backend={backend!r}): expected a built backend (open_backend), not a name")
        self.backend = backend
        if self.backend.num_envs != num_envs:
            raise ValueError(f"backend has {self.backend.num_envs} simulations, the task {num_envs} episodes")
        self.noise_rng = noise_rng
        self.ground_height = ground_height or self._height_of_terrain
        self._terrain_ground = ground_height is None
        self._gravity_state = None  # the state ``gravity`` was computed from
        self._kept: list[tuple] = []  # steps not yet fed to the success test and the metrics
        self._success = self._signals_now = self._diverged = None
        self._metrics = _NO_EPISODE
        self.nominal_height = spec.nominal_height if nominal_height is None else nominal_height
        self.track_metrics = track_metrics
        self.surface_rules = surface_rules
        self.torso = torso_frame(spec) if surface_rules else None
        self.start_surface = None
        rows = _joint_rows(spec, env_specs)
        self.lower, self.upper, self.default_pose = rows["joint_lower"], rows["joint_upper"], rows["default_pose"]
        self.nominal = PhysicsParams.nominal(spec, num_envs)
        if rows["kp"].ndim == 2 or rows["kd"].ndim == 2:
            self.nominal.kp, self.nominal.kd = _rows_of(rows["kp"], num_envs), _rows_of(rows["kd"], num_envs)
        self.t = 0

    # -- the physics outside an episode's steps: start banks, the assist force, the critic's ground truth -------
    def drive(self, targets: np.ndarray) -> RobotState:
        """Advance the physics one control step towards ``targets`` (N, n_joints) [rad] as given (not clipped, not
        an episode step: the success test and the metrics do not see it); returns the new ``state``. Used to
        record start banks (demo and rise starts) from the current starts."""
        self.backend.step(targets)
        self.state = self.backend.state()
        return self.state

    @property
    def physics_diverged(self) -> np.ndarray:
        """(N,) bool: the simulation has diverged now (since its last reset)."""
        return self.backend.diverged

    def set_base_force(self, force: np.ndarray) -> None:
        """A constant external force (N, 3) [N], world frame, on each base's centre of mass until changed."""
        self.backend.set_base_force(force)

    def whole_body_com(self) -> np.ndarray:
        """Whole-body centre of mass (N, 3) [m], world frame, payload included."""
        return self.backend.whole_body_com()

    def _height_of_terrain(self, xy: np.ndarray) -> np.ndarray:
        return height_at(self.terrain, xy)

    def _place(self, ids: np.ndarray, state: RobotState) -> None:
        """Put simulations ``ids`` in ``state`` (len(ids) rows), read ``state`` and ``contacts`` and measure the
        start (displacement and the start surface are measured from here)."""
        self.backend.reset(ids, state)
        self.state, self.contacts = self.backend.state(), self.backend.contacts()
        self._measure_start()

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
        self.start_xy = copy_of(self.state.base_pos[:, :2])
        if self.surface_rules:
            self.start_surface = StartSurface(self.terrain, self.start_xy)

    def settled_upright(self) -> np.ndarray:
        """(N,) whether each settled start already lies within the success test's upright bound."""
        tracker = SuccessTracker(self.num_envs, self.spec.kind, self.nominal_height)
        return tracker.up_pose(self._signals(self.contacts))

    # ------------------------------------------------------------------ the success test and the metrics
    @property
    def success(self) -> SuccessTracker:
        """The episodes' `SuccessTracker`, up to the last step."""
        self._catch_up()
        if self._success is None:
            raise AttributeError("success: no episode started yet")
        return self._success

    @success.setter
    def success(self, tracker: SuccessTracker) -> None:
        self._catch_up()
        self._success = tracker

    @property
    def metrics(self) -> EpisodeMetrics | None:
        """The episodes' `EpisodeMetrics` up to the last step (None without ``track_metrics``)."""
        self._catch_up()
        if self._metrics is _NO_EPISODE:
            raise AttributeError("metrics: no episode started yet")
        return self._metrics

    @metrics.setter
    def metrics(self, metrics: EpisodeMetrics | None) -> None:
        self._catch_up()
        self._metrics = metrics

    @property
    def signals(self) -> StepSignals:
        """The `StepSignals` of the last step."""
        self._catch_up()
        return self._signals_now

    @property
    def alive(self) -> np.ndarray:
        """(N,) not diverged at the last step, settle included."""
        if self._diverged is None:
            raise AttributeError("alive: no step taken yet")
        return ~self._diverged

    def _catch_up(self) -> None:
        """Feed the kept steps to the success test and the metrics: their signals as (k, N) arrays, then one
        `update_steps` each."""
        if not self._kept:
            return
        kept, self._kept = self._kept, []
        states = [step[0] for step in kept]
        base_pos, base_quat = _rows(states, "base_pos"), _rows(states, "base_quat")
        q = _rows(states, "q")
        metrics = self._metrics is not None and self._metrics is not _NO_EPISODE
        group_contact, body_force_max = _contact_rows([step[1] for step in kept], metrics)
        xp = namespace(base_pos)
        diverged = xp.stack([step[2] for step in kept])
        gravity = xp.stack([step[3] for step in kept])
        signals = self._signals_of(base_pos, base_quat, q, gravity, group_contact)
        self._signals_now = StepSignals(*(None if a is None else a[-1] for a in _fields(signals)))
        self._success.update_steps(signals, alive=~diverged)
        if metrics:
            self._metrics.update_steps(q, _rows(states, "qd"), _rows(states, "tau"), _rows(states, "base_angvel")[..., 0],
                                       body_force_max, signals.displacement, diverged)

    def reset(self, starts: FallenStarts, params: PhysicsParams | None = None,
              settle_steps: int = SETTLE_STEPS) -> dict[str, np.ndarray]:
        """Place and settle the starts (one per environment) under ``params`` (default: the spec's nominal
        physics), for ``settle_steps`` control steps, redrawing those already upright (`screen_starts`;
        ``self.starts`` then holds the starts the episodes run from); return the first observation."""
        n = self.num_envs
        self.params = self.nominal if params is None else params
        self.settle(starts, settle_steps)
        self.starts = screen_starts(self, starts, settle_steps)
        return self._start_episodes(_rows_of(self.default_pose, n), copy_of(self.backend.diverged))

    def begin(self, starts: RecordedStarts, params: PhysicsParams | None = None) -> dict[str, np.ndarray]:
        """Begin the episodes at recorded states (`RecordedStarts`, one per environment) under ``params``
        (default: the spec's nominal physics), without a settle: t = 0 is the state as recorded, velocities
        included (displacement and the start surface are measured from it), the previous action is
        ``starts.previous_action`` or, if None, the placed state's joint angles; ``self.starts`` holds ``starts``.
        Returns the first observation."""
        n = self.num_envs
        if len(starts.kinds) != n:
            raise ValueError(f"begin: {len(starts.kinds)} recorded states for {n} episodes")
        self.params = self.nominal if params is None else params
        self.backend.set_params(self.params)
        self._place(np.arange(n), starts.state)
        self.starts = starts
        previous = (copy_of(self.state.q) if starts.previous_action is None
                    else np.array(starts.previous_action, dtype=float))
        return self._start_episodes(previous, namespace(self.backend.diverged).zeros_like(self.backend.diverged))

    def _start_episodes(self, previous_action: np.ndarray, settle_diverged: np.ndarray) -> dict[str, np.ndarray]:
        """t = 0 from the placed starts: ``previous_action`` (N, n_joints) [rad], a fresh success test and
        metrics, ``settle_diverged`` (N,); returns the first observation."""
        n = self.num_envs
        self.previous_action = previous_action
        self._kept, self._signals_now, self._diverged = [], None, None
        ref = self.state.base_pos
        self._success = (SuccessTracker(n, self.spec.kind, self.nominal_height) if is_host(ref) else
                         SuccessTracker(n, self.spec.kind, resident(self.nominal_height, ref), like=ref))
        self._metrics = EpisodeMetrics(n, self.spec.n_joints) if self.track_metrics else None
        self.settle_diverged = settle_diverged
        self.t = 0
        return self.observation()

    def restart(self, ids: np.ndarray, state: RobotState) -> None:
        """Before the first step: start episodes ``ids`` from ``state`` (len(ids) rows) instead of their
        settled fallen starts (displacement is measured from there)."""
        self._catch_up()
        self._place(ids, state)
        self.settle_diverged[ids] = False

    def _signals(self, contacts) -> StepSignals:
        """What the success test reads in the current state (``gravity`` is refreshed here)."""
        s = self.state
        self.gravity, self._gravity_state = projected_gravity(s.base_quat), s
        signals = self._signals_of(s.base_pos[None], s.base_quat[None], s.q[None], self.gravity[None],
                                   contacts.group_contact[None])
        return StepSignals(*(None if a is None else a[0] for a in _fields(signals)))

    def _signals_of(self, base_pos, base_quat, q, gravity, group_contact) -> StepSignals:
        """The `StepSignals` (k, N) of k steps: base_pos (k, N, 3) [m], base_quat (k, N, 4), q (k, N, J) [rad],
        gravity (k, N, 3) (projected), group_contact (k, N, G)."""
        xy = base_pos[..., :2]
        if self._terrain_ground:
            ground = height_at(self.terrain, xy)
        else:  # a caller's rule for N points at a time
            ground = namespace(xy).stack([self.ground_height(step) for step in xy])
        surface_drop = None
        if self.start_surface is not None:  # the terrain's height under the base is ``ground`` unless given
            surface_drop = self.start_surface.drop(xy, ground if self._terrain_ground else None)
        torso = None
        if self.torso is not None:
            torso = self.torso.gravity_z(base_quat.reshape(-1, 4), q.reshape(-1, q.shape[-1])).reshape(xy.shape[:2])
        return StepSignals(
            gravity_z=gravity[..., 2],
            height=base_pos[..., 2] - ground,
            body_contact=namespace(group_contact).any(group_contact, axis=-1),
            displacement=vector_norm(xy - self.start_xy),
            surface_drop=surface_drop,
            torso_gravity_z=torso,
        )

    def observation(self) -> dict[str, np.ndarray]:
        """The policy's proprioception (see `frbench.tasks.observations`)."""
        gravity = self.gravity if self._gravity_state is self.state else None  # computed for this state already
        return proprioception(self.state, self.previous_action, self.noise_rng, gravity)

    def advance(self, targets: np.ndarray) -> None:
        """Advance one control step towards ``targets`` (N, n_joints) [rad] (clipped to the joint limits):
        physics, then ``state``, ``contacts``, ``gravity`` and ``alive``; the step is kept for the success test
        and the metrics (class docstring)."""
        ref = self.state.q
        if not is_host(ref):  # the backend's namespace and device (a numpy controller's targets go there)
            targets = like(targets, ref)
        xp = namespace(targets)  # np.clip's result, without its checks
        targets = xp.minimum(xp.maximum(targets, resident(self.lower, targets)), resident(self.upper, targets))
        self.backend.step(targets)
        self.previous_action = targets
        self.state = state = self.backend.state()
        self.contacts = self.backend.contacts()
        self._diverged = self.backend.diverged | self.settle_diverged
        self.gravity, self._gravity_state = projected_gravity(state.base_quat), state
        self._kept.append((state, self.contacts, self._diverged, self.gravity))
        if len(self._kept) >= CATCH_UP_STEPS:
            self._catch_up()
        self.t += 1

    def step(self, targets: np.ndarray) -> dict[str, np.ndarray]:
        """`advance` one control step towards ``targets`` (N, n_joints) [rad]; return the observation."""
        self.advance(targets)
        return self.observation()


def _joint_rows(spec: RobotSpec, env_specs) -> dict[str, np.ndarray]:
    """``joint_lower``, ``joint_upper``, ``default_pose``, ``kp`` and ``kd`` of ``spec`` (J,), or of each of
    ``env_specs`` (N, J) where one of them differs from ``spec``'s (a field at a time)."""
    out = {}
    for name in ("joint_lower", "joint_upper", "default_pose", "kp", "kd"):
        own = np.asarray(getattr(spec, name), dtype=float)
        if env_specs is not None and any(getattr(other, name) != getattr(spec, name) for other in env_specs):
            own = np.array([getattr(other, name) for other in env_specs], dtype=float)
        out[name] = own
    return out


def _rows_of(values: np.ndarray, n: int) -> np.ndarray:
    """(n, J): ``values`` (J,) repeated, or the (n, J) rows themselves, as a new array."""
    return np.tile(values, (n, 1)) if values.ndim == 1 else np.array(values)


def _rows(states: list[RobotState], name: str):
    """(k, N, ·): field ``name`` of k states, step after step (a view for one state); numpy or torch."""
    first = getattr(states[0], name)
    return first[None] if len(states) == 1 else namespace(first).stack([getattr(s, name) for s in states])


def _contact_rows(readings: list, force: bool = True) -> tuple:
    """(group contact (k, N, G), largest non-foot force (k, N), or None without ``force``) of k steps' `Contacts`;
    summarised together from the stacked link forces when each reading summarises lazily by one rule
    (`SummarizedContacts`)."""
    first = readings[0]
    xp = namespace(first.link_force)
    if len(readings) == 1:
        return first.group_contact[None], (first.body_force_max[None] if force else None)
    if all(isinstance(c, SummarizedContacts) and c._layout is first._layout for c in readings):
        forces = xp.stack([c.link_force for c in readings])
        k, n = forces.shape[:2]
        together = SummarizedContacts(first._layout, xp.reshape(forces, (k * n, *forces.shape[2:])))
        return (xp.reshape(together.group_contact, (k, n, -1)),
                xp.reshape(together.body_force_max, (k, n)) if force else None)
    return (xp.stack([c.group_contact for c in readings]),
            xp.stack([c.body_force_max for c in readings]) if force else None)


def _fields(signals: StepSignals) -> list:
    return [getattr(signals, f.name) for f in fields(StepSignals)]
