"""The policy interface every recovery policy implements.

A policy gets the robot spec when a batch of episodes starts and then, every
control step, a dict of proprioceptive arrays (N rows; see
`frbench.tasks.observations`), and returns joint targets q* [rad] of shape
(N, n_joints) in the spec's canonical order. Policies that think in offsets
(the paper's q* = q̊ + a) add the default pose themselves.

A policy that reads and writes joints in the canonical joint frame (`frbench.robots.joint_frame`) declares
``joint_frame = "canonical"``; the episode runner then maps its input and output (`policy_joint_frame`). Without
the attribute a policy works in the robot's own convention (``"robot"``).

A policy that is not blind declares ``uses_simulator_state = True`` and an ``inputs`` string: the episode
runner (`frbench.evaluation.episodes.run_episodes`) then calls ``reset_episode(terrain, seed)`` after
``reset`` and ``observe_state(state)`` with the simulator's `RobotState` before each ``act``, and its
results carry ``policy.inputs`` (the ``mpc`` planner: ``simulator-state``), so that the leaderboard never
ranks it with blind policies.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from frbench.errors import PolicyError
from frbench.robots.spec import RobotSpec


class Policy(Protocol):
    """A recovery policy. ``checkpoint`` is the file it was loaded from (None if built in)."""

    name: str
    checkpoint: Path | None

    def supports(self, spec: RobotSpec) -> bool:
        """Whether the policy can drive ``spec``."""

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Start ``num_envs`` new episodes of ``spec``."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, n_joints) [rad] for the observation dict."""


def policy_joint_frame(policy: Policy, spec: RobotSpec, declared: str | None = None):
    """The `frbench.robots.joint_frame.JointFrame` that ``policy`` reads and writes ``spec``'s joints in, or None when it
    uses the robot's own convention (``joint_frame`` absent or ``"robot"``); ``declared`` overrides the policy's
    (a name, or a `JointFrame` itself, e.g. ``joint_frame(spec, turn=False)`` in a diagnosis).

    Raises:
        PolicyError: the policy declares ``"canonical"`` and ``spec`` has no canonical frame (a humanoid, a leg that is
            not hip-thigh-calf), or declares a value other than ``"robot"`` / ``"canonical"``.
    """
    from frbench.robots.joint_frame import JOINT_FRAMES, JointFrame, JointFrameError, joint_frame

    if isinstance(declared, JointFrame):
        return declared
    declared = getattr(policy, "joint_frame", "robot") if declared is None else declared
    if declared not in JOINT_FRAMES:
        raise PolicyError(f"policy {policy.name!r}: joint_frame {declared!r}, expected one of {', '.join(JOINT_FRAMES)}")
    if declared == "robot":
        return None
    try:
        return joint_frame(spec)
    except JointFrameError as exc:
        raise PolicyError(f"policy {policy.name!r} declares joint_frame 'canonical', but {exc}") from None


def checked_actions(policy: Policy, actions, num_envs: int, n_joints: int) -> np.ndarray:
    """``actions`` as float64 (N, n_joints), or a `PolicyError` naming the policy and the problem."""
    try:
        array = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise PolicyError(f"policy {policy.name!r} returned actions that are not numbers ({exc})") from None
    if array.shape != (num_envs, n_joints):
        raise PolicyError(
            f"policy {policy.name!r} returned actions of shape {array.shape}, expected ({num_envs}, {n_joints})"
        )
    bad = ~np.isfinite(array)
    if bad.any():
        env, joint = np.argwhere(bad)[0]
        kind = "NaN" if np.isnan(array[env, joint]) else "infinite"
        raise PolicyError(
            f"policy {policy.name!r} returned {kind} targets ({int(bad.sum())} values; first at environment {env}, joint {joint})"
        )
    return array
