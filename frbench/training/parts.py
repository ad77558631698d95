"""What the training env is built from besides its config: the parts only the CPU stack can make.

`build_parts` makes them the way the training env always has, from the env's one generator in one order: the
terrain grid, the batch's robots (`population.TrainingRobots`: robot files, Pinocchio's masses), the curriculum's
families and first levels, the terrain rasters, the learner's joint frame (read from the robot files), the reward
table with the URDF's velocity limits, and with ``start_bank`` the bank of settled starts (`start_bank`). A device
bundle (`frbench.training.device_bundle`) saves them, with the simulator's compiled world, for a machine without
the robot files, Pinocchio or PyBullet (a GPU machine), where `frbench.training.env.RecoveryTrainingEnv` is built
from them unchanged.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from frbench.robots.batch_frame import batch_joint_frame
from frbench.robots.joint_frame import learner_joint_frame
from frbench.training.curriculum import TerrainCurriculum
from frbench.training.height_raster import HeightRaster
from frbench.training.population import TrainingRobots
from frbench.training.reward_tables import with_joint_velocity_limits
from frbench.training.terrain_grid import build_grid


@dataclasses.dataclass
class TrainingParts:
    """The parts of one training env (module docstring).

    Attributes:
        rng: the env's generator, after the draws that made the parts (the starts of every episode follow).
        grid: the world of terrain tiles (`terrain_grid.TerrainGrid`).
        robots: the batch's `TrainingRobots`.
        curriculum: the `TerrainCurriculum` (families and first levels).
        raster: the tiles' `HeightRaster`.
        frame: the learner's `JointFrame` shared by the batch's robots, a `BatchJointFrame` (one per environment)
            when their conventions differ (wide bodies), or None (the robots' own joints).
        reward: the reward table with the velocity limits resolved (`reward_tables.with_joint_velocity_limits`).
        bank: the `start_bank.StartBank`, or None (fresh starts every episode).
        world: the simulator's compiled world (`mujoco_warp_backend.CompiledWorld`), or None: compiled by the backend.
    """

    rng: np.random.Generator
    grid: object
    robots: TrainingRobots
    curriculum: TerrainCurriculum
    raster: HeightRaster
    frame: object
    reward: object
    bank: object = None
    world: object = None


def build_parts(cfg, log=print) -> TrainingParts:
    """The parts of `TrainEnvConfig` ``cfg`` (module docstring); needs the CPU stack."""
    rng = np.random.default_rng(cfg.seed)
    grid = build_grid(cfg.families)
    robots = TrainingRobots.drawn(cfg, rng)
    spec = robots.spec
    canonical = learner_joint_frame(spec.kind, bool(cfg.base_controller)) == "canonical"
    frame = batch_joint_frame(robots.specs, robots.assignment) if canonical else None
    curriculum = TerrainCurriculum(cfg.num_envs, rng, families=cfg.families, start_level=cfg.start_level)
    if not cfg.curriculum:
        curriculum.level[:] = rng.integers(1, curriculum.max_level + 1, size=cfg.num_envs)
    raster = HeightRaster(grid, sorted(grid.tiles))
    reward = with_joint_velocity_limits(cfg.reward, spec.urdf_path, spec.joint_names)
    bank = None
    if cfg.start_bank:
        from frbench.training.start_bank import record_bank

        bank = record_bank(cfg, grid, raster, robots, cfg.start_bank, rng, log)
    return TrainingParts(rng, grid, robots, curriculum, raster, frame, reward, bank)
