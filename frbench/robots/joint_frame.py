"""The canonical joint frame of a quadruped: one convention for every body's leg angles.

Robot files disagree on joint directions and zeros. Unitree's files (and the
five training robots, A1, B1, Laikago) turn +thigh and +calf backwards with
legs hanging straight down at zero; Solo12, Mini Cheetah and ANYmal turn them
the other way; Spirit40 and Vision60 fold their legs at zero angles. The
*canonical* frame is the Unitree convention with legs that hang straight down
at zero:

* +hip moves the foot towards +y (a rotation about the body's +x);
* the thigh angle is the direction of the hip-to-knee segment from straight
  down, the calf angle that of the knee-to-foot segment relative to the thigh,
  both about +y (positive swings the segment backwards, towards -x), so a
  standing calf angle is negative (the knee bent backwards).

`joint_frame` reads it from the robot's kinematics (the simulation URDF): per
joint a sign s = ±1 and an offset o [rad] with ``canonical = s·q + o``, and
per leg the knee direction. A robot whose four standing knees all point
forward (Solo12, ANYmal B and C as frbench stands them) is *turned*: seen from
behind, rotated 180° about its vertical axis, it is a robot whose knees point
backwards, so the canonical frame takes that view: its front legs are the
robot's hind legs (FL ↔ RR, FR ↔ RL), hip, thigh and calf turn the other way,
and the body-frame x and y of the angular velocity and of gravity change sign.
A robot with forward knees on some legs only has those legs mirrored front to
back instead (thigh and calf flipped, no swap), which is also how `scripted`
maps every forward knee (``turn=False``).

A humanoid has no canonical frame: its legs are hip-pitch/roll/yaw, knee and
ankle chains (and its arms are not legs), which the hip-thigh-calf convention
does not describe, so humanoid policies read and write joints in the robot's
own convention (`HUMANOID_REASON`).

Policies use the frame through `JointFrame.observation`, `JointFrame.to_joints`
and `JointFrame.canonical_spec` (`frbench.evaluation.episodes.run_episodes`, the
training core env): the `scripted` controller, learned policies and layouts that
declare ``joint_frame: canonical`` never see a robot's own convention. A training
batch of robots of several conventions (wide bodies) maps each environment
through its robot's frame (`frbench.robots.batch_frame`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from frbench.arrays import is_host, namespace, resident
from frbench.errors import FrbenchError
from frbench.robots.kinematics import link_poses
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import QUADRUPED_LEGS, RobotSpec
from frbench.robots.urdf_tree import parse_urdf

#: Joint-zero offsets [rad] below this count as zero (a leg that hangs straight down at zero angles).
OFFSET_TOLERANCE = 1e-6
#: A hip axis must lie within this cosine of the body's x axis, thigh and calf axes of its y axis.
AXIS_ALIGNMENT = 0.9
#: Why a humanoid has no canonical frame (``frbench spec`` prints it).
HUMANOID_REASON = ("a humanoid's legs are hip pitch/roll/yaw-knee-ankle chains, which the canonical "
                   "hip-thigh-calf leg convention does not describe: humanoid policies use the robot's own joint frame")
#: Factors of a body-frame vector (x, y, z) of a turned robot in the canonical body frame: x and y negated.
TURNED_BODY_FLIP = (-1.0, -1.0, 1.0)
#: The values of a policy's ``joint_frame``: ``robot`` (the robot file's own convention) or ``canonical``.
JOINT_FRAMES = ("robot", "canonical")


class JointFrameError(FrbenchError):
    """The robot has no canonical joint frame (not a quadruped, or a leg that is not hip-thigh-calf)."""


def _sagittal_angle(v: np.ndarray) -> float:
    """Angle [rad] of ``v`` from straight down in the body's x-z plane, positive towards -x (backwards)."""
    return float(np.arctan2(-v[0], -v[2]))


def _wrap(angle: float) -> float:
    """``angle`` [rad] wrapped into [-π, π)."""
    return float((angle + np.pi) % (2.0 * np.pi) - np.pi)


class CanonicalMaps:
    """The maths of a canonical joint frame, ``canonical = sign · q[order] + offset``, one implementation for one
    robot (`JointFrame`: sign, offset and order of shape (J,), broadcast over any leading axes) and for a batch of
    robots (`frbench.robots.batch_frame.BatchJointFrame`: (N, J), environment i through its robot's row), on numpy
    arrays or torch tensors. A frame sets its host rows once (`_set_rows`); a torch input reads them as
    device-resident copies (`frbench.arrays.resident`)."""

    is_identity = False

    def _set_rows(self, sign, offset, order, flip) -> None:
        """The frame's host rows: ``sign`` and ``offset`` (..., J), ``order`` (..., J) (None: the joints keep
        their order) and ``flip`` (..., 3), the body-vector factors (None: no body vector changes)."""
        object.__setattr__(self, "_rows", (np.asarray(sign, dtype=float), np.asarray(offset, dtype=float),
                                           None if order is None else np.asarray(order, dtype=np.int64),
                                           None if flip is None else np.asarray(flip, dtype=float)))

    def _row(self, k: int, like):
        """Row ``k`` of (sign, offset, order, flip) in ``like``'s namespace, device and dtype (the order int64)."""
        value = self._rows[k]
        if value is None or is_host(like):
            return value
        return resident(value, like, namespace(like).int64 if k == 2 else None)

    def _reorder(self, values):
        """(..., J) values in the other joint order (robot ↔ canonical: each row's order is its own inverse)."""
        order = self._row(2, values)
        if order is None:
            return values
        if is_host(values):
            values = np.asarray(values)
            return np.take_along_axis(values, np.broadcast_to(order, values.shape), axis=-1)
        return values.gather(-1, order.expand(values.shape))

    def to_canonical(self, q):
        """Robot joint angles [rad] (..., J) as canonical leg angles (numpy or torch)."""
        return self._row(0, q) * self._reorder(q) + self._row(1, q)

    def to_joints(self, canonical):
        """Canonical leg angles [rad] (..., J) as the robot's joint angles (inverse of `to_canonical`)."""
        return self._reorder(self._row(0, canonical) * (canonical - self._row(1, canonical)))

    def velocities(self, qd):
        """Joint velocities [rad/s] (..., J), robot → canonical: sign · q̇ in canonical order."""
        return self._row(0, qd) * self._reorder(qd)

    def body_vectors(self, v):
        """Body-frame vectors (..., 3) (angular velocity, gravity direction) in the canonical body frame: x and y
        negated for a turned robot, unchanged otherwise."""
        flip = self._row(3, v)
        return v if flip is None else v * flip

    def observation(self, obs: dict) -> dict:
        """The proprioception dict (`frbench.tasks.observations`) in the canonical frame (`canonical_observation`);
        the identity frame returns ``obs`` itself."""
        return obs if self.is_identity else canonical_observation(self, obs)

    def targets(self, canonical):
        """Joint targets from a policy in the canonical frame, (N, J) [rad] (numpy, as float64, or torch on its
        device), as the robot's targets; the identity frame returns them unchanged."""
        if self.is_identity:
            return canonical
        return self.to_joints(np.asarray(canonical, dtype=np.float64) if is_host(canonical) else canonical)


@dataclass(frozen=True)
class JointFrame(CanonicalMaps):
    """A robot's map onto canonical leg angles: ``canonical = sign · q + offset`` per joint.

    Attributes:
        robot: the robot's name.
        sign: ±1 per joint (n_joints,), canonical joint order.
        offset: [rad] per joint (n_joints,); zero where the leg hangs straight down at zero.
        knees: per leg of the robot (FL, FR, RL, RR), ``"backward"`` or ``"forward"``: where its standing knee points.
        turned: the robot is seen from behind (its four knees point forward; module docstring): canonical joint j
            is the robot's joint ``order[j]``.
    """

    robot: str
    sign: tuple[float, ...]
    offset: tuple[float, ...]
    knees: tuple[str, ...]
    turned: bool = False

    def __post_init__(self) -> None:
        self._set_rows(self.sign, self.offset, self.order if self.turned else None,
                       TURNED_BODY_FLIP if self.turned else None)

    @property
    def order(self) -> tuple[int, ...]:
        """The robot's joint index of each canonical joint (n_joints,): FL ↔ RR and FR ↔ RL for a turned robot."""
        n = len(self.sign)
        return tuple((n - 3 - j + 2 * (j % 3)) if self.turned else j for j in range(n))

    @property
    def is_identity(self) -> bool:
        """True when the robot's convention already is the canonical one (every sign +1, every offset 0)."""
        return not self.turned and all(s == 1.0 for s in self.sign) and not any(self.offset)

    def canonical_spec(self, spec: RobotSpec) -> RobotSpec:
        """``spec`` as a canonical-frame policy sees it: default pose and joint limits in canonical leg angles
        (a limit pair whose sign flips swaps ends), joint names, gains and torque limits in canonical joint order;
        everything else unchanged. The identity frame returns ``spec``."""
        if self.is_identity:
            return spec
        lower = self.to_canonical(np.asarray(spec.joint_lower, dtype=float))
        upper = self.to_canonical(np.asarray(spec.joint_upper, dtype=float))
        order = list(self.order)
        reordered = {name: tuple(getattr(spec, name)[k] for k in order) for name in
                     ("joint_names", "kp", "kd", "torque_limits")}
        return dataclasses.replace(
            spec, default_pose=tuple(float(v) for v in self.to_canonical(np.asarray(spec.default_pose, dtype=float))),
            joint_lower=tuple(float(v) for v in np.minimum(lower, upper)),
            joint_upper=tuple(float(v) for v in np.maximum(lower, upper)), **reordered)

    def to_dict(self) -> dict:
        """JSON form (``frbench spec --json``)."""
        return {"convention": "canonical[j] = sign[j] * q[order[j]] + offset[j]", "sign": list(self.sign),
                "offset": list(self.offset), "order": list(self.order), "turned": self.turned,
                "knees": dict(zip(QUADRUPED_LEGS, self.knees))}


def canonical_observation(frame, obs: dict) -> dict:
    """The proprioception dict ``obs`` through ``frame`` (a `JointFrame`, or a batch's
    `frbench.robots.batch_frame.BatchJointFrame`): ``joint_pos`` and ``previous_action`` through its
    ``to_canonical``, ``joint_vel`` through ``velocities``, ``base_angvel`` and ``projected_gravity`` through
    ``body_vectors``; other entries as they are (a new dict)."""
    mapped = dict(obs)
    for key in ("joint_pos", "previous_action"):
        if key in obs:
            mapped[key] = frame.to_canonical(obs[key])
    if "joint_vel" in obs:
        mapped["joint_vel"] = frame.velocities(obs["joint_vel"])
    for key in ("base_angvel", "projected_gravity"):
        if key in obs:
            mapped[key] = frame.body_vectors(obs[key])
    return mapped


def _leg_axis_signs(tree, zero, spec: RobotSpec, joints: tuple[int, int, int]) -> list[float]:
    """±1 per joint of one leg: the direction of the hip axis along the body's x, of the thigh and calf axes
    along its y, at the zero pose; `JointFrameError` when an axis is not along them (not a hip-thigh-calf leg)."""
    signs = []
    for j, component in zip(joints, (0, 1, 1)):
        joint = tree.joints[spec.joint_names[j]]
        axis = zero[joint.parent][:3, :3] @ joint.origin[:3, :3] @ (joint.axis / np.linalg.norm(joint.axis))
        if abs(axis[component]) < AXIS_ALIGNMENT:
            role = ("hip", "thigh", "calf")[joints.index(j)]
            raise JointFrameError(
                f"robot {spec.name!r}: joint {spec.joint_names[j]!r} ({role}) turns about "
                f"({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f}) in the body frame, expected the body's "
                f"{'x' if component == 0 else 'y'} axis: its legs are not hip-thigh-calf, so it has no canonical joint frame")
        signs.append(1.0 if axis[component] >= 0 else -1.0)
    return signs


def joint_frame(spec: RobotSpec, turn: bool = True) -> JointFrame:
    """The canonical joint frame of quadruped ``spec`` (module docstring).

    Axis directions are read from the simulation URDF; the offsets are the segment directions at the default
    pose (hips at zero) minus the joint angles there, so a file whose zero pose is not a straight leg (Spirit
    and Vision60 fold their legs at zero, Laikago's toe files bend them) maps onto the same canonical angles
    as one whose zero pose is. Offsets below `OFFSET_TOLERANCE` are zero. ``turn``: a robot whose four knees
    point forward is turned around (module docstring); False mirrors each such leg instead (`scripted`).

    Raises:
        JointFrameError: ``spec`` is not a 12-joint quadruped (`HUMANOID_REASON` for a humanoid), or a leg's
            joints do not turn about the body's x (hip), y (thigh) and y (calf) axes.
    """
    if spec.kind == "humanoid":
        raise JointFrameError(f"robot {spec.name!r}: no canonical joint frame: {HUMANOID_REASON}")
    if spec.kind != "quadruped" or spec.n_joints != 3 * len(QUADRUPED_LEGS):
        raise JointFrameError(f"robot {spec.name!r} ({spec.kind}, {spec.n_joints} joints): a canonical joint frame "
                              f"needs a quadruped of 4 hip-thigh-calf legs (12 joints)")
    tree = parse_urdf(sim_robot_file(spec).path)
    default = np.asarray(spec.default_pose, dtype=float)
    zero = link_poses(tree, {})
    hips_zero = dict(zip(spec.joint_names, default))
    hips_zero.update({spec.joint_names[3 * k]: 0.0 for k in range(len(QUADRUPED_LEGS))})
    standing = link_poses(tree, hips_zero)
    sign, offset, knees = np.ones(spec.n_joints), np.zeros(spec.n_joints), []
    for k in range(len(QUADRUPED_LEGS)):
        hip, thigh, calf = 3 * k, 3 * k + 1, 3 * k + 2
        axes = _leg_axis_signs(tree, zero, spec, (hip, thigh, calf))
        thigh_joint, calf_joint = tree.joints[spec.joint_names[thigh]], tree.joints[spec.joint_names[calf]]
        pivot = (standing[thigh_joint.parent] @ thigh_joint.origin)[:3, 3]
        knee = (standing[calf_joint.parent] @ calf_joint.origin)[:3, 3]
        foot = standing[spec.foot_links[k]][:3, 3]
        thigh_angle = _sagittal_angle(knee - pivot)
        calf_angle = _wrap(_sagittal_angle(foot - knee) - thigh_angle)
        offsets = (thigh_angle - axes[1] * default[thigh], calf_angle - axes[2] * default[calf])
        offsets = tuple(0.0 if abs(o) < OFFSET_TOLERANCE else o for o in offsets)
        mirror = 1.0 if calf_angle <= 0 else -1.0
        knees.append("backward" if mirror > 0 else "forward")
        sign[hip], sign[thigh], sign[calf] = axes[0], axes[1] * mirror, axes[2] * mirror
        offset[thigh], offset[calf] = mirror * offsets[0], mirror * offsets[1]
    turned = turn and all(k == "forward" for k in knees)
    if turned:  # seen from behind: canonical leg k is robot leg 3 - k, every axis turned (mirror and hips)
        legs = np.reshape(sign, (4, 3))[::-1] * np.array([-1.0, 1.0, 1.0])
        sign, offset = legs.reshape(-1), np.reshape(offset, (4, 3))[::-1].reshape(-1)
    return JointFrame(spec.name, tuple(float(s) for s in sign), tuple(float(o) + 0.0 for o in offset),  # no -0.0
                      tuple(knees), turned)


def learner_joint_frame(kind: str, residual: bool) -> str:
    """The joint frame frbench's trainers give a policy: ``canonical`` for a quadruped's plain policy, ``robot``
    for a residual one (its base controller maps the robot's joints itself) or a humanoid's (no canonical frame)."""
    return "canonical" if kind == "quadruped" and not residual else "robot"
