"""The training environment: rsl-rl's `VecEnv` over frbench's episode engine.

`RecoveryTrainingEnv` is a shell over the core environment
(`frbench.tasks.core_env.CoreEnv`, which the Gymnasium envs share): the core env
owns the simulator and the episode engine (`frbench.tasks.recovery.RecoveryTask`,
the one ``frbench evaluate`` runs) and steps it (action transform, held action,
the reward `step_reward.StepReward`, the assist force, the fallen starts). This
module composes the pieces training passes in — the batch's robots and their
randomised physics (`population`), the action → targets rule (`residual`), held
actions (`action_hold`), the reward, the assist force (`assist`), the critic's
and the estimator's observation groups (`observation_groups.PrivilegedGroups`) —
and keeps what only training has: the world of terrain tiles and its curriculum,
which tile each episode starts on, demo, rise and bank starts (`start_sources`,
`start_bank`, through the core env's ``drive``, ``restart`` and ``begin_recorded``),
episode statistics for rsl-rl's log, and torch tensors.

One environment for every simulator and device. The env computes in the namespace of
its backend's arrays (`frbench.arrays`): float64 numpy on the host for the CPU
simulators (``mujoco``, ``pybullet``, ``mujoco+pybullet``), float32 torch tensors on the
device for ``mujoco-warp`` (``device`` ``cpu`` or ``cuda:N``: Warp's worlds and the
tensors both there), with the same code — targets, observations, privileged groups,
rewards, the success test. Per episode, the curriculum, the episode statistics and the
draws of starts and physics run on the host from the env's one generator, whatever the
device (success and divergence come to the host once per episode). Its parts come from
`parts.build_parts` or from a device bundle (`device_bundle.load_bundle`).

N fallen robots on a world of all terrain tiles (`terrain_grid`), each on the
tile its curriculum level says, with randomised morphologies (or one named
robot), randomised gains and motor strength, friction and payload, trained on
the paper's rewards. Episodes are `TrainEnvConfig.episode_steps` control steps
(350 in the paper) and end together by time-out; all environments then get new
fallen starts on their (possibly new) tiles.

Observation groups (float32 TensorDict, N rows):

* ``policy``  o_t (6 + 3J = 42): [ω, g, q − q̊, q̇, a_{t−1}];
* ``history`` the last H = 5 o_t, oldest first (H·42);
* ``long_history`` (only with ``TrainEnvConfig.long_history`` = T > 0) the last
  T o_t, oldest first (T·42), for RMA's adaptation module;
* ``privileged`` the critic's s_t (277): [o_t, 187-point height scan, 4 group
  masses [kg], Kp (J) and Kd (J), CoM xy in the base yaw frame [m], 13 contact
  flags, 4 foot force norms [N], friction];
* ``mass`` (4) and ``contact`` (13): the estimator's labels (Pinocchio masses
  incl. payload; backend contact flags); ``velocity`` (3): base linear
  velocity, body frame [m/s]; ``extrinsics`` (11): RMA's environment factors;
* ``teacher`` (only with ``TrainEnvConfig.teacher``, J + 3): the teacher's label, the imitation and PPO
  weights, and whether the teacher acted (`frbench.training.teacher`); the env executes the label in the
  episodes the teacher acts in.

Action a (J) [-]: joint targets q* = q̊ + ``action_scale``·a, clipped to the
joint limits (the paper's q* = q̊ + a with a scale, as legged_gym).
"""

from __future__ import annotations

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from frbench.arrays import copy_of, is_host, to_host
from frbench.backends.simulators import DEVICE_SIMULATORS
from frbench.robots.joint_frame import learner_joint_frame
from frbench.tasks.actions import DirectTargets
from frbench.tasks.core_env import CoreEnv
from frbench.training.action_hold import HeldAction
from frbench.training.assist import AssistForce
from frbench.training.config import TrainEnvConfig
from frbench.training.curves import LossLog
from frbench.training.observation_groups import PrivilegedGroups
from frbench.training.parts import TrainingParts, build_parts
from frbench.training.residual import ResidualController
from frbench.training.step_reward import StepReward
from frbench.training.start_sources import CurriculumStarts
from frbench.training.teacher import TEACHER_GROUP, EnvTeacher

__all__ = ["RecoveryTrainingEnv", "TrainEnvConfig"]


class RecoveryTrainingEnv(VecEnv):
    """See the module docstring. ``cfg`` is a `TrainEnvConfig`; ``device`` (`frbench.backends.devices.parse_device`'s
    value, default ``cpu``): where a device simulator (``mujoco-warp``) runs and the outputs live (the CPU
    simulators run on ``cpu`` only); ``parts``: the `TrainingParts` to build from (default `build_parts` of
    ``cfg``)."""

    def __init__(self, cfg: TrainEnvConfig, device: str | None = None, parts: TrainingParts | None = None):
        self.cfg_obj = cfg
        self.cfg = {"env": {k: (str(v) if k == "reward" else v) for k, v in cfg.to_dict().items()}}
        on_device = cfg.backend in DEVICE_SIMULATORS
        self.device = (device or "cpu") if on_device else "cpu"
        if not on_device and device not in (None, "cpu"):
            raise ValueError(f"backend {cfg.backend} runs on the CPU; --device {device} is for "
                             f"{', '.join(DEVICE_SIMULATORS)}")
        self.num_envs = n = cfg.num_envs
        parts = build_parts(cfg) if parts is None else parts
        self.rng, self.grid, self.robots = parts.rng, parts.grid, parts.robots
        self.curriculum, self.raster = parts.curriculum, parts.raster
        self.spec = self.robots.spec
        self.num_actions = self.spec.n_joints
        self.default_pose = np.asarray(self.spec.default_pose)
        #: the joint frame the policy observes and acts in (`learner_joint_frame`)
        self.joint_frame = learner_joint_frame(self.spec.kind, bool(cfg.base_controller))
        frame = parts.frame
        policy_pose = self.default_pose if frame is None else np.asarray(frame.canonical_spec(self.spec).default_pose)
        targets_of = (ResidualController(cfg.base_controller, cfg.base_controller_parameters, self.spec,
                                         cfg.action_scale, cfg.residual_gate, cfg.gate_phases)
                      if cfg.base_controller else DirectTargets(policy_pose, cfg.action_scale))
        actions = HeldAction(cfg.action_hold)
        self.max_episode_length = actions.decisions_per_episode(cfg.episode_steps)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=self.device)
        reward = StepReward(parts.reward, self.spec, self.robots.nominal_height, self._ground_height,
                            self.robots.head)
        assist = AssistForce(cfg.assist_force, cfg.assist_until, self.robots.env_masses)
        self.starts = CurriculumStarts(cfg, self.grid, self.raster, self.curriculum, self.robots, parts.bank)
        self.core = CoreEnv(self.spec, cfg.backend, self.grid.world, n, transform=targets_of, hold=actions,
                            reward=reward, assist=assist, starts=self.starts, rng=self.rng, history=cfg.history,
                            long_history=cfg.long_history, episode_steps=cfg.episode_steps,
                            variants=self.robots.variants, ground_height=self._ground_height,
                            nominal_height=self.robots.nominal_height, track_metrics=False, surface_rules=False,
                            privileged=PrivilegedGroups(self.raster, self.starts, self.robots, frame),
                            joint_frame=frame,
                            device=self.device if on_device else None, world=parts.world)
        #: whether the backend's arrays live on the device (torch) rather than on the host (numpy)
        self.device_arrays = self.core.device_arrays
        #: the teacher labelling every control step (`frbench.training.teacher`), or None
        self.teacher = (EnvTeacher(self.robots.specs, self.robots.assignment, policy_pose, frame, cfg.action_scale,
                                   cfg.imitation_schedule(), cfg.dagger_noise, cfg.seed) if cfg.teacher else None)
        self.last_episode_stats: dict[str, float] = {}
        #: the curriculum's levels at the last episode end (`TerrainCurriculum.stats`, ``level_<family>`` …)
        self.last_curriculum_stats: dict[str, float] = {}
        #: each reward term's mean per env step since the learning curve's last row (``reward_<term>``)
        self.reward_means = LossLog(prefix="reward_")
        self._new_episodes()

    # ------------------------------------------------------------------ the core env's parts, for callers
    @property
    def env_steps(self) -> int:
        """Env steps taken so far (N per control step); the run restores it on --resume."""
        return self.core.env_steps

    @env_steps.setter
    def env_steps(self, steps: int) -> None:
        self.core.env_steps = steps
        if self.teacher is not None:  # a resumed run: the current episode's teacher and weights at its step
            self.teacher.resume(steps, self._episode_number())

    def _episode_number(self) -> int:
        """The run's episodes so far (all environments' episodes end together)."""
        return int(self.core.env_steps // (self.num_envs * self.cfg_obj.episode_steps))

    @property
    def backend(self):
        """The core env's simulator (read-only: benchmarks time its raw step)."""
        return self.core.backend

    # ------------------------------------------------------------------ the batch's robots, for callers
    @property
    def specs(self):
        return self.robots.specs

    @property
    def assignment(self) -> np.ndarray:
        return self.robots.assignment

    @property
    def env_masses(self) -> np.ndarray:
        return self.robots.env_masses

    @property
    def env_payload(self) -> np.ndarray:
        return self.robots.env_payload

    @property
    def params(self):
        """The current episode's `PhysicsParams`."""
        return self.core.params

    @property
    def step_count(self) -> int:
        """Control steps taken in the current episode."""
        return self.core.t

    def _ground_height(self, xy):
        """Terrain height [m] (N,) under world points ``xy`` (N, 2) on each environment's tile (numpy or torch)."""
        return self.raster.lookup(self.starts.tiles(xy), xy[:, None, :])[:, 0]

    # ------------------------------------------------------------------ observations
    def get_observations(self) -> TensorDict:
        """The core env's observation groups (`CoreEnv.observation_groups`) as float32 tensors."""
        groups = self.core.observation_groups()
        if self.teacher is not None:
            groups[TEACHER_GROUP] = self.teacher.group()
        return TensorDict({k: torch.as_tensor(v, dtype=torch.float32, device=self.device) for k, v in groups.items()},
                          batch_size=[self.num_envs], device=self.device)

    # ------------------------------------------------------------------ stepping
    def step(self, actions: torch.Tensor):
        """One decision for every environment (rsl-rl `VecEnv.step`): the action held for
        `TrainEnvConfig.action_hold` control steps (fewer if the episode ends first), their rewards summed."""
        n = self.num_envs
        if self.device_arrays:
            action = torch.clamp(actions.detach().to(self.device, self.core.state.q.dtype), -10.0, 10.0)
        else:
            action = np.clip(actions.detach().cpu().numpy().astype(np.float64), -10.0, 10.0)
        if self.teacher is not None:  # the teacher runs on the host
            executed = self.teacher.executed(to_host(action))
            action = torch.as_tensor(executed, dtype=action.dtype, device=self.device) if self.device_arrays else executed
        reward, term_sums, alive = self.core.step(action)
        self.episode_length_buf += 1
        log = {f"/reward/{k}": v / self.core.actions.held for k, v in _alive_means(term_sums, alive).items()}
        self.reward_means.add({k[len("/reward/"):]: v for k, v in log.items()})
        done = self.core.done
        if done:
            self.last_episode_stats = self.starts.end_episodes(self.core, copy_of(self.core.success.success), alive)
            curriculum = self.curriculum.stats()
            self.last_curriculum_stats = {k.replace("/", "_"): v for k, v in curriculum.items() if k != "level/all"}
            log.update({f"/episode/{k}": v for k, v in self.last_episode_stats.items()})
            log.update({f"/curriculum/{k}": float(v) for k, v in curriculum.items()})
            self._new_episodes()
        elif self.teacher is not None:
            self.teacher.observe(self._host_observation(), self.env_steps)
        obs = self.get_observations()
        dones = torch.full((n,), bool(done), device=self.device)
        extras = {"time_outs": dones.clone(), "log": log}
        return obs, torch.as_tensor(reward, dtype=torch.float32, device=self.device), dones, extras

    def _host_observation(self) -> dict:
        """The engine's proprioception dict as numpy arrays (the teacher's input)."""
        return {k: to_host(v) for k, v in self.core.observation().items()}

    def _new_episodes(self) -> None:
        """New episodes for every environment (the core env's start distribution, `CurriculumStarts`)."""
        self.core.new_episodes()
        self.episode_length_buf.zero_()
        if self.teacher is not None:
            self.teacher.new_episodes(self._host_observation(), self.env_steps, self._episode_number())

    def close(self) -> None:
        """Free the simulator (the core env's)."""
        self.core.close()


def _alive_means(values: dict, alive) -> dict:
    """Each entry's mean (N,) over the ``alive`` (N,) environments (0 when none is): floats for numpy, 0-d tensors
    on the device for torch (read once per curve row, `LossLog`; all terms in one reduction)."""
    if not values or is_host(alive):
        return {k: _alive_mean(v, alive) for k, v in values.items()}
    stacked = torch.stack(list(values.values()))
    means = (stacked * alive).sum(dim=1) / alive.sum().clamp(min=1)
    return dict(zip(values, means.unbind()))


def _alive_mean(values: np.ndarray, alive: np.ndarray) -> float:
    """Mean of ``values`` (N,) over the ``alive`` (N,) environments (0 when none is)."""
    if alive.all():
        return float(np.mean(values))
    return float(np.mean(values[alive])) if alive.any() else 0.0
