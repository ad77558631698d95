"""G1 residual training env steps per second in MuJoCo, in PyBullet, and on the batch split between them.

The training environment of the G1 residual runs (`RecoveryTrainingEnv` with the
``keyframe-humanoid`` base controller, gated residual, nominal physics, flat
ground) stepped with zero actions, built once per backend; the split batch
(``--backend mujoco+pybullet``) runs half of the environments in each
simulator one after the other, so its expected rate is the harmonic mean of
the two single-simulator rates. Printed: each rate, the split's ratio to
MuJoCo alone and to that expectation (≈ 1: the split adds no cost of its own).

Run: ``python benchmarks/split_training_throughput.py [--envs 64] [--seconds 5]``.
"""

from __future__ import annotations

import argparse

import torch
from common import timed

from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig
from frbench.training.reward_tables import humanoid_reward_config


def env_rate(backend: str, envs: int, seconds: float) -> float:
    """Env steps/s of the G1 residual training env on ``backend``."""
    cfg = TrainEnvConfig(num_envs=envs, backend=backend, robot="g1", families=("flat",), episode_steps=100000,
                         settle_steps=5, randomize=False, reward=humanoid_reward_config(),
                         base_controller="keyframe-humanoid", residual_gate=True, action_scale=0.1)
    env = RecoveryTrainingEnv(cfg)
    actions = torch.zeros(envs, env.num_actions)
    rate = timed(lambda: env.step(actions), seconds) * envs
    env.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    rates = {name: env_rate(name, args.envs, args.seconds) for name in ("mujoco", "pybullet", "mujoco+pybullet")}
    expected = 2.0 / (1.0 / rates["mujoco"] + 1.0 / rates["pybullet"])
    print(f"G1 residual training env, {args.envs} envs: MuJoCo {rates['mujoco']:.0f} steps/s, PyBullet "
          f"{rates['pybullet']:.0f} steps/s, split {rates['mujoco+pybullet']:.0f} steps/s (ratio to MuJoCo "
          f"{rates['mujoco+pybullet'] / rates['mujoco']:.2f}, to the harmonic mean of the two "
          f"{rates['mujoco+pybullet'] / expected:.2f})")


if __name__ == "__main__":
    main()
