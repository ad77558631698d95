"""Gymnasium environments for researchers who bring their own training loop.

``import frbench.gym`` registers (this module's only purpose; ``import frbench``
registers nothing):

* ``gymnasium.make("frbench/FallRecovery-v1", robot="go2", backend="mujoco",
  terrain="flat", level=1)`` — one environment;
* ``gymnasium.make_vec("frbench/FallRecovery-v1", num_envs=64,
  vectorization_mode="vector_entry_point", ...)`` — a batched
  `FallRecoveryVectorEnv` on one backend batch.

``backend``: any simulator of `frbench.backends.BACKENDS` (``mujoco``, ``pybullet``, ``mujoco-warp``: the
``gpu`` extra, docs/gpu.md) or the split batch ``mujoco+pybullet``.

Both envs are shells over the core environment (`frbench.tasks.core_env.CoreEnv`,
which the training env shares): they turn its arrays into Gymnasium's spaces.
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

Fallen starts are drawn from a generator seeded with ``seed`` (default 0) when
the env is made; ``reset(seed=S)`` replaces it with one seeded with S, and a
reset without a seed draws on from the current one.

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

from frbench.render import SIMULATOR_LABELS, SceneRenderer, caption, use_headless_gl
from frbench.robot_checks.lookup import get_robot
from frbench.tasks.actions import ACTION_SCALE, DirectTargets
from frbench.tasks.core_env import CoreEnv
from frbench.tasks.observations import observation_bounds
from frbench.tasks.protocol import CONTROL_DT, EPISODE_SECONDS
from frbench.tasks.recovery import EPISODE_STEPS
from frbench.terrains import height_at, make_terrain
from frbench.training.action_hold import HeldAction
from frbench.training.reward_tables import reward_table
from frbench.training.rewards import RewardConfig
from frbench.training.step_reward import HeadPoints, StepReward

ENV_ID = "frbench/FallRecovery-v1"
#: Frames per second of ``render`` videos (every second control step of 50 Hz).
RENDER_FPS = 25
#: Reward presets: name → function of the robot kind giving a `RewardConfig`.
REWARD_PRESETS = ("training", "paper")


def reward_config(reward, kind: str):
    """The `RewardConfig` of preset ``reward`` (``"training"``: the trainer's table for robots of ``kind``;
    ``"paper"``: the paper's) or ``reward`` itself if it is one."""

    if isinstance(reward, RewardConfig):
        return reward
    if reward == "training":
        return reward_table(kind)
    if reward == "paper":
        return RewardConfig()
    raise ValueError(f"reward={reward!r}: expected one of {', '.join(REWARD_PRESETS)} or a RewardConfig")


class FallRecoveryVectorEnv(VectorEnv):
    """``num_envs`` recovery episodes of one robot on one terrain: a shell over `frbench.tasks.core_env.CoreEnv`
    (``core``) that converts its arrays to Gymnasium's spaces (module docstring)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": ["rgb_array"], "render_fps": RENDER_FPS}

    def __init__(self, num_envs: int = 1, robot: str = "go2", backend: str = "mujoco", terrain: str = "flat",
                 level: int = 1, terrain_seed: int = 0, reward="training", action_scale: float = ACTION_SCALE,
                 render_mode: str | None = None, render_size: tuple[int, int] = (640, 480),
                 max_episode_steps: int | None = None, seed: int = 0):

        if max_episode_steps not in (None, EPISODE_STEPS):
            raise ValueError(f"max_episode_steps={max_episode_steps}: the protocol's episodes last {EPISODE_STEPS} steps")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        if render_mode is not None:

            use_headless_gl()  # before the simulator imports mujoco

        self.spec_robot = spec = get_robot(robot)
        self.num_envs, self.backend_name, self.render_mode, self.render_size = num_envs, backend, render_mode, render_size
        self.action_scale = float(action_scale)
        self.terrain = make_terrain(terrain, level, terrain_seed)
        self.terrain_label = f"{terrain} level {level}"
        head = HeadPoints([spec], np.zeros(num_envs, dtype=int)) if spec.kind == "humanoid" else None
        self.step_reward = StepReward(reward_config(reward, spec.kind), spec, spec.nominal_height,
                                      lambda xy: height_at(self.terrain, xy), head)
        self.episode_steps = EPISODE_STEPS
        n = spec.n_joints
        self.default_pose = np.asarray(spec.default_pose)
        self.core = CoreEnv(spec, backend, self.terrain, num_envs, hold=HeldAction(1), reward=self.step_reward,
                            transform=DirectTargets(self.default_pose, self.action_scale), episode_steps=EPISODE_STEPS,
                            rng=np.random.default_rng(seed))
        low, high = observation_bounds(spec)
        self.single_observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._renderer = None

    # -- observations, actions, rewards ---------------------------------------------------------------------

    def _flat(self) -> np.ndarray:
        """The core env's o_t (N, 6 + 3J) as the observation space's float32, NaN and infinities as 0, clipped."""
        flat = np.nan_to_num(self.core.flat_observation(), nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(flat, self.single_observation_space.low, self.single_observation_space.high).astype(np.float32)

    def _actions(self, actions) -> np.ndarray:
        """Normalised actions as (N, n_joints) float64, clipped to the action space [−1, 1]."""
        return np.clip(np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1), -1.0, 1.0)

    def targets(self, actions) -> np.ndarray:
        """Joint targets q* (N, n_joints) [rad] of normalised actions (N, n_joints) (clipped to [−1, 1]): the core
        env's action transform (`frbench.tasks.actions.DirectTargets`)."""
        state = getattr(self.core, "state", None)  # none before a reset
        return self.core.transform.targets(state, self._actions(actions))

    def _step(self, actions) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], bool]:
        """One core env step of normalised ``actions``: (observation (N, ·) float32, reward (N,), weighted reward
        terms (`StepReward`, the trainer's; 0 where diverged), whether the episodes are over)."""
        reward, terms, alive = self.core.step(self._actions(actions))
        terms = {k: np.where(alive, np.nan_to_num(v), 0.0) for k, v in terms.items()}
        return self._flat(), reward, terms, self.core.done

    # -- episodes -------------------------------------------------------------------------------------------

    def _new_episodes(self) -> np.ndarray:
        """New fallen starts (the core env's `ProtocolStarts`, drawn from its generator) for every environment; the
        first observation."""
        self.core.new_episodes()
        if self._renderer is not None:
            for k in range(self.num_envs):
                self._renderer.forget(k)
        return self._flat()

    def episode_metrics(self) -> dict[str, np.ndarray]:
        """The per-episode record of ``frbench evaluate`` so far, each (N,) (time_to_recover NaN if none)."""
        return self.core.episode_record()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw new fallen starts (seeded) for every environment."""
        if seed is not None:
            self.core.seed(seed)
        return self._new_episodes(), {}

    def step(self, actions):
        """Apply normalised actions (num_envs, n_joints); all episodes truncate together after 250 steps."""
        flat, reward, terms, done = self._step(actions)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.full(self.num_envs, done)
        infos = {**self.core.success_info(), "reward_terms": terms}
        if done:
            infos["episode_metrics"] = self.episode_metrics()
            infos["final_obs"] = flat
            flat = self._new_episodes()
        return flat, reward.astype(np.float32), terminated, truncated, infos

    # -- rendering ------------------------------------------------------------------------------------------

    def render_frame(self, row: int = 0) -> np.ndarray:
        """An RGB image (H, W, 3) uint8 of environment ``row`` now, captioned with time, success and simulator."""
        if self._renderer is None:
            self._renderer = SceneRenderer(self.spec_robot, self.terrain, *self.render_size)
        s = self.core.state
        recovered = self.core.success.success[row] if hasattr(self.core, "success") else False
        text = caption(f"{self.spec_robot.name}, {self.terrain_label}",
                       SIMULATOR_LABELS.get(self.backend_name, self.backend_name), self.core.t * CONTROL_DT,
                       float(self.core.success.time_to_recover[row]) if recovered else None)
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
        self.core.close()


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
        flat, reward, terms, truncated = vector._step(np.asarray(action)[None])
        info = _first_row(vector.core.success_info())
        info["reward_terms"] = {k: float(v[0]) for k, v in terms.items()}
        if truncated:
            info["episode_metrics"] = _first_row(vector.episode_metrics())
        return flat[0], float(reward[0]), False, bool(truncated), info

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
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point="frbench.gym:FallRecoveryEnv",
            vector_entry_point="frbench.gym:FallRecoveryVectorEnv",
            max_episode_steps=int(round(EPISODE_SECONDS / CONTROL_DT)),
            disable_env_checker=True,
        )


register_envs()
