"""Stable-Baselines3 models (a ``model.save`` zip) trained on ``frbench/FallRecovery-v1``.

The model sees what the gymnasium environment (`frbench.gym`) gives it: the
frame [ω, g, q − q̊, q̇, q*_{t−1} − q̊] (the previous *target* as applied),
clipped to the environment's `observation_bounds`, float32; its action a in
[−1, 1] gives q* = q̊ + ``ACTION_SCALE`` · a, as in the environment. ``--spec``
replaces that layout (then the frame is the layout's, unclipped by the bounds).
The model's policy is rebuilt from the zip and acts deterministically
(``policy.predict(obs, deterministic=True)``); stable-baselines3 is an optional
extra (``pip install 'frbench[sb3]'``). Observation normalisation kept outside
the model (a ``VecNormalize`` file) is not read.
"""

from __future__ import annotations

import inspect
import zipfile
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.contract import Contract, ObservationTerm, PolicyLayout, read_layout
from frbench.policies.layout_policy import LayoutPolicy, safe_name
from frbench.tasks.actions import ACTION_SCALE
from frbench.tasks.observations import observation_bounds


def is_sb3_zip(path: Path) -> bool:
    """Whether ``path`` is a Stable-Baselines3 ``model.save`` archive (members ``data`` and ``policy.pth``)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return {"data", "policy.pth"} <= set(archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def gym_layout() -> PolicyLayout:
    """The layout of ``frbench/FallRecovery-v1``'s observations and actions."""
    terms = tuple(ObservationTerm(name) for name in
                  ("base_angvel", "projected_gravity", "joint_pos", "joint_vel", "previous_target"))
    return PolicyLayout(observation=terms, action_scale=ACTION_SCALE, action_clip=1.0)


class Sb3Policy(LayoutPolicy):
    """A Stable-Baselines3 policy network driven through the gymnasium environment's layout."""

    def __init__(self, path: Path, layout: PolicyLayout, policy, gym_bounds: bool):
        super().__init__(safe_name(path.stem), path, layout)
        self.policy, self.gym_bounds = policy, gym_bounds

    def check(self, contract: Contract) -> None:
        """The model's observation and action spaces against the layout."""
        self._contract = contract
        n = contract.n_joints
        obs_shape, act_shape = self.policy.observation_space.shape, self.policy.action_space.shape
        if obs_shape != (contract.layout.frame_size(n),) or self.policy.observation_space.dtype != np.float32:
            raise PolicyError(f"{self.who}: the model's observation space is {obs_shape} "
                              f"{self.policy.observation_space.dtype}, expected ({contract.layout.frame_size(n)},) "
                              f"float32 {self.expected()}")
        if act_shape != (n,):
            raise PolicyError(f"{self.who}: the model's action space is {act_shape}, expected ({n},) for robot "
                              f"{contract.robot!r} {self.expected()}")
        super().check(contract)

    def reset(self, spec, num_envs: int) -> None:
        """New episodes; the environment's observation bounds of ``spec``."""
        if self.gym_bounds:
            self.bounds = observation_bounds(spec)
        super().reset(spec, num_envs)

    def frame(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The layout's frame, clipped to the environment's bounds as the environment does."""
        frame = super().frame(obs)
        if not self.gym_bounds:
            return frame
        return np.clip(np.nan_to_num(frame, nan=0.0, posinf=0.0, neginf=0.0), *self.bounds)

    def forward(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """Deterministic actions of the policy network."""
        (obs,) = inputs.values()
        actions, _ = self.policy.predict(obs, deterministic=True)
        return actions


def load_sb3_policy(path: Path, layout_file: str | None = None) -> Sb3Policy:
    """The Stable-Baselines3 model at ``path`` (see the module docstring)."""
    try:
        from stable_baselines3.common.save_util import load_from_zip_file
    except ImportError:
        raise PolicyError(f"{path}: a Stable-Baselines3 model, but stable-baselines3 is not installed: "
                          "pip install 'frbench[sb3]'") from None
    try:
        data, params, _ = load_from_zip_file(path, device="cpu")
        policy_class = data["policy_class"]
        kwargs = dict(data.get("policy_kwargs") or {})
        if "use_sde" in data and "use_sde" in inspect.signature(policy_class).parameters:
            kwargs["use_sde"] = data["use_sde"]
        policy = policy_class(data["observation_space"], data["action_space"], lambda _: 0.0, **kwargs)
        policy.load_state_dict(params["policy"])
    except Exception as exc:  # stable-baselines3 and torch raise many types for unreadable or foreign zips
        raise PolicyError(f"{path}: not a loadable Stable-Baselines3 model ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0][:200] if str(exc) else ''})") from None
    policy.set_training_mode(False)
    layout = read_layout(layout_file) if layout_file else gym_layout()
    return Sb3Policy(path, layout, policy, gym_bounds=not layout_file)
