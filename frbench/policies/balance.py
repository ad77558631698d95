"""Where the whole-body centre of mass is over the feet, from proprioception only (Pinocchio).

A standing robot balances by keeping its centre of mass (CoM) over its feet. `ComOverFeet` estimates the
CoM's horizontal offset ahead of the feet from what a real robot measures: the projected gravity g (the
IMU's pelvis roll and pitch; yaw does not matter) and the joint angles. It places the pelvis at the origin
with zero yaw and the measured roll and pitch, runs Pinocchio's kinematics on the simulation URDF and
returns ``CoM_x − mean(foot_x)``, forward along the pelvis heading, in metres. The feet need not touch the
ground for the number to be defined; it means "over the feet" only while they stand flat.
"""

from __future__ import annotations

import numpy as np

from frbench.robots import ground_truth
from frbench.robots.spec import RobotSpec


def roll_pitch_quaternion(gravity: np.ndarray) -> np.ndarray:
    """Base orientations (N, 4) wxyz with zero yaw whose body frame sees the unit gravity ``gravity`` (N, 3).

    Pitch θ = asin(g_x) (nose down positive), roll φ = atan2(−g_y, −g_z); the rotation is Rz(0) Ry(θ) Rx(φ).
    """
    g = np.asarray(gravity, dtype=float)
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    pitch = np.arcsin(np.clip(g[:, 0], -1.0, 1.0))
    roll = np.arctan2(-g[:, 1], -g[:, 2])
    cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    return np.stack([cp * cr, cp * sr, sp * cr, -sp * sr], axis=1)


class ComOverFeet:
    """Forward offset [m] of the CoM from the midpoint of ``spec.foot_links`` (see the module docstring)."""

    def __init__(self, spec: RobotSpec):
        import pinocchio

        self.robot = ground_truth.load(spec)
        self.data = self.robot.model.createData()
        self.feet = [self.robot.model.getFrameId(link) for link in spec.foot_links]
        self._pin = pinocchio

    def offset(self, gravity: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(N,) CoM x minus the feet's mean x [m] in the yaw-free frame of the pelvis, from the projected
        gravity (N, 3) and the joint angles (N, J) [rad] in canonical order."""
        pin, model, data = self._pin, self.robot.model, self.data
        quats = roll_pitch_quaternion(gravity)
        q = np.asarray(q, dtype=float)
        out = np.empty(len(q))
        for i in range(len(q)):
            config = ground_truth.configuration(self.robot, np.zeros(3), quats[i], q[i])
            com = pin.centerOfMass(model, data, config)
            pin.updateFramePlacements(model, data)
            feet_x = np.mean([data.oMf[f].translation[0] for f in self.feet])
            out[i] = com[0] - feet_x
        return out
