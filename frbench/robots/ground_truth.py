"""Mass and centre-of-mass ground truth, computed with Pinocchio from the simulation URDF.

These are the labels of FR-Net's mass head and the critic's ``m_t`` and
``p_com``. No other frbench code computes them; the backends only *report*
what their simulators hold, and ``frbench robot check`` compares the two.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec


@dataclass(frozen=True)
class PinocchioRobot:
    """A robot loaded in Pinocchio with the free-flyer root.

    Attributes:
        model: ``pinocchio.Model`` (nq = 7 + n_joints).
        q_index: per canonical joint, its index in Pinocchio's configuration.
        group_joints: per mass group, the Pinocchio joint ids whose bodies it sums.
    """

    model: object
    q_index: np.ndarray
    group_joints: tuple[tuple[int, ...], ...]


@lru_cache(maxsize=64)
def load(spec: RobotSpec) -> PinocchioRobot:
    """Load ``spec``'s simulation URDF in Pinocchio (cached per spec)."""
    import pinocchio

    path = sim_robot_file(spec).path
    try:
        model = pinocchio.buildModelFromUrdf(str(path), pinocchio.JointModelFreeFlyer())
    except ValueError as exc:
        raise RobotFileError(f"{spec.urdf_path}: Pinocchio cannot load its simulation URDF {path} ({exc})") from None
    q_index = np.array([model.joints[model.getJointId(name)].idx_q for name in spec.joint_names])
    group_joints = []
    for group in spec.mass_groups:
        ids = sorted({model.frames[model.getFrameId(link)].parentJoint for link in group.links})
        group_joints.append(tuple(ids))
    return PinocchioRobot(model=model, q_index=q_index, group_joints=tuple(group_joints))


def configuration(robot: PinocchioRobot, base_pos, base_quat_wxyz, q) -> np.ndarray:
    """Pinocchio configuration (nq,) from a base pose and canonical joint angles [rad]."""
    config = np.zeros(robot.model.nq)
    config[:3] = base_pos
    w, x, y, z = np.asarray(base_quat_wxyz, dtype=float) / np.linalg.norm(base_quat_wxyz)
    config[3:7] = (x, y, z, w)  # Pinocchio stores xyzw
    config[robot.q_index] = q
    return config


def total_mass(spec: RobotSpec) -> float:
    """Total mass [kg]."""
    import pinocchio

    return float(pinocchio.computeTotalMass(load(spec).model))


def group_masses(spec: RobotSpec) -> np.ndarray:
    """Mass [kg] of each of ``spec.mass_groups``, shape (n_groups,).

    A group's mass is the sum of the rigid bodies its links belong to, feet and
    other fixed links included (Go2: base 7.277, hip 4×0.767, thigh 4×1.241,
    calf 4×0.194 kg).
    """
    robot = load(spec)
    return np.array([sum(robot.model.inertias[j].mass for j in ids) for ids in robot.group_joints])


def center_of_mass(spec: RobotSpec, base_pos, base_quat_wxyz, q) -> np.ndarray:
    """Whole-body CoM [m] in the world frame, shape (3,), for one configuration.

    Args:
        base_pos: root link frame position (3,) [m].
        base_quat_wxyz: root orientation (4,), w first.
        q: canonical joint angles (n_joints,) [rad].
    """
    import pinocchio

    robot = load(spec)
    data = robot.model.createData()
    return np.array(pinocchio.centerOfMass(robot.model, data, configuration(robot, base_pos, base_quat_wxyz, q)))
