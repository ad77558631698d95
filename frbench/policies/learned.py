"""Policies trained by ``frbench train``, loaded from their ``policy.pt`` checkpoint.

The checkpoint holds the actor's weights (normalisers and estimator included)
and the training configs; this wrapper rebuilds the rsl-rl actor, keeps each
environment's observation history and previous action, and turns actions into
joint targets q* = q̊ + action_scale · a for the robot being evaluated.

frbench's trainers observe and act in the canonical joint frame (`frbench.robots.joint_frame`), and a checkpoint
records it (``joint_frame``). A quadruped checkpoint without that field is read as ``canonical`` too: every
training robot's frame is the identity, so those policies were canonical-frame policies all along (their
standard-grid episodes are bit-identical either way, ``tests/test_learned_joint_frame.py``). A residual policy
keeps the robot's frame (its base controller maps the robot's joints itself), and so does a humanoid policy
(humanoids have no canonical frame).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.registry import load_base_controller
from frbench.robots.spec import RobotSpec
from frbench.tasks.observations import flatten

#: The observation groups a deployed policy gets: o_t (6 + 3J), its history (H frames) and its long
#: history (T frames, RMA's adaptation module).
DEPLOYABLE_GROUPS = {"policy", "history", "long_history"}


def deployable_group_widths(num_actions: int, frames: int, long_frames: int = 0) -> dict[str, int]:
    """Widths of the deployable groups for a robot with ``num_actions`` joints (see frbench.training.env)."""
    frame = 6 + 3 * num_actions
    widths = {"policy": frame, "history": frames * frame}
    if long_frames:
        widths["long_history"] = long_frames * frame
    return widths


#: Where the actors lived before :mod:`frbench.networks`; run configs of that time name it in ``class_name``.
FORMER_ACTOR_MODULE, ACTOR_MODULE = "frbench.training.models:", "frbench.networks.models:"


def current_class_path(class_name: str) -> str:
    """``class_name`` ("module:Class") with a former actor module replaced by :mod:`frbench.networks.models`."""
    if class_name.startswith(FORMER_ACTOR_MODULE):
        return ACTOR_MODULE + class_name[len(FORMER_ACTOR_MODULE):]
    return class_name


def policy_name(method: str, checkpoint: Path) -> str:
    """A results-safe name: the run folder or file stem when it starts with the method (``ppo-3m``), else the
    method then the stem (``frnet-myrun``)."""
    stem = checkpoint.parent.name if checkpoint.name == "policy.pt" else checkpoint.stem
    name = stem if stem.startswith(method) else f"{method}-{stem}"
    return re.sub(r"[^A-Za-z0-9._-]", "-", name)[:64]


def residual_targets(base: np.ndarray, action: np.ndarray, scale: float, controller, gated: bool,
                     phases: tuple[str, ...] | None = None) -> np.ndarray:
    """Joint targets (N, J) [rad] of a residual policy: base + scale·a, or base + gate·scale·a with the base
    controller's ``residual_gate(phases)`` (N,) when ``gated`` (None: its default phases) — the one rule
    training and deployment share."""
    if not gated:
        return base + scale * action
    gate = controller.residual_gate() if phases is None else controller.residual_gate(tuple(phases))
    return base + gate[:, None] * scale * action


def portable_actions(actions: np.ndarray) -> np.ndarray:
    """Actions (N, J) computed in float64, rounded to float32 and returned as float64 (protocol 1.2).

    A float32 forward pass depends on the processor: torch picks its ATen kernels by the CPU's vector
    extensions (``ATEN_CPU_CAPABILITY``: default / AVX2 / AVX-512) and MKL or oneDNN block their sums by
    the same, so the last bits of an action differ between machines, and over a chaotic 5 s episode a
    last-bit difference can flip its outcome (docs/protocol.md, "Protocol 1.2"). In float64 the kernels
    still differ, but only around 1e-16 relative; rounding to float32 (about 6e-8) maps both to the same
    value unless the exact result lies within that distance of a float32 rounding boundary (about one
    action in 10^8-10^9). The network's weights are float32 numbers, so float64 loses nothing of them."""
    return np.asarray(actions, dtype=np.float64).astype(np.float32).astype(np.float64)


def checkpoint_joint_frame(data: dict, robot_kind: str, residual: bool, path) -> str:
    """The joint frame a checkpoint's policy reads and writes joints in (module docstring): its recorded
    ``joint_frame``, else ``canonical`` for a quadruped's plain policy and ``robot`` for a residual or a humanoid's."""
    from frbench.robots.joint_frame import JOINT_FRAMES, learner_joint_frame

    frame = data.get("joint_frame", learner_joint_frame(robot_kind, residual))
    if frame not in JOINT_FRAMES:
        raise PolicyError(f"{path}: joint_frame {frame!r}, expected one of {', '.join(JOINT_FRAMES)}")
    return frame


class LearnedPolicy:
    """A trained recovery policy (proprioception only), optionally a residual over a base controller."""

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
        actor_cfg = dict(train_cfg["actor"])
        # RMA after its phase 2 acts on ẑ = φ(long history) and never reads its extrinsics group: zeros go there
        ignored = {"extrinsics"} if actor_cfg.get("use_adaptation") else set()
        missing = set(self.groups) - DEPLOYABLE_GROUPS - ignored
        if missing:
            raise PolicyError(
                f"{path}: a {self.method!r} policy needs {', '.join(sorted(missing))} at deployment, which a benchmark "
                "policy does not get (proprioception only); train its adaptation phase first"
            )
        self.action_scale = float(data["action_scale"])
        self.frames = int(data["history"])
        self.num_actions = int(data.get("num_actions", 12))
        self.robot_kind = str(data.get("robot_kind", "quadruped"))
        self.base_controller_name = config["env"].get("base_controller")
        self.residual_gate = bool(config["env"].get("residual_gate", False))
        self.gate_phases = config["env"].get("gate_phases")  # None (runs before it existed): the default rise
        self.action_hold = int(config["env"].get("action_hold", 1))  # control steps per decision
        self.long_frames = int(config["env"].get("long_history", 0)) if "long_history" in self.groups else 0
        actor_class = resolve_callable(current_class_path(actor_cfg.pop("class_name")))
        widths = deployable_group_widths(self.num_actions, self.frames, self.long_frames)
        # the extrinsics' width: the input width of RMA's extrinsics encoder (its first linear layer), weights (H, E)
        extrinsics = data["actor_state_dict"].get("encoder.0.weight")
        self.ignored_widths = {g: int(extrinsics.shape[-1]) if extrinsics is not None else 11 for g in ignored}
        widths.update(self.ignored_widths)
        dummy = TensorDict({g: torch.zeros(1, w) for g, w in widths.items()}, batch_size=[1])
        self.actor = actor_class(dummy, {"actor": self.groups}, "actor", self.num_actions, **actor_cfg)
        try:
            self.actor.load_state_dict(data["actor_state_dict"])
        except RuntimeError as exc:
            raise PolicyError(f"{path}: checkpoint weights do not fit the {self.method!r} actor ({str(exc)[:200]})") from None
        self.actor.eval()
        self.actor.double()  # portable inference (protocol 1.2): see `portable_actions`
        self._torch, self._TensorDict = torch, TensorDict

        self.joint_frame = checkpoint_joint_frame(data, self.robot_kind, bool(self.base_controller_name), path)
        self.base_controller = None
        if self.base_controller_name:
            self.base_controller = load_base_controller(self.base_controller_name,
                                                        config["env"].get("base_controller_parameters"))

    def supports(self, spec: RobotSpec) -> bool:
        """Robots of the training robots' kind and joint count (and its base controller's, if residual)."""
        from frbench.policies.base import policy_joint_frame

        fits = spec.kind == self.robot_kind and spec.n_joints == self.num_actions
        if fits and self.base_controller is None:
            policy_joint_frame(self, spec)  # a one-line PolicyError for a robot without a canonical frame
        return fits and (self.base_controller is None or self.base_controller.supports(spec))

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """New episodes: empty history, zero previous action."""
        self.default_pose = np.asarray(spec.default_pose)
        self.action = np.zeros((num_envs, spec.n_joints))
        self.history = None
        self.long_history = None
        self.calls = 0  # `act` calls this episode: the policy decides on every ``action_hold``-th
        if self.base_controller is not None:
            self.base_controller.reset(spec, num_envs)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, J) [rad] from the proprioception dict: q̊ (or the base controller's targets,
        for a residual policy) + action_scale · a, with a new action a every ``action_hold`` calls (training's)."""
        if self.calls % self.action_hold == 0:
            self._decide(obs)
        self.calls += 1
        if self.base_controller is None:
            return self.default_pose + self.action_scale * self.action
        base = np.asarray(self.base_controller.act(obs))
        return residual_targets(base, self.action, self.action_scale, self.base_controller, self.residual_gate,
                                self.gate_phases)

    def _decide(self, obs: dict[str, np.ndarray]) -> None:
        """The next action a (N, J) from the observation and its histories (updated once per decision)."""
        o_t = flatten(obs, self.default_pose)
        o_t[:, -self.action.shape[1]:] = self.action
        if self.history is None:  # a new episode: the histories start filled with its first frame
            self.history = np.repeat(o_t[:, None, :], self.frames, axis=1)
            self.long_history = np.repeat(o_t[:, None, :], self.long_frames, axis=1)
        else:
            self.history = np.concatenate([self.history[:, 1:], o_t[:, None, :]], axis=1)
            self.long_history = np.concatenate([self.long_history[:, 1:], o_t[:, None, :]], axis=1)
        torch, n = self._torch, len(o_t)
        groups = {"policy": o_t, "history": self.history.reshape(n, -1), "long_history": self.long_history.reshape(n, -1)}
        groups.update({g: np.zeros((n, w)) for g, w in self.ignored_widths.items()})
        td = self._TensorDict({g: torch.as_tensor(groups[g], dtype=torch.float64) for g in self.groups},
                              batch_size=[n])
        with torch.inference_mode():
            action = portable_actions(self.actor(td).numpy())
        self.action = np.clip(action, -10.0, 10.0)


def load_learned_policy(data: dict, path: Path) -> LearnedPolicy:
    """Checkpoint loader registered for every training method."""
    return LearnedPolicy(data, path)
