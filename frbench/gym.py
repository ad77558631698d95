"""Gymnasium environments for researchers who bring their own training loop.

``import frbench.gym`` registers (this module's only purpose; ``import frbench``
registers nothing):

* ``gymnasium.make("frbench/FallRecovery-v0", robot="go2", backend="mujoco",
  terrain="flat", level=1)`` — one environment;
* ``gymnasium.make_vec("frbench/FallRecovery-v0", num_envs=64, ...)`` — a
  batched `FallRecoveryVectorEnv` on one backend batch.

Observation: the paper's o_t as a flat float32 vector (6 + 3·n_joints: body
angular velocity, projected gravity, q − q̊, q̇, previous target − q̊).
Action: joint targets q* [rad] in the canonical order, within the joint limits.
Reward: `upright_reward` (the paper's upright-orientation term, weight 6,
σ = 0.4); the full reward table lives with the trainer. Episodes last 5 s
(250 steps) and end by truncation, all environments together; the vector
environment resets them in the same step (``AutoresetMode.SAME_STEP``), with
the last observation in ``infos["final_obs"]``. ``infos["success"]`` holds the
benchmark's success test.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from frbench.robots import get_robot
from frbench.tasks.initial_states import FallenStarts, draw_start
from frbench.tasks.observations import flatten
from frbench.tasks.recovery import EPISODE_STEPS, RecoveryTask

ENV_ID = "frbench/FallRecovery-v0"


def upright_reward(obs_dict: dict[str, np.ndarray], sigma: float = 0.4, weight: float = 6.0) -> np.ndarray:
    """The paper's upright orientation term w·exp(−(g_z + 1)² / (2σ²)), (N,)."""
    gz = obs_dict["projected_gravity"][:, 2]
    return weight * np.exp(-((gz + 1.0) ** 2) / (2 * sigma**2))


class FallRecoveryVectorEnv(VectorEnv):
    """``num_envs`` recovery episodes of one robot on one terrain, batched in one backend."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, robot: str = "go2", backend: str = "mujoco", terrain: str = "flat",
                 level: int = 1, terrain_seed: int = 0, max_episode_steps: int | None = None):
        from frbench.terrains import make_terrain

        if max_episode_steps not in (None, EPISODE_STEPS):
            raise ValueError(f"max_episode_steps={max_episode_steps}: the protocol's episodes last {EPISODE_STEPS} steps")

        self.spec_robot = get_robot(robot)
        self.num_envs = num_envs
        self.terrain = make_terrain(terrain, level, terrain_seed)
        self.task = RecoveryTask(self.spec_robot, backend, self.terrain, num_envs)
        n = self.spec_robot.n_joints
        self.default_pose = np.asarray(self.spec_robot.default_pose)
        lower = np.asarray(self.spec_robot.joint_lower, dtype=np.float32)
        upper = np.asarray(self.spec_robot.joint_upper, dtype=np.float32)
        self.single_observation_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(6 + 3 * n,), dtype=np.float32)
        self.single_action_space = gymnasium.spaces.Box(lower, upper, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rng = np.random.default_rng()

    def _flat(self, obs: dict) -> np.ndarray:
        return flatten(obs, self.default_pose).astype(np.float32)

    def _new_episodes(self) -> dict:
        rows = [draw_start(self.spec_robot, self.terrain, self._rng) for _ in range(self.num_envs)]
        starts = FallenStarts(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                              np.array([r[2] for r in rows]), [r[3] for r in rows])
        return self.task.reset(starts)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw new fallen starts (seeded) for every environment."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        obs = self._new_episodes()
        return self._flat(obs), {}

    def step(self, actions):
        """Apply joint targets (num_envs, n_joints); all episodes truncate together at 250 steps."""
        obs = self.task.step(np.asarray(actions, dtype=np.float64))
        reward = upright_reward(obs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.full(self.num_envs, self.task.t >= EPISODE_STEPS)
        infos = {"success": self.task.success.success.copy(), "diverged": self.task.backend.diverged.copy()}
        flat = self._flat(obs)
        if truncated.all():
            infos["final_obs"] = flat
            flat = self._flat(self._new_episodes())
        return flat, reward.astype(np.float32), terminated, truncated, infos

    def close(self, **kwargs):
        """Free the simulator."""
        self.task.close()


class FallRecoveryEnv(gymnasium.Env):
    """One recovery episode at a time (a `FallRecoveryVectorEnv` of size 1)."""

    metadata = {"render_modes": []}

    def __init__(self, **kwargs):
        self._vector = FallRecoveryVectorEnv(num_envs=1, **kwargs)
        self.observation_space = self._vector.single_observation_space
        self.action_space = self._vector.single_action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw a new fallen start."""
        super().reset(seed=seed)
        obs, info = self._vector.reset(seed=seed)
        return obs[0], info

    def step(self, action):
        """Apply joint targets (n_joints,) [rad]."""
        obs = self._vector.task.step(np.asarray(action, dtype=np.float64)[None])
        reward = float(upright_reward(obs)[0])
        truncated = self._vector.task.t >= EPISODE_STEPS
        info = {"success": bool(self._vector.task.success.success[0])}
        return self._vector._flat(obs)[0], reward, False, truncated, info

    def close(self):
        """Free the simulator."""
        self._vector.close()


def register_envs() -> None:
    """Register ``frbench/FallRecovery-v0`` (idempotent)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point="frbench.gym:FallRecoveryEnv",
            vector_entry_point="frbench.gym:FallRecoveryVectorEnv",
            max_episode_steps=EPISODE_STEPS,
            disable_env_checker=True,
        )


register_envs()
