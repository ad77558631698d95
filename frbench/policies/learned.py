"""Policies trained by ``frbench train``, loaded from their ``policy.pt`` checkpoint.

The checkpoint holds the actor's weights (normalisers and estimator included)
and the training configs; this wrapper rebuilds the rsl-rl actor, keeps each
environment's observation history and previous action, and turns actions into
joint targets q* = q̊ + action_scale · a for the robot being evaluated.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.robots.spec import RobotSpec
from frbench.tasks.observations import flatten

#: Widths of the observation groups the training env provides (see frbench.training.env).
GROUP_WIDTHS = {"policy": 42, "history": 5 * 42, "privileged": 277, "mass": 4, "contact": 13, "velocity": 3, "extrinsics": 11}
DEPLOYABLE_GROUPS = {"policy", "history"}


def policy_name(method: str, checkpoint: Path) -> str:
    """A results-safe name: the method, then the run folder or file stem when it differs (``frnet-myrun``)."""
    import re

    stem = checkpoint.parent.name if checkpoint.name == "policy.pt" else checkpoint.stem
    name = method if stem == method else f"{method}-{stem}"
    return re.sub(r"[^A-Za-z0-9._-]", "-", name)[:64]


class LearnedPolicy:
    """A trained quadruped recovery policy (proprioception only)."""

    def __init__(self, data: dict, path: Path):
        import torch
        from rsl_rl.utils import resolve_callable
        from tensordict import TensorDict

        self.checkpoint = Path(path)
        self.method = data["method"]
        self.name = policy_name(self.method, self.checkpoint)
        config = json.loads(data["config_json"])
        train_cfg = config["train_cfg"]
        self.groups = list(train_cfg["obs_groups"]["actor"])
        missing = set(self.groups) - DEPLOYABLE_GROUPS
        if missing:
            raise PolicyError(
                f"{path}: a {self.method!r} policy needs {', '.join(sorted(missing))} at deployment, which a benchmark "
                "policy does not get (proprioception only); train its adaptation phase first"
            )
        self.action_scale = float(data["action_scale"])
        self.frames = int(data["history"])
        actor_cfg = dict(train_cfg["actor"])
        actor_class = resolve_callable(actor_cfg.pop("class_name"))
        dummy = TensorDict({g: torch.zeros(1, w) for g, w in GROUP_WIDTHS.items()}, batch_size=[1])
        self.actor = actor_class(dummy, train_cfg["obs_groups"], "actor", 12, **actor_cfg)
        try:
            self.actor.load_state_dict(data["actor_state_dict"])
        except RuntimeError as exc:
            raise PolicyError(f"{path}: checkpoint weights do not fit the {self.method!r} actor ({str(exc)[:200]})") from None
        self.actor.eval()
        self._torch, self._TensorDict = torch, TensorDict

    def supports(self, spec: RobotSpec) -> bool:
        """Quadrupeds with 12 joints (the training robots' structure)."""
        return spec.kind == "quadruped" and spec.n_joints == 12

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """New episodes: empty history, zero previous action."""
        self.default_pose = np.asarray(spec.default_pose)
        self.action = np.zeros((num_envs, spec.n_joints))
        self.history = None

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, 12) [rad] from the proprioception dict."""
        o_t = flatten(obs, self.default_pose)
        o_t[:, -self.action.shape[1]:] = self.action
        if self.history is None:
            self.history = np.repeat(o_t[:, None, :], self.frames, axis=1)
        else:
            self.history = np.concatenate([self.history[:, 1:], o_t[:, None, :]], axis=1)
        torch = self._torch
        td = self._TensorDict(
            {"policy": torch.as_tensor(o_t, dtype=torch.float32),
             "history": torch.as_tensor(self.history.reshape(len(o_t), -1), dtype=torch.float32)},
            batch_size=[len(o_t)],
        )
        with torch.inference_mode():
            action = self.actor(td).numpy().astype(np.float64)
        self.action = np.clip(action, -10.0, 10.0)
        return self.default_pose + self.action_scale * self.action


def load_learned_policy(data: dict, path: Path) -> LearnedPolicy:
    """Checkpoint loader registered for every training method."""
    return LearnedPolicy(data, path)
