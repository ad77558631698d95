"""The training environment: rsl-rl's `VecEnv` over frbench's episode engine.

`RecoveryTrainingEnv` is a shell over the core environment
(`frbench.tasks.core_env.CoreEnv`, which the Gymnasium envs share): the core env
owns the simulator and the episode engine (`frbench.tasks.recovery.RecoveryTask`,
the one ``frbench evaluate`` runs) and steps it (action transform, held action,
the reward `step_reward.StepReward`, the assist force, the fallen starts). This
module composes the pieces training passes in — the batch's robots and their
randomised physics (`population`), the action → targets rule (`residual`), held
actions (`action_hold`), the reward, the assist force (`assist`) — and keeps what
only training has: the world of terrain tiles and its curriculum, which tile each
episode starts on, demo and rise starts (`start_sources`, through the core env's
``drive`` and ``restart``), the observation history and groups, episode
statistics, and torch tensors.

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
  velocity, body frame [m/s]; ``extrinsics`` (11): RMA's environment factors.

Action a (J) [-]: joint targets q* = q̊ + ``action_scale``·a, clipped to the
joint limits (the paper's q* = q̊ + a with a scale, as legged_gym).
"""

from __future__ import annotations

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from frbench.tasks.core_env import CoreEnv
from frbench.training.action_hold import HeldAction
from frbench.training.assist import AssistForce
from frbench.training.config import TrainEnvConfig
from frbench.training.curriculum import TerrainCurriculum
from frbench.training.height_raster import HeightRaster
from frbench.training.observation_groups import observation_groups
from frbench.training.population import TrainingRobots, yaw_of
from frbench.tasks.actions import DirectTargets
from frbench.training.residual import ResidualController
from frbench.training.step_reward import StepReward
from frbench.training.start_sources import DemoStarts, RiseStarts
from frbench.training.terrain_grid import build_grid

__all__ = ["RecoveryTrainingEnv", "TrainEnvConfig"]


class RecoveryTrainingEnv(VecEnv):
    """See the module docstring. ``cfg`` is a `TrainEnvConfig`; ``device`` the torch device of the outputs."""

    def __init__(self, cfg: TrainEnvConfig, device: str = "cpu"):
        self.cfg_obj = cfg
        self.cfg = {"env": {k: (str(v) if k == "reward" else v) for k, v in cfg.to_dict().items()}}
        self.device = device
        self.num_envs = n = cfg.num_envs
        self.rng = np.random.default_rng(cfg.seed)
        self.grid = build_grid(cfg.families)
        self.robots = TrainingRobots(cfg, self.rng)
        self.spec = self.robots.spec
        self.num_actions = self.spec.n_joints
        self.default_pose = np.asarray(self.spec.default_pose)
        targets_of = (ResidualController(cfg.base_controller, cfg.base_controller_parameters, self.spec,
                                         cfg.action_scale, cfg.residual_gate, cfg.gate_phases)
                      if cfg.base_controller else DirectTargets(self.default_pose, cfg.action_scale))
        actions = HeldAction(cfg.action_hold)
        self.max_episode_length = actions.decisions_per_episode(cfg.episode_steps)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long)
        self.curriculum = TerrainCurriculum(n, self.rng, families=cfg.families, start_level=cfg.start_level)
        if not cfg.curriculum:
            self.curriculum.level[:] = self.rng.integers(1, 11, size=n)
        self.raster = HeightRaster(self.grid, sorted(self.grid.tiles))
        reward = StepReward(cfg.reward, self.spec, self.robots.nominal_height, self._ground_height, self.robots.head)
        assist = AssistForce(cfg.assist_force, cfg.assist_until, self.robots.env_masses)
        self.core = CoreEnv(self.spec, cfg.backend, self.grid.world, n, transform=targets_of, hold=actions,
                            reward=reward, assist=assist, episode_steps=cfg.episode_steps,
                            variants=self.robots.variants, ground_height=self._ground_height,
                            nominal_height=self.robots.nominal_height, track_metrics=False, surface_rules=False)
        self.demo = DemoStarts(cfg.demo_start_fraction, cfg.demo_start_until, cfg.demo_refresh_episodes,
                               cfg.demo_steps, cfg.demo_stride)
        self.rise = RiseStarts(cfg.rise_start_fraction, cfg.demo_refresh_episodes) if cfg.rise_start_fraction else None
        self.last_episode_stats: dict[str, float] = {}
        self.from_demo = np.zeros(n, dtype=bool)
        self._reset_all()

    # ------------------------------------------------------------------ the core env's parts, for callers
    @property
    def env_steps(self) -> int:
        """Env steps taken so far (N per control step); the run restores it on --resume."""
        return self.core.env_steps

    @env_steps.setter
    def env_steps(self, steps: int) -> None:
        self.core.env_steps = steps

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

    def _ground_height(self, xy: np.ndarray) -> np.ndarray:
        """Terrain height [m] (N,) under world points ``xy`` (N, 2) on each environment's tile."""
        return self.raster.lookup(self.tile_row, xy[:, None, :])[:, 0]

    # ------------------------------------------------------------------ episodes
    def _reset_all(self) -> None:
        """New episodes for every environment: fresh fallen starts, a fraction of them replaced by bank states."""
        cfg, n = self.cfg_obj, self.num_envs
        fraction = self.demo.fraction(self.env_steps)
        if self.demo.needs_recording(fraction):
            self._fresh_starts()
            self.demo.record(self.core, self.specs, self.assignment, self.tile_row)
        if self.rise is not None:
            if self.rise.needs_recording():
                self._fresh_starts()
                self.rise.record(self.core, self.core.transform.fresh_copy(), self.spec, self.default_pose,
                                 self.tile_row)
            self.rise.count_episode()
        self._fresh_starts()
        action = np.zeros((n, self.spec.n_joints))
        self.from_demo = self.demo.draw(self.rng, n, fraction)
        if self.from_demo.any():
            ids = np.flatnonzero(self.from_demo)
            state, targets, tiles = self.demo.sample(ids, self.rng)
            self._restart_from(ids, state, tiles)
            action[ids] = (targets - self.default_pose) / cfg.action_scale
        self.core.begin(action)  # a_{t-1} = a_t: both zero at a fresh start; the transform reset
        if self.rise is not None:
            drawn = self.rise.draw(self.rng, self.from_demo)
            if drawn is not None:
                ids, state, tiles, targets, paths = drawn
                self._restart_from(ids, state, tiles)
                self.from_demo[ids] = True
                self.core.transform.enter_gate(ids, targets, self.core.state.q, paths)
        o_t = self.core.policy_observation()
        self.history = np.repeat(o_t[:, None, :], cfg.history, axis=1)
        self.long_history = np.repeat(o_t[:, None, :], cfg.long_history, axis=1) if cfg.long_history else None

    def _restart_from(self, ids: np.ndarray, state, tiles) -> None:
        """Start environments ``ids`` from recorded ``state`` (len(ids) rows) on their recorded ``tiles``."""
        self.core.restart(ids, state)
        self.tile_row[ids] = tiles

    def _fresh_starts(self) -> None:
        """Fallen starts on every environment's curriculum tile, settled for ``settle_steps`` by the engine."""
        tiles = list(zip(self.curriculum.family.tolist(), self.curriculum.level.tolist()))
        self.tile_row = np.array([self.raster.index[t] for t in tiles])
        starts = self.core.draw_fallen(self.rng, [self.grid.tiles[t] for t in tiles],
                                       [self.grid.offsets[t] for t in tiles], [self.specs[k] for k in self.assignment])
        self.core.reset(starts, self.robots.episode_params(), self.cfg_obj.settle_steps)
        self.episode_length_buf.zero_()

    # ------------------------------------------------------------------ observations
    def _observations(self, o_t: np.ndarray) -> TensorDict:
        core = self.core
        s = core.state
        scan = self.raster.scan(self.tile_row, s.base_pos, yaw_of(s.base_quat))
        return observation_groups(o_t, self.history, self.long_history, s, core.contacts, core.params,
                                  self.robots.env_masses, self.robots.com_xy(s, core.whole_body_com()), scan,
                                  core.physics_diverged)

    def get_observations(self) -> TensorDict:
        """The current observation groups."""
        return self._observations(self.core.policy_observation())

    # ------------------------------------------------------------------ stepping
    def step(self, actions: torch.Tensor):
        """One decision for every environment (rsl-rl `VecEnv.step`): the action held for
        `TrainEnvConfig.action_hold` control steps (fewer if the episode ends first), their rewards summed."""
        n, cfg = self.num_envs, self.cfg_obj
        action = np.clip(actions.detach().cpu().numpy().astype(np.float64), -10.0, 10.0)
        reward, term_sums, alive = self.core.step(action)
        held = self.core.actions.held
        self.episode_length_buf += 1
        o_t = self.core.policy_observation()
        self.history = np.concatenate([self.history[:, 1:], o_t[:, None, :]], axis=1)
        if self.long_history is not None:
            self.long_history = np.concatenate([self.long_history[:, 1:], o_t[:, None, :]], axis=1)
        log = {f"/reward/{k}": _alive_mean(v, alive) / held for k, v in term_sums.items()}
        done = self.core.done
        if done:
            success = self.core.success.success.copy()
            self.last_episode_stats = self._episode_stats(success, alive)
            log.update({f"/episode/{k}": v for k, v in self.last_episode_stats.items()})
            if cfg.curriculum:  # the curriculum judges fallen starts only
                fallen = np.flatnonzero(~self.from_demo)
                self.curriculum.update(fallen, success[fallen])
            log.update({f"/curriculum/{k}": float(v) for k, v in self.curriculum.stats().items()})
            self._reset_all()
            o_t = self.core.policy_observation()
        obs = self._observations(o_t)
        dones = torch.full((n,), bool(done))
        extras = {"time_outs": torch.full((n,), bool(done)), "log": log}
        return obs, torch.as_tensor(reward, dtype=torch.float32), dones, extras

    def _episode_stats(self, success: np.ndarray, alive: np.ndarray) -> dict[str, float]:
        """Success rate of the episodes from fallen starts, overall, per family (all levels) and, on a split
        backend, per simulator (``success_in_<simulator>``); the diverged fraction; with demo starts, their
        share and their success rate."""
        fallen = ~self.from_demo
        stats = {"success_all": float(success[fallen].mean()) if fallen.any() else 0.0,
                 "diverged": float((~alive).mean()), "mean_level": float(self.curriculum.level.mean())}
        if self.cfg_obj.assist_force > 0.0:
            stats["assist_fraction"] = float(self.core.assist.fraction)
        if self.from_demo.any():
            stats["demo_start_share"] = float(self.from_demo.mean())
            stats["success_demo_starts"] = float(success[self.from_demo].mean())
        for f, family in enumerate(self.cfg_obj.families):
            mine = (self.curriculum.family == f) & fallen
            if mine.any():
                stats[f"success_{family}"] = float(success[mine].mean())
        parts = self.core.simulator_parts()
        for simulator, rows in parts if len(parts) > 1 else ():
            mine = np.zeros_like(fallen)
            mine[rows] = fallen[rows]
            if mine.any():
                stats[f"success_in_{simulator}"] = float(success[mine].mean())
        return stats

    def close(self) -> None:
        """Free the simulator (the core env's)."""
        self.core.close()


def _alive_mean(values: np.ndarray, alive: np.ndarray) -> float:
    """Mean of ``values`` (N,) over the ``alive`` (N,) environments (0 when none is)."""
    if alive.all():
        return float(np.mean(values))
    return float(np.mean(values[alive])) if alive.any() else 0.0
