"""The planner's cost: how far a rolled-out trajectory is from standing still upright over its feet.

Every term is read from the planning model's sensors and joint coordinates at the end of each control
period of a rollout (`frbench.planning.model`), weighted by `CostWeights` and averaged over the horizon.
``up`` ∈ [0, 1] is how far the root has risen (0 below half its standing height, 1 at 90 %): the terms
that only make sense on the feet (balance, body contact, CoM velocity, posture) are scaled by it, so that
a robot on the ground is pulled up first and steadied once up.

Terms (per control step; K samples, C steps):

* height: (h* − h)₊/h* of the root and the upper body, h* their standing heights above the ground;
* upright: 1 − (z axis)_z of the root and the upper body (0 upright, 2 upside down);
* balance: |CoM_xy − mean(feet_xy)|² [m²] · up;
* body contact: number of non-foot links touching anything · up;
* CoM velocity: |v_CoM|² [m²/s²] · up;
* posture: mean over joints of (q − q̊)² [rad²] · up;
* effort: mean over joints of (Kp (q* − q) / τ_max)² (the PD torque that the target asks for);
* joint limits: sum over joints of (q past the limits shrunk by `LIMIT_MARGIN`)² [rad²];
* displacement: (distance of the root from the episode's start − `FREE_DISPLACEMENT`)₊² [m²].

A diverged rollout (non-finite values) costs `DIVERGED_COST`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from frbench.planning.config import CostWeights
from frbench.planning.model import PlanningModel
from frbench.robots.spec import RobotSpec

#: Fraction of each joint's range kept free at either end before the joint-limit term counts [-].
LIMIT_MARGIN = 0.02
#: Horizontal distance [m] from the episode's start that the displacement term leaves free (the protocol
#: fails a recovery more than 1 m away).
FREE_DISPLACEMENT = 0.3
#: The cost of a rollout that diverged.
DIVERGED_COST = 1e9


@dataclass(frozen=True)
class StandingReference:
    """Heights [m] above the ground of the root and the upper body when standing at the default pose."""

    root: float
    upper: float


def standing_reference(spec: RobotSpec, planning: PlanningModel) -> StandingReference:
    """The root's and the upper body's standing heights [m]: the root's is the spec's nominal height, the upper
    body's follows from forward kinematics of the default pose with the root upright at that height."""
    data = mujoco.MjData(planning.model)
    data.qpos[0:4] = [0.0, 0.0, spec.nominal_height, 1.0]
    data.qpos[planning.qadr] = spec.default_pose
    mujoco.mj_forward(planning.model, data)
    return StandingReference(root=float(spec.nominal_height),
                             upper=float(data.sensordata[planning.sensors.upper_pos][2]))


class Cost:
    """The cost of K rollouts (module docstring).

    Args:
        spec: the robot (default pose, gains, torque and joint limits).
        planning: the planning model (sensor layout).
        weights: the cost weights.
    """

    def __init__(self, spec: RobotSpec, planning: PlanningModel, weights: CostWeights):
        self.weights = weights
        self.layout = planning.sensors
        self.reference = standing_reference(spec, planning)
        self.default_pose = np.asarray(spec.default_pose, dtype=float)
        self.kp = np.asarray(spec.kp, dtype=float)
        self.torque_limits = np.asarray(spec.torque_limits, dtype=float)
        lower, upper = np.asarray(spec.joint_lower, float), np.asarray(spec.joint_upper, float)
        margin = LIMIT_MARGIN * (upper - lower)
        self.lower, self.upper = lower + margin, upper - margin

    def terms(self, sensordata: np.ndarray, q: np.ndarray, targets: np.ndarray, ground: float,
              anchor: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Each weighted term per sample and step, (K, C).

        Args:
            sensordata: (K, C, nsensordata) at the end of each control period.
            q: (K, C, n_joints) joint positions [rad] there.
            targets: (K, C, n_joints) the joint targets q* [rad] held during each period.
            ground: terrain height [m] under the robot.
            anchor: (2,) where the episode started, world xy [m] (the displacement term; None: no term).
        """
        w, s, ref = self.weights, self.layout, self.reference
        h_root = sensordata[..., s.root_pos][..., 2] - ground
        h_upper = sensordata[..., s.upper_pos][..., 2] - ground
        up = np.clip((h_root / ref.root - 0.5) / 0.4, 0.0, 1.0)
        deficit = np.maximum(ref.root - h_root, 0.0) / ref.root + np.maximum(ref.upper - h_upper, 0.0) / ref.upper
        tilt = (1.0 - sensordata[..., s.root_z][..., 2]) + (1.0 - sensordata[..., s.upper_z][..., 2])
        feet = sensordata[..., s.feet].reshape(*sensordata.shape[:-1], s.n_feet, 3)
        offset = sensordata[..., s.com][..., :2] - feet[..., :2].mean(axis=-2)
        contact = (sensordata[..., s.body_contact] > 0).sum(axis=-1)
        speed = (sensordata[..., s.com_vel] ** 2).sum(axis=-1)
        posture = ((q - self.default_pose) ** 2).mean(axis=-1)
        effort = ((np.clip(self.kp * (targets - q), -self.torque_limits, self.torque_limits) / self.torque_limits) ** 2).mean(axis=-1)
        limits = (np.maximum(q - self.upper, 0.0) ** 2 + np.maximum(self.lower - q, 0.0) ** 2).sum(axis=-1)
        drift = np.zeros_like(h_root)
        if anchor is not None:
            away = np.linalg.norm(sensordata[..., s.root_pos][..., :2] - anchor, axis=-1)
            drift = np.maximum(away - FREE_DISPLACEMENT, 0.0) ** 2
        return {
            "height": w.height * deficit,
            "upright": w.upright * tilt,
            "balance": w.balance * up * (offset ** 2).sum(axis=-1),
            "body_contact": w.body_contact * up * contact,
            "com_velocity": w.com_velocity * up * speed,
            "posture": w.posture * up * posture,
            "effort": w.effort * effort,
            "joint_limits": w.joint_limits * limits,
            "displacement": w.displacement * drift,
        }

    def __call__(self, sensordata: np.ndarray, q: np.ndarray, targets: np.ndarray, ground: float,
                 anchor: np.ndarray | None = None) -> np.ndarray:
        """Total cost per sample (K,): the terms summed, averaged over the C steps (see `terms`)."""
        total = sum(self.terms(sensordata, q, targets, ground, anchor).values()).mean(axis=-1)
        finite = np.isfinite(sensordata).all(axis=(1, 2)) & np.isfinite(q).all(axis=(1, 2))
        return np.where(finite & np.isfinite(total), total, DIVERGED_COST)
