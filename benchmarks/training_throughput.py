"""Training env steps per second beside the raw simulator throughput of the same batch.

The training env (`RecoveryTrainingEnv`: 256 randomised robots on the terrain
grid, rewards, privileged observations, Pinocchio CoM) stepped with random
actions, against the same MuJoCo batch stepped by the bare PD loop (what the
backend wraps), and against a full rsl-rl iteration (rollout + PPO/MCP update)
converted to env steps/s. Target: env / raw >= 0.6.

Run: ``python benchmarks/training_throughput.py [--envs 256] [--seconds 5]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from common import timed

from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=args.envs, episode_steps=100000))
    actions = torch.zeros(args.envs, env.num_actions)
    env_rate = timed(lambda: env.step(actions), args.seconds) * args.envs
    backend = env.backend
    batch, spec = backend.batch, env.spec
    ctrl, qpos, qvel = batch.bind("ctrl"), batch.bind("qpos"), batch.bind("qvel")
    targets = np.tile(spec.default_pose, (args.envs, 1))
    kp, kd, limits = env.params.kp, env.params.kd, np.asarray(spec.torque_limits)

    def raw_step():
        for _ in range(backend.substeps):
            ctrl[:] = np.clip(kp * (targets - qpos[:, backend._qadr]) - kd * qvel[:, backend._dadr], -limits, limits)
            batch.step(nstep=1)

    raw_rate = timed(raw_step, args.seconds) * args.envs
    from rsl_rl.runners import OnPolicyRunner

    from frbench.training.methods import make_train_cfg

    cfg = make_train_cfg("frnet")
    runner = OnPolicyRunner(env, cfg, log_dir=None, device="cpu")
    start = time.perf_counter()
    runner.learn(2)
    learn_rate = 2 * cfg["num_steps_per_env"] * args.envs / (time.perf_counter() - start)
    env.close()
    print(f"envs {args.envs}: raw PD+MuJoCo {raw_rate:.0f} steps/s, training env {env_rate:.0f} steps/s "
          f"(ratio {env_rate / raw_rate:.2f}), full PPO+MCP iteration {learn_rate:.0f} steps/s (ratio {learn_rate / raw_rate:.2f})")


if __name__ == "__main__":
    main()
