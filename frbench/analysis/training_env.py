"""A trained run's deterministic policy in its own training environment, per simulator.

`frbench evaluate` scores a policy on the benchmark's episodes; this runs it
where it was trained — the run's `TrainEnvConfig` (robots, terrains, episode
length, settle steps, base controller and gate, action hold), optionally on
another backend such as the split ``mujoco+pybullet`` batch — with the
actor's mean action (no exploration noise), or with zero actions (a residual
run's base controller alone, a plain run's default pose). Comparing the two
separates what the residual adds from what its base does, per simulator, on
the distribution PPO saw; a difference in sign from `frbench evaluate` would
point to a mismatch between training and evaluation.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np


def training_env_success(policy: str | Path, episodes: int, backend: str | None = None, zero: bool = False,
                         seed: int = 12345, num_envs: int | None = None) -> dict[str, float]:
    """Mean success rates over ``episodes`` rounds of the training env (each round: every environment runs one
    episode) of the run ``policy`` (run folder or its policy.pt): ``success_all``, per family
    (``success_<family>``) and on a split backend per simulator (``success_in_<simulator>``). ``backend``
    (None: the run's), ``seed`` (the env's random generator: starts, terrains), ``num_envs`` (None: the run's).
    ``zero``: zero actions instead of the actor's mean."""
    import torch

    from frbench.errors import FrbenchError
    from frbench.policies.learned import LearnedPolicy
    from frbench.training.env import RecoveryTrainingEnv
    from frbench.training.run import env_cfg_from_dict

    if episodes < 1:
        raise FrbenchError(f"--episodes {episodes}: expected at least 1")
    path = Path(policy)
    path = path / "policy.pt" if path.is_dir() else path
    if not path.is_file():
        raise FrbenchError(f"{policy}: no training run's policy.pt there")
    data = torch.load(path, weights_only=True)
    config = json.loads(data["config_json"])
    changes = {"seed": int(seed), **({"backend": backend} if backend else {}),
               **({"num_envs": int(num_envs)} if num_envs else {})}
    cfg = dataclasses.replace(env_cfg_from_dict(config["env"]), **changes)
    actor = LearnedPolicy(data, path).actor
    env = RecoveryTrainingEnv(cfg)
    try:
        obs, rounds = env.get_observations(), []
        while len(rounds) < episodes:
            with torch.inference_mode():
                action = torch.zeros(env.num_envs, env.num_actions) if zero else actor(obs)
            obs, _, dones, _ = env.step(action)
            if bool(dones[0]):
                rounds.append(dict(env.last_episode_stats))
    finally:
        env.close()
    keys = [k for k in rounds[0] if k.startswith("success_") and k != "success_demo_starts"]
    return {k: float(np.mean([r[k] for r in rounds if k in r])) for k in keys}
