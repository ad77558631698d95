"""The reward of one control step of the episode engine: the one place where reward inputs are assembled.

`StepReward` reads a `frbench.tasks.recovery.RecoveryTask` after its step (state, contacts, signals, the start
position) plus the actions the policy took, builds `rewards.RewardInputs` and sums the weighted terms of a
`rewards.RewardConfig` (`rewards.compute_rewards`). The training env (`frbench.training.env`) and the Gymnasium
envs (`frbench.gym`, ``reward="training"``) both call it, so a policy trained on either sees the same reward:
the same table, the same velocity-limit threshold read from the URDF (`reward_tables.with_joint_velocity_limits`:
0.8 × each joint's limit, 24.1 / 12.6 rad/s on Go2), the same standing heights and head point.

`HeadPoints` is the humanoid's head: a point `HEAD_OFFSET_M` above the torso link's origin along its z axis, by
Pinocchio forward kinematics of each environment's robot.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from frbench.backends.base import RobotState
from frbench.robots import ground_truth
from frbench.robots.spec import RobotSpec
from frbench.training.reward_tables import with_joint_velocity_limits
from frbench.training.rewards import RewardConfig, RewardInputs, compute_rewards

#: The humanoid's "head": a point this far [m] above the torso link's origin along its z axis (the G1's head
#: centre stands about 1.23 m above flat ground in the default pose).
HEAD_FRAME, HEAD_OFFSET_M = "torso_link", 0.40
#: Joint-name fragments of a humanoid's legs; every other joint belongs to the upper body (waist, arms).
LEG_JOINT_WORDS = ("hip", "knee", "ankle")


def upper_body_joints(spec: RobotSpec) -> np.ndarray:
    """(J,) bool: the joints of the waist and arms (every joint whose name names no leg part)."""
    return np.array([not any(w in name for w in LEG_JOINT_WORDS) for name in spec.joint_names])


class HeadPoints:
    """World head positions of N environments, each simulating ``specs[assignment[i]]`` (Pinocchio models,
    loaded once per robot)."""

    def __init__(self, specs: Sequence[RobotSpec], assignment: np.ndarray):
        self.assignment = np.asarray(assignment)
        self._pin = [ground_truth.load(s) for s in specs]
        self._pin_data = [p.model.createData() for p in self._pin]
        spec = specs[0]
        standing = RobotState.standing(spec, 1, clearance=0.0)
        #: The head's height [m] of the first robot standing in its default pose on flat ground at z = 0.
        self.standing_height = float(self.positions(standing, [0])[0, 2])

    def positions(self, state: RobotState, rows=None) -> np.ndarray:
        """World head positions (M, 3) [m] of the environments ``rows`` (default all; ``state`` has M rows)."""
        import pinocchio

        rows = range(len(self.assignment)) if rows is None else rows
        out = np.zeros((len(state.base_pos), 3))
        for m, i in enumerate(rows):
            robot = self._pin[self.assignment[i]]
            data = self._pin_data[self.assignment[i]]
            config = ground_truth.configuration(robot, state.base_pos[m], state.base_quat[m], state.q[m])
            pinocchio.framesForwardKinematics(robot.model, data, config)
            frame = data.oMf[robot.model.getFrameId(HEAD_FRAME)]
            out[m] = frame.translation + frame.rotation[:, 2] * HEAD_OFFSET_M
        return out


class StepReward:
    """The weighted reward terms of one control step (see the module docstring).

    Args:
        config: the reward table; its velocity-limit threshold, if left at the paper's literal 0.8 rad/s, is
            read from ``spec``'s URDF.
        spec: the robot (joint order, limits, default pose = the standing posture q̊).
        nominal_height: standing base height [m], scalar or (N,).
        ground_height: terrain height [m] (N,) under world points (N, 2) of each environment.
        head: the humanoid's head points (None for robots without a head; unused when the table has no
            ``head_height`` term).
    """

    def __init__(self, config: RewardConfig, spec: RobotSpec, nominal_height, ground_height: Callable,
                 head: HeadPoints | None = None):
        self.config = with_joint_velocity_limits(config, spec.urdf_path, spec.joint_names)
        self.default_pose = np.asarray(spec.default_pose)
        self.nominal_height = nominal_height
        self.upper_body = upper_body_joints(spec)
        self.ground_height = ground_height
        #: The head points, kept only when the table has a head term (one Pinocchio pass per env and step).
        self.head = head if "head_height" in self.config.weights else None

    def __call__(self, task, action: np.ndarray, action_prev: np.ndarray, action_prev2: np.ndarray,
                 qd_prev: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """(reward (N,), weighted terms name → (N,), alive (N,) bool) after ``task``'s step; actions a_t, a_{t−1},
        a_{t−2} (N, J) in policy units; ``qd_prev`` the joint velocities before the step [rad/s]. A diverged
        environment's reward is 0 (its terms are left as computed)."""
        s, c = task.state, task.contacts
        inputs = RewardInputs(
            projected_gravity=task.gravity, q=s.q, qd=s.qd, qd_prev=qd_prev, tau=s.tau, action=action,
            action_prev=action_prev, q_stand=self.default_pose, q_lower=task.lower, q_upper=task.upper,
            foot_contact=c.foot_contact, body_contact=task.signals.body_contact, knee_force_xy=c.knee_force_xy,
            base_xy=s.base_pos[:, :2], init_xy=task.start_xy, base_height=task.signals.height,
            nominal_height=self.nominal_height, action_prev2=action_prev2, upper_body=self.upper_body,
        )
        if self.head is not None:
            head = self.head.positions(s)
            inputs.head_height = head[:, 2] - self.ground_height(head[:, :2])
            inputs.nominal_head_height = self.head.standing_height
        reward, terms = compute_rewards(inputs, self.config)
        alive = task.alive
        if not (alive.all() and np.isfinite(reward).all()):  # else the reward stays as it is
            reward = np.where(alive, np.nan_to_num(reward), 0.0)
        return reward, terms, alive
