"""Gymnasium environments for researchers who bring their own training loop.

``import frbench.gym`` registers (this module's only purpose; ``import frbench``
registers nothing):

* ``gymnasium.make("frbench/FallRecovery-v1", robot="go2", backend="mujoco",
  terrain="flat", level=1)`` — one environment;
* ``gymnasium.make_vec("frbench/FallRecovery-v1", num_envs=64,
  vectorization_mode="vector_entry_point", ...)`` — a batched
  `FallRecoveryVectorEnv` on one backend batch.

The episodes are the benchmark's (`frbench.tasks.recovery.RecoveryTask`: the
same fallen starts, settle, physics, success test and metrics as ``frbench
evaluate``), 5 s = 250 control steps at 50 Hz.

Action a (n_joints,) in ``Box(-1, 1)``: joint targets
q* = q̊ + ``action_scale`` · a [rad] (q̊ the robot's default pose, canonical
joint order; then clipped to the joint limits), the mapping and scale (1.0) of
the shipped policies, whose ONNX sidecar states the same. Actions outside the
box are clipped to it.

Observation (6 + 3·n_joints,) float32, the paper's o_t: body angular velocity
[rad/s], projected gravity, q − q̊ [rad], q̇ [rad/s], previous target − q̊ [rad];
bounded (`observation_bounds`: ±`MAX_ANGULAR_VELOCITY`, ±1, the joint range
around q̊, ±`MAX_JOINT_VELOCITY`) and clipped to those bounds.

Reward: frbench's training reward, computed by the trainer's own
`frbench.training.step_reward.StepReward` (the same inputs, the velocity-limit
threshold read from the URDF, the same head point) with the trainer's tables
(``reward="training"``: `training_reward_config` for quadrupeds,
`humanoid_reward_config` for humanoids; ``"paper"``: the paper's table; or any
`RewardConfig`); every term's weighted value is in ``info["reward_terms"]``.

``info`` also holds the success test's state after each step: ``success``
(recovered so far), ``upright`` (the success test's pose condition now),
``time_to_recover`` [s] (None, or NaN in the vector env, until recovered), ``diverged``; and at the
episode's end ``episode_metrics``, the record ``frbench evaluate`` writes
(success, time to recover, displacements, energy, smoothness, peak contact
force, rolled over, diverged).

Episodes end by truncation, all environments together; the vector environment
resets them in the same step (``AutoresetMode.SAME_STEP``), the last
observation in ``infos["final_obs"]``. ``render_mode="rgb_array"`` draws with
`frbench.render.SceneRenderer` (visual meshes, following camera, caption), so
``gymnasium.wrappers.RecordVideo`` records episodes; headless on Linux it sets
``MUJOCO_GL=egl`` before mujoco is first imported.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from frbench.terrains import height_at
from frbench.tasks.actions import ACTION_SCALE, DirectTargets
from frbench.tasks.observations import observation_bounds
from frbench.training.step_reward import HeadPoints, StepReward

ENV_ID = "frbench/FallRecovery-v1"
#: Frames per second of ``render`` videos (every second control step of 50 Hz).
RENDER_FPS = 25
#: Reward presets: name → function of the robot kind giving a `RewardConfig`.
REWARD_PRESETS = ("training", "paper")


def reward_config(reward, kind: str):
    """The `RewardConfig` of preset ``reward`` (``"training"``: the trainer's table for robots of ``kind``;
    ``"paper"``: the paper's) or ``reward`` itself if it is one."""
    from frbench.training.reward_tables import reward_table
    from frbench.training.rewards import RewardConfig

    if isinstance(reward, RewardConfig):
        return reward
    if reward == "training":
        return reward_table(kind)
    if reward == "paper":
        return RewardConfig()
    raise ValueError(f"reward={reward!r}: expected one of {', '.join(REWARD_PRESETS)} or a RewardConfig")


class FallRecoveryVectorEnv(VectorEnv):
    """``num_envs`` recovery episodes of one robot on one terrain, batched in one backend (module docstring)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": ["rgb_array"], "render_fps": RENDER_FPS}

    def __init__(self, num_envs: int = 1, robot: str = "go2", backend: str = "mujoco", terrain: str = "flat",
                 level: int = 1, terrain_seed: int = 0, reward="training", action_scale: float = ACTION_SCALE,
                 render_mode: str | None = None, render_size: tuple[int, int] = (640, 480),
                 max_episode_steps: int | None = None):
        from frbench.robots import get_robot
        from frbench.tasks.recovery import EPISODE_STEPS
        from frbench.terrains import make_terrain

        if max_episode_steps not in (None, EPISODE_STEPS):
            raise ValueError(f"max_episode_steps={max_episode_steps}: the protocol's episodes last {EPISODE_STEPS} steps")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        if render_mode is not None:
            from frbench.render import use_headless_gl

            use_headless_gl()  # before the simulator imports mujoco
        from frbench.tasks.recovery import RecoveryTask

        self.spec_robot = spec = get_robot(robot)
        self.num_envs, self.backend_name, self.render_mode, self.render_size = num_envs, backend, render_mode, render_size
        self.action_scale = float(action_scale)
        self.terrain = make_terrain(terrain, level, terrain_seed)
        self.terrain_label = f"{terrain} level {level}"
        self.task = RecoveryTask(spec, backend, self.terrain, num_envs)
        head = HeadPoints([spec], np.zeros(num_envs, dtype=int)) if spec.kind == "humanoid" else None
        self.step_reward = StepReward(reward_config(reward, spec.kind), spec, spec.nominal_height,
                                      lambda xy: height_at(self.terrain, xy), head)
        self.episode_steps = EPISODE_STEPS
        n = spec.n_joints
        self.default_pose = np.asarray(spec.default_pose)
        self.action_transform = DirectTargets(self.default_pose, self.action_scale)
        low, high = observation_bounds(spec)
        self.single_observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rng = np.random.default_rng()
        self._renderer = None

    # -- observations, actions, rewards ---------------------------------------------------------------------

    def _flat(self, obs: dict) -> np.ndarray:
        from frbench.tasks.observations import flatten

        flat = np.nan_to_num(flatten(obs, self.default_pose), nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(flat, self.single_observation_space.low, self.single_observation_space.high).astype(np.float32)

    def targets(self, actions) -> np.ndarray:
        """Joint targets q* (N, n_joints) [rad] of normalised actions (N, n_joints) (clipped to [−1, 1]): the
        training env's action transform (`frbench.tasks.actions.DirectTargets`)."""
        actions = np.clip(np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1), -1.0, 1.0)
        return self.action_transform.targets(getattr(self.task, "state", None), actions)  # no state before a reset

    def _reward(self, actions: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The step's reward (N,) and weighted terms (`StepReward`, the trainer's), both 0 where diverged."""
        total, terms, alive = self.step_reward(self.task, actions, self._actions[0], self._actions[1], self._qd_prev)
        return total, {k: np.where(alive, np.nan_to_num(v), 0.0) for k, v in terms.items()}

    # -- episodes -------------------------------------------------------------------------------------------

    def _new_episodes(self) -> dict:
        from frbench.tasks.initial_states import FallenStarts, draw_start

        rows = [draw_start(self.spec_robot, self.terrain, self._rng) for _ in range(self.num_envs)]
        starts = FallenStarts(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                              np.array([r[2] for r in rows]), [r[3] for r in rows])
        obs = self.task.reset(starts)
        self._qd_prev = self.task.state.qd.copy()
        zeros = np.zeros((self.num_envs, self.spec_robot.n_joints))
        self._actions = (zeros, zeros)  # a_{t-1}, a_{t-2}
        if self._renderer is not None:
            for k in range(self.num_envs):
                self._renderer.forget(k)
        return obs

    def _success_info(self) -> dict:
        tracker, signals = self.task.success, self.task.signals
        if self.spec_robot.kind == "humanoid":
            upright = signals.height > tracker.up_height
        else:
            upright = tracker.upright(signals)
        return {"success": tracker.success.copy(), "upright": np.asarray(upright, dtype=bool),
                "time_to_recover": tracker.time_to_recover.copy(),
                "diverged": self.task.physics_diverged | self.task.settle_diverged}

    def episode_metrics(self) -> dict[str, np.ndarray]:
        """The per-episode record of ``frbench evaluate`` so far, each (N,) (time_to_recover NaN if none)."""
        success, metrics = self.task.success, self.task.metrics
        diverged = metrics.diverged | self.task.settle_diverged
        return {"success": success.success & ~diverged, "time_to_recover": success.time_to_recover.copy(),
                "final_displacement": metrics.final_displacement.copy(),
                "max_displacement": metrics.max_displacement.copy(), "energy": metrics.energy.copy(),
                "smoothness": np.asarray(metrics.smoothness).copy(),
                "peak_contact_force": metrics.peak_contact_force.copy(), "rolled_over": metrics.rolled_over.copy(),
                "diverged": diverged.copy()}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw new fallen starts (seeded) for every environment."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        obs = self._new_episodes()
        return self._flat(obs), {}

    def step(self, actions):
        """Apply normalised actions (num_envs, n_joints); all episodes truncate together after 250 steps."""
        actions = np.clip(np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1), -1.0, 1.0)
        obs = self.task.step(self.targets(actions))
        reward, terms = self._reward(actions)
        self._qd_prev = self.task.state.qd.copy()
        self._actions = (actions, self._actions[0])
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.full(self.num_envs, self.task.t >= self.episode_steps)
        infos = {**self._success_info(), "reward_terms": terms}
        flat = self._flat(obs)
        if truncated.all():
            infos["episode_metrics"] = self.episode_metrics()
            infos["final_obs"] = flat
            flat = self._flat(self._new_episodes())
        return flat, reward.astype(np.float32), terminated, truncated, infos

    # -- rendering ------------------------------------------------------------------------------------------

    def render_frame(self, row: int = 0) -> np.ndarray:
        """An RGB image (H, W, 3) uint8 of environment ``row`` now, captioned with time, success and simulator."""
        from frbench.backends.base import CONTROL_DT
        from frbench.render import SIMULATOR_LABELS, SceneRenderer, caption

        if self._renderer is None:
            self._renderer = SceneRenderer(self.spec_robot, self.terrain, *self.render_size)
        s = self.task.state
        recovered = self.task.success.success[row] if hasattr(self.task, "success") else False
        text = caption(f"{self.spec_robot.name}, {self.terrain_label}",
                       SIMULATOR_LABELS.get(self.backend_name, self.backend_name), self.task.t * CONTROL_DT,
                       float(self.task.success.time_to_recover[row]) if recovered else None)
        return self._renderer.frame(s.base_pos[row], s.base_quat[row], s.q[row], text, track=row)

    def render(self):
        """``render_mode="rgb_array"``: one frame per environment (a tuple); otherwise None."""
        if self.render_mode != "rgb_array":
            return None
        return tuple(self.render_frame(k) for k in range(self.num_envs))

    def close(self, **kwargs):
        """Free the simulator and the renderer."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.task.close()


class FallRecoveryEnv(gymnasium.Env):
    """One recovery episode at a time (a `FallRecoveryVectorEnv` of size 1); see the module docstring."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": RENDER_FPS}

    def __init__(self, render_mode: str | None = None, **kwargs):
        self._vector = FallRecoveryVectorEnv(num_envs=1, render_mode=render_mode, **kwargs)
        self.render_mode = render_mode
        self.observation_space = self._vector.single_observation_space
        self.action_space = self._vector.single_action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw a new fallen start."""
        super().reset(seed=seed)
        obs, info = self._vector.reset(seed=seed)
        return obs[0], info

    def step(self, action):
        """Apply a normalised action (n_joints,) in [−1, 1]: q* = q̊ + action_scale · a."""
        vector = self._vector
        actions = np.clip(np.asarray(action, dtype=np.float64)[None], -1.0, 1.0)
        obs = vector.task.step(vector.targets(actions))
        reward, terms = vector._reward(actions)
        vector._qd_prev = vector.task.state.qd.copy()
        vector._actions = (actions, vector._actions[0])
        truncated = vector.task.t >= vector.episode_steps
        info = _first_row(vector._success_info())
        info["reward_terms"] = {k: float(v[0]) for k, v in terms.items()}
        if truncated:
            info["episode_metrics"] = _first_row(vector.episode_metrics())
        return vector._flat(obs)[0], float(reward[0]), False, bool(truncated), info

    def render(self):
        """``render_mode="rgb_array"``: an RGB image (H, W, 3) uint8; otherwise None."""
        return self._vector.render_frame(0) if self.render_mode == "rgb_array" else None

    def close(self):
        """Free the simulator and the renderer."""
        self._vector.close()


def _first_row(values: dict[str, np.ndarray]) -> dict:
    """Row 0 of (N,) arrays as Python scalars, NaN (no time to recover yet) as None."""
    out = {}
    for key, value in values.items():
        item = value[0].item()
        out[key] = None if isinstance(item, float) and np.isnan(item) else item
    return out


def register_envs() -> None:
    """Register ``frbench/FallRecovery-v1`` (idempotent)."""
    from frbench.tasks.protocol import CONTROL_DT, EPISODE_SECONDS

    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point="frbench.gym:FallRecoveryEnv",
            vector_entry_point="frbench.gym:FallRecoveryVectorEnv",
            max_episode_steps=int(round(EPISODE_SECONDS / CONTROL_DT)),
            disable_env_checker=True,
        )


register_envs()
