"""The reward of one control step of the episode engine: the one place where reward inputs are assembled.

`StepReward` reads a `frbench.tasks.recovery.RecoveryTask` after its step (state, contacts, signals, the start
position) plus the actions the policy took, builds `rewards.RewardInputs` and sums the weighted terms of a
`rewards.RewardConfig` (`rewards.compute_rewards`). The training env (`frbench.training.env`) and the Gymnasium
envs (`frbench.gym`, ``reward="training"``) both call it, so a policy trained on either sees the same reward:
the same table, the same velocity-limit threshold read from the URDF (`reward_tables.with_joint_velocity_limits`:
0.8 × each joint's limit, 24.1 / 12.6 rad/s on Go2), the same standing heights and head point.

`HeadPoints` is the humanoid's head: a point `HEAD_OFFSET_M` above the torso link's origin along its z axis, by
forward kinematics along the simulation URDF's chain from the root link to the torso (joint origins and axes),
vectorised over the environments. Everything here runs on numpy arrays or torch tensors on a device
(`frbench.arrays`), whichever the engine's state holds.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from frbench.arrays import is_host, namespace, resident
from frbench.backends.base import RobotState
from frbench.robots.kinematics import chain_to_link
from frbench.robots.spec import RobotSpec
from frbench.training.reward_tables import with_joint_velocity_limits
from frbench.training.rewards import RewardConfig, RewardInputs, compute_rewards, term_arguments

#: The humanoid's "head": a point this far [m] above the torso link's origin along its z axis (the G1's head
#: centre stands about 1.23 m above flat ground in the default pose).
HEAD_FRAME, HEAD_OFFSET_M = "torso_link", 0.40
#: Joint-name fragments of a humanoid's legs; every other joint belongs to the upper body (waist, arms).
LEG_JOINT_WORDS = ("hip", "knee", "ankle")
_EYE = np.eye(3)


def upper_body_joints(spec: RobotSpec) -> np.ndarray:
    """(J,) bool: the joints of the waist and arms (every joint whose name names no leg part)."""
    return np.array([not any(w in name for w in LEG_JOINT_WORDS) for name in spec.joint_names])


def quaternion_matrices(quat):
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) wxyz (numpy or torch)."""
    xp = namespace(quat)
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    rows = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return xp.stack([xp.stack(row, axis=-1) for row in rows], axis=-2)


def chain_arrays(spec: RobotSpec, link: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joints from ``spec``'s root link to ``link`` in its simulation URDF (`chain_to_link`): origins
    (L, 4, 4), unit axes (L, 3) and canonical joint indices (L,) (−1 for a fixed joint)."""
    chain, index = chain_to_link(spec, link)
    axes = np.array([np.asarray(j.axis, dtype=float) / np.linalg.norm(j.axis) for j in chain]).reshape(-1, 3)
    return (np.array([j.origin for j in chain], dtype=float).reshape(-1, 4, 4), axes,
            np.array(index, dtype=np.int64))


class HeadPoints:
    """World head positions of N environments, each simulating ``specs[assignment[i]]``: the chain from the root
    link to `HEAD_FRAME` (`chain_arrays`) of every robot, evaluated for all environments at once.

    Attributes: ``origins`` (K, L, 4, 4), ``axes`` (K, L, 3), ``joints`` (L,) (the chain of each of the K robots,
    one shape), ``assignment`` (N,), ``standing_height`` [m] (the head of the first robot standing in its default
    pose on flat ground at z = 0)."""

    def __init__(self, specs: Sequence[RobotSpec], assignment: np.ndarray):
        chains = [chain_arrays(s, HEAD_FRAME) for s in specs]
        self._hold(np.stack([c[0] for c in chains]), np.stack([c[1] for c in chains]), chains[0][2], assignment)
        standing = RobotState.standing(specs[0], 1, clearance=0.0)
        self.standing_height = float(self.positions(standing, np.zeros(1, dtype=np.int64))[0, 2])

    @classmethod
    def from_arrays(cls, origins, axes, joints, assignment, standing_height: float) -> "HeadPoints":
        """The head points of arrays `to_arrays` gave (a bundle's), without the robot files."""
        head = cls.__new__(cls)
        head._hold(np.asarray(origins, dtype=float), np.asarray(axes, dtype=float), np.asarray(joints), assignment)
        head.standing_height = float(standing_height)
        return head

    def _hold(self, origins, axes, joints, assignment) -> None:
        self.origins, self.axes, self.joints = origins, axes, np.asarray(joints, dtype=np.int64)
        self.assignment = np.asarray(assignment, dtype=np.int64)
        # the cross-product matrix K of each axis and K², for Rodrigues' R(θ) = I + sin θ K + (1 − cos θ) K²
        x, y, z = axes[..., 0], axes[..., 1], axes[..., 2]
        zero = np.zeros_like(x)
        self._cross = np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                                np.stack([-y, x, zero], -1)], -2)
        self._cross2 = self._cross @ self._cross
        self._per_env = tuple(a[self.assignment] for a in (self.origins, self._cross, self._cross2))

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The arrays `from_arrays` reads back (``assignment`` and ``standing_height`` aside)."""
        return {"origins": self.origins, "axes": self.axes, "joints": self.joints}

    def positions(self, state: RobotState, robots=None):
        """World head positions (M, 3) [m] of ``state`` (M rows, numpy or torch), row m simulating robot
        ``robots[m]`` (an index into the specs; default: each environment's, ``assignment``)."""
        ref = state.base_pos
        xp = namespace(ref)
        if robots is None:
            origins, cross, cross2 = (a if is_host(ref) else resident(a, ref) for a in self._per_env)
        else:  # numpy, a few rows (the standing height)
            origins, cross, cross2 = (a[np.asarray(robots)] for a in (self.origins, self._cross, self._cross2))
        rotation, position = quaternion_matrices(state.base_quat), state.base_pos
        eye = resident(_EYE, ref)
        for link, joint in enumerate(self.joints.tolist()):
            position = position + (rotation @ origins[:, link, :3, 3:4])[..., 0]
            rotation = rotation @ origins[:, link, :3, :3]
            if joint >= 0:
                angle = state.q[:, joint][:, None, None]
                rotation = rotation @ (eye + xp.sin(angle) * cross[:, link] + (1 - xp.cos(angle)) * cross2[:, link])
        return position + rotation[:, :, 2] * HEAD_OFFSET_M


class StepReward:
    """The weighted reward terms of one control step (see the module docstring).

    Args:
        config: the reward table; its velocity-limit threshold, if left at the paper's literal 0.8 rad/s, is
            read from ``spec``'s URDF.
        spec: the robot (joint order, URDF velocity limits); the standing posture q̊ and the joint limits are the
            task's (each environment's robot's).
        nominal_height: standing base height [m], scalar or (N,).
        ground_height: terrain height [m] (N,) under world points (N, 2) of each environment.
        head: the humanoid's head points (None for robots without a head; unused when the table has no
            ``head_height`` term).
    """

    def __init__(self, config: RewardConfig, spec: RobotSpec, nominal_height, ground_height: Callable,
                 head: HeadPoints | None = None):
        self.config = with_joint_velocity_limits(config, spec.urdf_path, spec.joint_names)
        self.nominal_height = nominal_height
        self.upper_body = upper_body_joints(spec)
        self.ground_height = ground_height
        #: The head points, kept only when the table has a head term.
        self.head = head if "head_height" in self.config.weights else None
        self._arguments: dict = {}  # the terms' arguments per device (`term_arguments`)

    def __call__(self, task, action, action_prev, action_prev2, qd_prev):
        """(reward (N,), weighted terms name → (N,), alive (N,) bool) after ``task``'s step; actions a_t, a_{t−1},
        a_{t−2} (N, J) in policy units; ``qd_prev`` the joint velocities before the step [rad/s]. A diverged
        environment's reward is 0 (its terms are left as computed). numpy or torch, as the engine's state."""
        s, c = task.state, task.contacts
        host = is_host(s.q)

        def own(value, dtype=None):  # a host constant in the state's namespace and device (converted once)
            return value if host or isinstance(value, (int, float)) else resident(value, s.q, dtype)

        inputs = RewardInputs(
            projected_gravity=task.gravity, q=s.q, qd=s.qd, qd_prev=qd_prev, tau=s.tau, action=action,
            action_prev=action_prev, q_stand=own(task.default_pose), q_lower=own(task.lower),
            q_upper=own(task.upper), foot_contact=c.foot_contact, body_contact=task.signals.body_contact,
            knee_force_xy=c.knee_force_xy, base_xy=s.base_pos[:, :2], init_xy=task.start_xy,
            base_height=task.signals.height, nominal_height=own(self.nominal_height), action_prev2=action_prev2,
            upper_body=own(self.upper_body, None if host else namespace(s.q).bool),
        )
        if self.head is not None:
            head = self.head.positions(s)
            inputs.head_height = head[:, 2] - self.ground_height(head[:, :2])
            inputs.nominal_head_height = self.head.standing_height
        alive = task.alive
        if host:
            reward, terms = compute_rewards(inputs, self.config)
            if not (alive.all() and np.isfinite(reward).all()):  # else the reward stays as it is
                reward = np.where(alive, np.nan_to_num(reward), 0.0)
            return reward, terms, alive
        key = str(s.q.device), s.q.dtype  # the thresholds as arrays on the device, made once
        if key not in self._arguments:
            self._arguments[key] = term_arguments(self.config, inputs)
        reward, terms = compute_rewards(inputs, self.config, self._arguments[key])
        return namespace(reward).where(alive, reward.nan_to_num(), 0.0), terms, alive
