"""frbench's training reward tables: the paper's weights with the changes frbench's training needs, each with
its reason (`rewards.RewardConfig.overrides_reason`), per robot kind; and the velocity-limit threshold read
from a robot's URDF.

* `training_reward_config` — quadrupeds: the paper's table, motion penalties ×0.1, the height term, the knee
  force ×0.1 (reasons below);
* `humanoid_reward_config` — humanoids: the training table with HoST-style terms (head height, feet on
  ground, upper-body posture, action jerk) in place of the quadruped-only ones;
* `reward_table(kind)` — the table of a robot kind; `with_joint_velocity_limits` — legged_gym's reading of
  the velocity-limit term.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Mapping

from frbench.robots.urdf_tree import parse_urdf
from frbench.training.rewards import DEFAULT_VELOCITY_THRESHOLD, PAPER_WEIGHTS, RewardConfig

MOTION_PENALTY_REASON = (
    "x0.1: at the paper's weights the joint-velocity, -acceleration and torque penalties outweigh the upright "
    "reward about 10:1 at the start of training; with ~10M steps on 2 CPU cores the policy then learns to lie "
    "still instead of rolling over"
)


HEIGHT_REASON = (
    "added (not in the paper), weight 6: with the paper's table alone, 2 M steps of training rolled robots onto "
    "their bellies without ever rising (0 % success, target-posture reward 0); a term that pays for height, as in "
    "MuJoCo Playground's getup task, gives the rise a gradient. At weight 2 lying belly-down (upright term full) "
    "still earned about half of standing, and after 2.2 M steps policies let even standing starts collapse; at "
    "weight 6 standing pays about twice lying on the belly"
)

SAFETY_FORCE_REASON = (
    "x0.1: the knee force frbench measures is the net contact force on thigh and calf, which includes leg-on-leg "
    "self-contact while the legs are folded (55-120 N on each knee during a scripted roll of Go2); at the paper's "
    "weight it cost as much as the upright reward pays (-0.06 vs +0.09 per step at 2 M steps)"
)


#: Target-posture kernel width of frbench's training [rad²] (the paper: 1); see docs/training.md.
POSTURE_SIGMA2 = 3.0


#: The motion penalties `training_reward_config` scales (joint velocity, acceleration and torques).
MOTION_PENALTY_TERMS = ("joint_velocity", "joint_acceleration", "joint_torques")
#: Their scale relative to the paper's weights when a run starts (see `MOTION_PENALTY_REASON`).
MOTION_PENALTY_SCALE = 0.1


def training_reward_config() -> RewardConfig:
    """The paper's reward table, motion and knee-force penalties x0.1, plus a base-height term (reasons recorded
    in the config): the quadrupeds' training table."""
    config = RewardConfig()
    for term in MOTION_PENALTY_TERMS:
        config = config.with_weight(term, MOTION_PENALTY_SCALE * PAPER_WEIGHTS[term], MOTION_PENALTY_REASON)
    config = config.with_weight("safety_force", 0.1 * PAPER_WEIGHTS["safety_force"], SAFETY_FORCE_REASON)
    config = config.with_weight("base_height", 6.0, HEIGHT_REASON)
    return replace(config, posture_sigma2=POSTURE_SIGMA2)


HUMANOID_REASONS = {
    "feet_contact": "humanoids: replaced by feet_on_ground, which pays only once the base has risen (a G1 lying "
                    "with its soles on the floor would otherwise be paid for it)",
    "head_height": "humanoid term (HoST, HumanUP): pays for lifting the head, the signal of sitting and rising up",
    "feet_on_ground": "humanoid term: both feet under the robot once it has risen",
    "upper_body_posture": "humanoid term: waist and arms back to their standing pose once upright",
    "action_jerk": "humanoid term: HoST's smoothness (second difference of the actions)",
}


def humanoid_reward_config() -> RewardConfig:
    """frbench's quadruped training rewards plus the humanoid terms (each with its reason); see docs/training.md."""
    config = training_reward_config().without(("feet_contact",), HUMANOID_REASONS["feet_contact"])
    for term, weight in (("head_height", 2.0), ("feet_on_ground", 1.0), ("upper_body_posture", 1.0),
                         ("action_jerk", -0.01)):
        config = config.with_weight(term, weight, HUMANOID_REASONS[term])
    return config

#: The training table of each robot kind (`RobotSpec.kind`).
REWARD_TABLES: Mapping[str, Callable[[], RewardConfig]] = {
    "quadruped": training_reward_config,
    "humanoid": humanoid_reward_config,
}


def reward_table(kind: str) -> RewardConfig:
    """frbench's training reward table for a robot of ``kind`` (``"quadruped"`` or ``"humanoid"``)."""
    if kind not in REWARD_TABLES:
        raise ValueError(f"robot kind {kind!r}: no training reward table; known: {', '.join(REWARD_TABLES)}")
    return REWARD_TABLES[kind]()


def with_joint_velocity_limits(reward: RewardConfig, urdf_path, joint_names) -> RewardConfig:
    """``reward`` with the velocity-limit threshold read as legged_gym does: 0.8 × each joint's URDF velocity
    limit [rad/s] (30 where the URDF gives none); unchanged when the config sets its own threshold.

    The paper writes max(|q̇| − 0.8, 0); FR-Net builds on legged_gym, whose ``dof_vel_limits`` reward uses
    ``soft_dof_vel_limit = 0.8`` of the URDF limit. Read literally (0.8 rad/s) the term dominates every
    other reward.
    """
    if reward.velocity_threshold != DEFAULT_VELOCITY_THRESHOLD:
        return reward
    joints = parse_urdf(urdf_path).joints
    limits = [joints[name].velocity or 30.0 for name in joint_names]
    return replace(reward, velocity_threshold=tuple(0.8 * v for v in limits))
