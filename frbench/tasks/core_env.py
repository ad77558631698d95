"""The core environment: N recovery episodes that own their physics, under every learning interface.

`CoreEnv` builds the simulator (`frbench.backends.make_backend`, N simulations, morphology variants allowed),
runs the episode engine over it (`frbench.tasks.recovery.RecoveryTask`, which never builds or closes one) and
frees the simulator in `close`. The rsl-rl `VecEnv` (`frbench.training.env`) and the Gymnasium envs
(`frbench.gym`, single and vector) are shells over it: they convert types, devices and spaces. Batched over N
robot instances it covers:

* reset: `new_episodes` asks the start distribution ``starts`` for new episodes of every environment, drawn
  from the env's generator ``rng`` (`seed` replaces it): `ProtocolStarts` (the Gymnasium envs') or training's
  `frbench.training.start_sources.CurriculumStarts` (curriculum tiles, demo and rise starts). They work
  through the env's API: `draw_fallen` draws the protocol's fallen starts (one terrain, or one tile per
  environment with its world offset and robot), `reset` places, settles and screens them (the engine) with the
  assist force cleared for the settle and set after it, `begin` starts the episode's actions, `drive` runs
  physics only (to record a bank of states) and `restart` puts episodes on recorded states; the assist force
  (`frbench.training.assist`) pushes through `set_base_force`;
* step: one decision `step(action)`: the action held (``hold``) for its control steps, each one
  ``transform.targets(state, a_t)`` (an action transform, `frbench.tasks.actions`) → the engine's ``advance``
  (clip to the joint limits, physics, signals, success test, metrics) → ``reward(task, a_t, a_{t−1}, a_{t−2},
  q̇_prev)`` (the one reward, `frbench.training.step_reward.StepReward`), rewards and terms summed over the held
  steps;
* observations: `observation` (the engine's proprioception dict), `flat_observation` (its flat o_t) and
  `policy_observation` (o_t with the previous action in policy units, the trainer's), with ``history`` > 0 also
  ``history`` (N, H, ·) and ``long_history`` (N, T, ·): the last H (T) policy observations, oldest first,
  refilled with the first one at new episodes;
* termination: episodes last ``episode_steps`` control steps and end together (`done`);
* what an episode tells: `success_info` (after each step) and `episode_record` (the record ``frbench evaluate``
  writes).

The action transform, the held action (`frbench.training.action_hold.HeldAction`), the reward and the assist
force are objects passed in: the ways actions become targets compose outside the env, and this module imports
nothing above `tasks/`. Shapes: N environments, J joints; actions (N, J) in policy units.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from frbench.arrays import copy_of, is_host, like, namespace
from frbench.backends import make_backend, simulator_parts
from frbench.backends.base import PhysicsParams, RobotState
from frbench.robots.spec import RobotSpec
from frbench.tasks.initial_states import FallenStarts, RecordedStarts, draw_start
from frbench.tasks.observations import flatten
from frbench.tasks.recovery import EPISODE_STEPS, SETTLE_STEPS, RecoveryTask


class CoreEnv:
    """N recovery episodes of ``spec`` (or of its ``variants``) in simulator ``backend`` (module docstring).

    Args:
        spec: the robot (the batch's first robot when ``variants`` are given).
        backend: the simulator's name (``"mujoco"``, ``"pybullet"``, ``"mujoco+pybullet"``); built here, closed by
            `close`.
        terrain: the `Terrain` the simulator is built on (a world of tiles in training).
        num_envs: N.
        transform: the action transform (``reset(spec, N)``, ``targets(state, action) -> (N, J) [rad]``).
        hold: the held action (`HeldAction`: ``begin``, ``decide``, ``current``, ``held``).
        reward: ``reward(task, a_t, a_{t−1}, a_{t−2}, q̇_prev) -> (reward (N,), terms, alive (N,))``, or None
            (no reward: zeros).
        assist: an assist force (``clear(env)``, ``apply(env, env_steps)``) or None.
        starts: the start distribution (``new_episodes(env, rng)``); default `ProtocolStarts` on ``terrain``.
        rng: the seeded generator every start is drawn from (`seed` replaces it).
        history, long_history: policy observations kept (H, T; None / 0: none kept).
        episode_steps: control steps per episode.
        privileged: ``privileged(env, o_t) -> {group: (N, ·) array}``, the groups beyond proprioception that
            `observation_groups` adds (training's `frbench.training.observation_groups.PrivilegedGroups`), or None.
        variants, noise_rng, ground_height, nominal_height, track_metrics, surface_rules: as in `make_backend`
            and `RecoveryTask`.
        device: where the simulator runs and hands out its arrays (`frbench.backends.devices.parse_device`'s
            value; training): numpy on the host for the CPU simulators, torch on that device for MuJoCo Warp, and
            everything the env computes follows them (`frbench.arrays`). None: host numpy arrays whatever the
            simulator (the Gymnasium envs, which hand numpy to their users).
        world: the simulator's compiled world (`frbench.backends.mujoco_warp_backend.CompiledWorld`, a bundle's),
            or None: compiled here from ``spec``, ``terrain`` and ``variants``.
        joint_frame: the `frbench.robots.joint_frame.JointFrame` the learner reads and writes joints in (frbench's
            trainers: the robots' canonical frame), or None: the robot's own convention (the Gymnasium envs).
            The observation's joint terms go through it into o_t, and the transform's targets, which are then
            canonical (``transform`` built on `policy_default_pose`), come back through it.
    """

    def __init__(self, spec: RobotSpec, backend: str, terrain, num_envs: int, *, transform, hold,
                 rng: np.random.Generator, reward: Callable | None = None, assist=None, starts=None,
                 history: int | None = None, long_history: int = 0, episode_steps: int = EPISODE_STEPS,
                 variants=None, noise_rng=None, ground_height: Callable | None = None, nominal_height=None,
                 track_metrics: bool = True, surface_rules: bool = True, privileged: Callable | None = None,
                 joint_frame=None, device: str | None = None, world=None):
        self.spec, self.terrain, self.num_envs = spec, terrain, int(num_envs)
        self.default_pose = np.asarray(spec.default_pose)
        self.frame = joint_frame
        #: q̊ [rad] (J,) in the learner's joint frame: what o_t's joint terms are relative to
        self.policy_default_pose = (self.default_pose if joint_frame is None
                                    else np.asarray(joint_frame.canonical_spec(spec).default_pose))
        self.transform, self.actions, self.reward, self.assist = transform, hold, reward, assist
        self.starts = ProtocolStarts(terrain) if starts is None else starts
        self.rng, self.privileged = rng, privileged
        self.history_length, self.long_history_length = history, long_history
        self.history = self.long_history = None
        self.episode_steps = int(episode_steps)
        #: Env steps taken so far (N per control step): the schedules of start sources and the assist read it.
        self.env_steps = 0
        self.backend = make_backend(backend, spec, self.num_envs, terrain=terrain, variants=variants, device=device,
                                    device_arrays=device is not None, world=world)
        #: whether the backend's arrays (and so everything the env computes) are torch tensors on a device
        self.device_arrays = bool(getattr(self.backend, "device_arrays", False))
        try:
            env_specs = None if variants is None else [variants[0][k] for k in np.asarray(variants[1])]
            self.task = RecoveryTask(spec, self.backend, terrain, self.num_envs, noise_rng=noise_rng,
                                     ground_height=ground_height, nominal_height=nominal_height,
                                     track_metrics=track_metrics, surface_rules=surface_rules, env_specs=env_specs)
        except Exception:
            self.backend.close()
            raise

    def close(self) -> None:
        """Free the simulator (built here; the task never closes it)."""
        self.backend.close()

    # -- the engine's state, for the shells ---------------------------------------------------------------
    @property
    def state(self) -> RobotState:
        return self.task.state

    @property
    def contacts(self):
        return self.task.contacts

    @property
    def params(self) -> PhysicsParams:
        """The current episode's `PhysicsParams`."""
        return self.task.params

    @property
    def t(self) -> int:
        """Control steps taken in the current episode."""
        return self.task.t

    @property
    def success(self):
        return self.task.success

    @property
    def signals(self):
        return self.task.signals

    @property
    def done(self) -> bool:
        """Whether the episodes (all together) have run their ``episode_steps``."""
        return self.task.t >= self.episode_steps

    @property
    def physics_diverged(self) -> np.ndarray:
        """(N,) bool: the simulation has diverged now."""
        return self.task.physics_diverged

    def whole_body_com(self) -> np.ndarray:
        """Whole-body centre of mass (N, 3) [m], world frame, payload included."""
        return self.task.whole_body_com()

    def simulator_parts(self) -> list[tuple[str, slice]]:
        """(simulator name, rows) of each simulator the batch runs (`frbench.backends.simulator_parts`)."""
        return simulator_parts(self.backend)

    # -- the physics outside an episode's steps: start sources and the assist force ---------------------------
    def drive(self, targets: np.ndarray) -> RobotState:
        """One control step of physics towards ``targets`` (N, J) [rad], not an episode step (start banks)."""
        return self.task.drive(targets)

    def restart(self, ids: np.ndarray, state: RobotState) -> None:
        """Before the first step: episodes ``ids`` start from ``state`` (len(ids) rows) instead."""
        self.task.restart(ids, state)

    def set_base_force(self, force: np.ndarray) -> None:
        """A constant external force (N, 3) [N], world frame, on each base's centre of mass until changed."""
        self.task.set_base_force(force)

    # -- episodes -----------------------------------------------------------------------------------------
    def seed(self, seed: int) -> None:
        """Draw the following starts from a new generator seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)

    def new_episodes(self) -> None:
        """New episodes for every environment from the start distribution (``starts``, drawn from ``rng``); the
        observation history refilled with the first policy observation."""
        self.starts.new_episodes(self, self.rng)
        if self.history_length is not None:
            o_t = self.policy_observation()
            self.history = _repeated(o_t, self.history_length)
            if self.long_history_length:
                self.long_history = _repeated(o_t, self.long_history_length)

    def draw_fallen(self, rng: np.random.Generator, terrains, offsets: Sequence | None = None,
                    specs: Sequence[RobotSpec] | None = None) -> FallenStarts:
        """The protocol's fallen starts, one per environment, drawn from ``rng`` in environment order: on
        ``terrains`` (one `Terrain`, or one per environment), moved by ``offsets`` (N × (dx, dy) [m], a tile's
        place in the world; None: not moved), of robots ``specs`` (one per environment; default ``spec``)."""
        n = self.num_envs
        terrains = terrains if isinstance(terrains, (list, tuple)) else [terrains] * n
        pos, quat, q = np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, self.spec.n_joints))
        kinds = []
        for i in range(n):
            p, o, j, kind = draw_start(self.spec if specs is None else specs[i], terrains[i], rng)
            if offsets is not None:
                dx, dy = offsets[i]
                p = p + (dx, dy, 0.0)
            pos[i], quat[i], q[i] = p, o, j
            kinds.append(kind)
        return FallenStarts(pos, quat, q, kinds)

    def reset(self, starts: FallenStarts, params: PhysicsParams | None = None,
              settle_steps: int = SETTLE_STEPS) -> None:
        """Place, settle and screen ``starts`` under ``params`` (default nominal) for ``settle_steps`` control steps
        (`RecoveryTask.reset`); the assist force is off during the settle and set for the episode after it."""
        if self.assist is not None:
            self.assist.clear(self)
        self.task.reset(starts, params, settle_steps)
        if self.assist is not None:
            self.assist.apply(self, self.env_steps)

    def begin_recorded(self, starts: RecordedStarts, params: PhysicsParams | None = None) -> None:
        """Begin the episodes at recorded states (the engine's `RecoveryTask.begin`: no settle, velocities
        included) under ``params``; the assist force set for the episode."""
        self.task.begin(starts, params)
        if self.assist is not None:
            self.assist.apply(self, self.env_steps)

    def begin(self, action: np.ndarray | None = None) -> None:
        """Start the episodes' actions: a_{t−1} = a_{t−2} = ``action`` (N, J) (default zeros; in the namespace of the
        backend's arrays), the transform reset."""
        action = np.zeros((self.num_envs, self.spec.n_joints)) if action is None else action
        q = self.task.state.q
        self.actions.begin(action if is_host(q) else like(action, q))
        self.transform.reset(self.spec, self.num_envs)

    # -- stepping -----------------------------------------------------------------------------------------
    def step(self, action: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """One decision ``action`` (N, J), held for its control steps (fewer when the episode ends first):
        (reward (N,) and weighted terms name → (N,), both summed over the held steps, alive (N,) bool), in the
        namespace of the backend's arrays (``action`` too)."""
        reward, term_sums, alive = None, {}, None
        for action_prev, action_prev2 in self.actions.decide(action, self.episode_steps - self.task.t):
            step_reward, terms, alive = self._control_step(action_prev, action_prev2)
            reward = step_reward if reward is None else reward + step_reward
            term_sums = {k: term_sums.get(k, 0.0) + v for k, v in terms.items()}
        if self.history_length is not None:
            o_t = self.policy_observation()[:, None, :]
            xp = namespace(o_t)
            self.history = xp.concat([self.history[:, 1:], o_t], axis=1)
            if self.long_history is not None:
                self.long_history = xp.concat([self.long_history[:, 1:], o_t], axis=1)
        return reward, term_sums, alive

    def _control_step(self, action_prev: np.ndarray, action_prev2: np.ndarray):
        """One control step of the current action: targets, the engine's step, the reward; returns (reward (N,),
        terms, alive (N,) bool)."""
        task, action = self.task, self.actions.current
        targets = self.transform.targets(task.state, action)
        if self.frame is not None:
            targets = self.frame.targets(targets)
        qd_prev = task.state.qd
        task.advance(targets)
        self.env_steps += self.num_envs
        if self.reward is None:
            return namespace(task.alive).zeros(task.alive.shape, dtype=task.state.q.dtype), {}, task.alive
        return self.reward(task, action, action_prev, action_prev2, qd_prev)

    # -- observations and what an episode tells ---------------------------------------------------------------
    def observation(self) -> dict[str, np.ndarray]:
        """The engine's proprioception (`frbench.tasks.observations.proprioception`)."""
        return self.task.observation()

    def flat_observation(self) -> np.ndarray:
        """o_t (N, 6 + 3J), the previous action as target − q̊ [rad] (`frbench.tasks.observations.flatten`), joint
        terms in the learner's joint frame."""
        obs = self.task.observation()
        return flatten(obs if self.frame is None else self.frame.observation(obs), self.policy_default_pose)

    def policy_observation(self) -> np.ndarray:
        """o_t (N, 6 + 3J) with the previous action in policy units (the trainer's o_t)."""
        o_t = self.flat_observation()
        o_t[:, -self.spec.n_joints:] = self.actions.current
        return o_t

    def observation_groups(self) -> dict[str, np.ndarray]:
        """A learner's observation groups, each (N, ·): ``policy`` (`policy_observation`), ``history`` (N, H·D),
        the groups of ``privileged``, ``long_history`` (N, T·D; with ``long_history`` > 0). NaN and infinities
        become 0, and a diverged simulation's rows are all 0."""
        n = self.num_envs
        o_t = self.policy_observation()
        groups = {"policy": o_t, "history": self.history.reshape(n, -1)}
        if self.privileged is not None:
            groups.update(self.privileged(self, o_t))
        if self.long_history is not None:
            groups["long_history"] = self.long_history.reshape(n, -1)
        diverged = self.physics_diverged
        if is_host(diverged):
            alive = ~diverged if diverged.any() else None
        else:
            alive = ~diverged  # on a device: no host synchronisation to find that all are alive
        return {key: zero_invalid(value, alive) for key, value in groups.items()}

    def success_info(self) -> dict[str, np.ndarray]:
        """After a step, each (N,): ``success`` (recovered so far), ``upright`` (the success test's pose condition
        now; a humanoid's height condition), ``time_to_recover`` [s] (NaN until recovered), ``diverged``."""
        tracker, signals = self.task.success, self.task.signals
        upright = signals.height > tracker.up_height if self.spec.kind == "humanoid" else tracker.upright(signals)
        return {"success": tracker.success.copy(), "upright": np.asarray(upright, dtype=bool),
                "time_to_recover": tracker.time_to_recover.copy(),
                "diverged": self.task.physics_diverged | self.task.settle_diverged}

    def episode_record(self) -> dict[str, np.ndarray]:
        """The per-episode record of ``frbench evaluate`` so far, each (N,) (time_to_recover NaN if none)."""
        success, metrics = self.task.success, self.task.metrics
        diverged = metrics.diverged | self.task.settle_diverged
        return {"success": success.success & ~diverged, "time_to_recover": success.time_to_recover.copy(),
                "final_displacement": metrics.final_displacement.copy(),
                "max_displacement": metrics.max_displacement.copy(), "energy": metrics.energy.copy(),
                "smoothness": np.asarray(metrics.smoothness).copy(),
                "peak_contact_force": metrics.peak_contact_force.copy(), "rolled_over": metrics.rolled_over.copy(),
                "diverged": diverged.copy()}


class ProtocolStarts:
    """The protocol's fallen starts on one ``terrain`` for every episode (`frbench.tasks.initial_states.draw_start`,
    settled and screened), the actions begun at zero: the Gymnasium envs' start distribution."""

    def __init__(self, terrain):
        self.terrain = terrain

    def new_episodes(self, env: CoreEnv, rng: np.random.Generator) -> None:
        """New episodes for every environment of ``env``, drawn from ``rng``."""
        env.reset(env.draw_fallen(rng, self.terrain))
        env.begin()


def zero_invalid(value, alive):
    """``value`` (N, k) with NaN and infinities as zeros, and the rows not ``alive`` (N,) zero (None: all are
    alive); numpy or torch. A float64 numpy ``value`` itself when nothing changes."""
    if is_host(value):
        if alive is None and value.dtype == np.float64 and np.isfinite(value).all():
            return value
        cleaned = np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0)
        return cleaned if alive is None else np.where(alive[:, None], cleaned, 0.0)
    xp = namespace(value)  # torch on a device: the same rule without asking the host whether anything changes
    cleaned = xp.where(xp.isfinite(value), value, 0.0)
    return cleaned if alive is None else xp.where(alive[:, None], cleaned, 0.0)


def _repeated(o_t, length: int):
    """(N, ``length``, D): the observation ``o_t`` (N, D) repeated (a history refilled), numpy or torch."""
    xp = namespace(o_t)
    return copy_of(xp.broadcast_to(o_t[:, None, :], (o_t.shape[0], length, o_t.shape[1])))
