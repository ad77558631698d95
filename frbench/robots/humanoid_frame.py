"""The G1 joint frame of a humanoid: the G1's joint names and conventions, read off any humanoid's kinematics.

frbench's humanoid controllers (``scripted-humanoid``, ``keyframe-humanoid``) are written in the Unitree G1's
joint names and sign conventions (`frbench.policies.scripted_humanoid.G1_JOINTS`). `humanoid_frame` maps another
humanoid's joints onto those names, per joint, as the quadruped canonical frame does
(`frbench.robots.joint_frame`): ``g1_angle = sign · q[index] + offset``.

Which joint is which is read from the robot's kinematic tree at its zero pose (the simulation URDF), not from
its names:

* a **leg** is the chain of moving joints from the pelvis (the last link both feet hang from) to a foot of
  ``spec.foot_links``; its side is the sign of the foot's y. Its joints are told apart by the direction of their
  axis in the root frame (pitch: mostly y, roll: mostly x, yaw: mostly z): the pitch joints in chain order are
  ``hip_pitch``, ``knee``, ``ankle_pitch``; the first roll joint is ``hip_roll``, the last ``ankle_roll``; the
  first yaw joint ``hip_yaw``;
* an **arm** ends at the leaf link farthest out on its side (|y|) that is neither a leg nor on the midline;
  the *torso* is the last link both arms hang from. The arm's ``elbow`` is its first pitch joint at least
  `SEGMENT_MIN` from the arm's first joint; before it, the pitch joint is ``shoulder_pitch``, the roll joint
  ``shoulder_roll`` and the last yaw joint ``shoulder_yaw`` (the twist about the upper arm); wrists are mapped
  only by name (a G1 file's; the controllers hold them at the default pose);
* the **waist** joints lie between the pelvis and the torso: ``waist_yaw``, ``waist_roll``, ``waist_pitch`` by
  their axes.

The sign of a mapped joint is that of its axis along the G1's axis of the same joint (both in the root frame at
the zero pose). The offset makes the limb's geometry agree, for the joints whose zero differs between files:
``hip_pitch`` and ``shoulder_pitch`` (the thigh's or upper arm's direction from straight down), ``knee`` and
``elbow`` (the lower segment's direction from the upper one's; the G1's elbow is a right angle at zero, iCub's
and Talos' are straight). Every other mapped joint has offset 0: feet flat, torso upright and roll and yaw
joints neutral at zero, as in the three humanoids frbench ships. Offsets below `OFFSET_TOLERANCE` (the
rounding of the files' link origins) are zero.

A role a robot lacks (Talos' shoulder has no pitch axis at its zero pose, its waist no roll joint) is not
mapped: the controller's target for it is dropped, and the robot's joint that no role names holds its default
angle. For the G1 itself the frame is the identity (every index its own, signs +1, offsets 0), so a controller
driving the G1 through it moves exactly as without it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from frbench.errors import FrbenchError
from frbench.robots.builtin import G1_JOINTS  # the frame's canonical joints: the G1's, in its order
from frbench.robots.kinematics import link_poses
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import parse_urdf

SIDES = ("left", "right")
#: The G1's waist joints without the ``_joint`` suffix.
WAIST_ROLES = ("waist_yaw", "waist_roll", "waist_pitch")
#: The robot whose joints are the frame's canonical joints.
REFERENCE_ROBOT = "g1"
#: Shortest distance [m] between two joints for the link between them to count as a limb segment.
SEGMENT_MIN = 0.05
#: Offsets [rad] below this are zero (iCub's straight legs are 3e-6 rad off in its file).
OFFSET_TOLERANCE = 1e-4
#: The joints a humanoid controller cannot do without: both legs' sagittal chain.
REQUIRED_ROLES = tuple(f"{s}_{j}_joint" for s in SIDES for j in ("hip_pitch", "knee", "ankle_pitch"))
#: Axis classes by the root-frame component an axis mostly lies along.
_AXIS_CLASSES = ("roll", "pitch", "yaw")


class HumanoidFrameError(FrbenchError):
    """The robot's legs do not map onto the G1's (`REQUIRED_ROLES`), or it is not a humanoid."""


@dataclass(frozen=True)
class HumanoidFrame:
    """A humanoid's map onto the G1's joints: ``g1[j] = sign[j] · q[index[j]] + offset[j]``.

    Attributes:
        robot: the robot's name.
        index: (29,) the robot's joint index of each G1 joint (`G1_JOINTS` order), -1 where it has none.
        sign: (29,) ±1 (1 where unmapped).
        offset: (29,) [rad] (0 where unmapped).
    """

    robot: str
    index: tuple[int, ...]
    sign: tuple[float, ...]
    offset: tuple[float, ...]

    @property
    def mapped(self) -> np.ndarray:
        """(29,) bool: the G1 joints the robot has."""
        return np.asarray(self.index) >= 0

    @property
    def unmapped(self) -> tuple[str, ...]:
        """The G1 joints the robot has no counterpart for."""
        return tuple(name for name, i in zip(G1_JOINTS, self.index) if i < 0)

    @property
    def is_identity(self) -> bool:
        """True when the robot's joints are the G1's, in order, signs +1 and offsets 0 (the G1 itself)."""
        return (self.index == tuple(range(len(G1_JOINTS))) and all(s == 1.0 for s in self.sign)
                and not any(self.offset))

    def to_g1(self, q: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """Robot joint angles (..., n_joints) [rad] as G1 joint angles (..., 29); joints the robot lacks take
        ``fill`` (29,) [rad]."""
        q = np.asarray(q, dtype=float)
        if self.is_identity:
            return q.copy()
        mapped, index = self.mapped, np.asarray(self.index)
        out = np.broadcast_to(np.asarray(fill, dtype=float), (*q.shape[:-1], len(G1_JOINTS))).copy()
        out[..., mapped] = np.asarray(self.sign)[mapped] * q[..., index[mapped]] + np.asarray(self.offset)[mapped]
        return out

    def to_joints(self, g1: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """G1 joint angles (..., 29) [rad] as the robot's (..., n_joints); robot joints no G1 joint names take
        ``fill`` (n_joints,) [rad] (its default pose)."""
        g1 = np.asarray(g1, dtype=float)
        if self.is_identity:
            return g1.copy()
        mapped, index = self.mapped, np.asarray(self.index)
        fill = np.asarray(fill, dtype=float)
        out = np.broadcast_to(fill, (*g1.shape[:-1], len(fill))).copy()
        out[..., index[mapped]] = np.asarray(self.sign)[mapped] * (g1[..., mapped] - np.asarray(self.offset)[mapped])
        return out

    def g1_limits(self, spec: RobotSpec, reference: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (29,) [rad]: ``spec``'s joint limits in G1 angles (a pair whose sign flips swaps ends);
        the ``reference`` G1's own where the robot has no such joint."""
        lo = self.to_g1(np.asarray(spec.joint_lower, dtype=float), np.asarray(reference.joint_lower, dtype=float))
        hi = self.to_g1(np.asarray(spec.joint_upper, dtype=float), np.asarray(reference.joint_upper, dtype=float))
        return np.minimum(lo, hi), np.maximum(lo, hi)

    def to_dict(self, spec: RobotSpec) -> dict:
        """JSON form (``frbench spec --json``): per G1 joint, the robot joint, sign and offset, or null."""
        return {"convention": "g1[j] = sign[j] * q[index[j]] + offset[j]", "reference": REFERENCE_ROBOT,
                "joints": {name: ({"joint": spec.joint_names[i], "sign": s, "offset": round(o, 6)} if i >= 0 else None)
                           for name, i, s, o in zip(G1_JOINTS, self.index, self.sign, self.offset)}}


@dataclass(frozen=True)
class _Kinematics:
    """A robot's zero pose as the frame derivation reads it: per moving joint (by name) its axis (3,) and
    position (3,) in the root frame, and the moving joints from the root to each link, in chain order."""

    axis: dict
    position: dict
    chain: dict  # link -> tuple of moving joint names from the root down to it
    leaves: tuple[str, ...]
    link_position: dict


def _kinematics(spec: RobotSpec) -> _Kinematics:
    tree = parse_urdf(sim_robot_file(spec).path)
    zero = link_poses(tree, {})
    actuated = set(spec.joint_names)
    axis, position, chain = {}, {}, {tree.root: ()}
    pending = [tree.root]
    while pending:
        link = pending.pop()
        for joint in tree.child_joints(link):
            frame = zero[joint.parent] @ joint.origin
            moving = joint.name in actuated
            if moving:
                axis[joint.name] = frame[:3, :3] @ (joint.axis / np.linalg.norm(joint.axis))
                position[joint.name] = frame[:3, 3]
            chain[joint.child] = chain[link] + ((joint.name,) if moving else ())
            pending.append(joint.child)
    leaves = tuple(link for link in tree.links if not tree.child_joints(link))
    return _Kinematics(axis, position, chain, leaves, {link: zero[link][:3, 3] for link in tree.links})


def _axis_class(axis: np.ndarray) -> str:
    return _AXIS_CLASSES[int(np.argmax(np.abs(axis)))]


def _common_prefix(a: tuple, b: tuple) -> tuple:
    n = 0
    while n < min(len(a), len(b)) and a[n] == b[n]:
        n += 1
    return a[:n]


def _segment_angle(parent: np.ndarray, child: np.ndarray, axis: np.ndarray) -> float:
    """Signed angle [rad] about ``axis`` from ``parent`` to ``child`` (both projected onto the plane normal to it)."""
    return float(np.arctan2(np.dot(np.cross(parent, child), axis), np.dot(parent, child)))


def _assign(spec: RobotSpec) -> tuple[dict[str, str], dict[str, float], dict[str, np.ndarray]]:
    """The robot's joint for each G1 joint it has (by structure, module docstring; a G1 joint left over maps onto
    the robot's joint of the same name, if any: a G1 file's wrists), each such joint's zero-pose angle θ0 [rad]
    about its own axis (0 for the joints with no offset), and every moving joint's root-frame axis (3,)."""
    kin = _kinematics(spec)
    down = np.array([0.0, 0.0, -1.0])
    roles: dict[str, str] = {}
    theta0: dict[str, float] = {}
    feet = list(spec.foot_links)
    if len(feet) != 2:
        raise HumanoidFrameError(f"robot {spec.name!r}: {len(feet)} feet, a humanoid frame needs two legs")
    pelvis_chain = _common_prefix(kin.chain[feet[0]], kin.chain[feet[1]])
    leg_joints = set()
    for foot in feet:
        side = "left" if kin.link_position[foot][1] > 0 else "right"
        joints = kin.chain[foot][len(pelvis_chain):]
        leg_joints.update(joints)
        by_class = {c: [j for j in joints if _axis_class(kin.axis[j]) == c] for c in _AXIS_CLASSES}
        for role, j in zip(("hip_pitch", "knee", "ankle_pitch"), by_class["pitch"]):
            roles[f"{side}_{role}_joint"] = j
        if by_class["roll"]:
            roles[f"{side}_hip_roll_joint"] = by_class["roll"][0]
        if len(by_class["roll"]) > 1:
            roles[f"{side}_ankle_roll_joint"] = by_class["roll"][-1]
        if by_class["yaw"]:
            roles[f"{side}_hip_yaw_joint"] = by_class["yaw"][0]
        hip, knee, ankle = (roles.get(f"{side}_{r}_joint") for r in ("hip_pitch", "knee", "ankle_pitch"))
        if hip and knee and ankle:
            thigh, shank = kin.position[knee] - kin.position[hip], kin.position[ankle] - kin.position[knee]
            theta0[hip] = _segment_angle(down, thigh, kin.axis[hip])
            theta0[knee] = _segment_angle(thigh, shank, kin.axis[knee])
    arms = {}
    for leaf in kin.leaves:
        joints = kin.chain[leaf]
        y = kin.link_position[leaf][1]
        if leaf in feet or set(joints) & leg_joints or abs(y) < SEGMENT_MIN:
            continue
        side = "left" if y > 0 else "right"
        if side not in arms or abs(y) > abs(kin.link_position[arms[side]][1]):
            arms[side] = leaf
    if set(arms) == set(SIDES):
        torso_chain = _common_prefix(kin.chain[arms["left"]], kin.chain[arms["right"]])
        for j in torso_chain[len(pelvis_chain):]:
            roles.setdefault(f"waist_{_axis_class(kin.axis[j])}_joint", j)
        for side, leaf in arms.items():
            joints = kin.chain[leaf][len(torso_chain):]
            if not joints:
                continue
            first = kin.position[joints[0]]
            elbow = next((j for j in joints if _axis_class(kin.axis[j]) == "pitch"
                          and np.linalg.norm(kin.position[j] - first) >= SEGMENT_MIN), None)
            if elbow is None:
                continue
            shoulder = joints[:joints.index(elbow)]
            by_class = {c: [j for j in shoulder if _axis_class(kin.axis[j]) == c] for c in _AXIS_CLASSES}
            if by_class["pitch"]:
                roles[f"{side}_shoulder_pitch_joint"] = by_class["pitch"][0]
            if by_class["roll"]:
                roles[f"{side}_shoulder_roll_joint"] = by_class["roll"][0]
            if by_class["yaw"]:
                roles[f"{side}_shoulder_yaw_joint"] = by_class["yaw"][-1]
            roles[f"{side}_elbow_joint"] = elbow
            upper = kin.position[elbow] - first
            beyond = joints[joints.index(elbow) + 1:]
            hand = (max((kin.position[j] for j in beyond), key=lambda p: np.linalg.norm(p - kin.position[elbow]))
                    if beyond else kin.link_position[leaf])
            theta0[elbow] = _segment_angle(upper, hand - kin.position[elbow], kin.axis[elbow])
            pitch = roles.get(f"{side}_shoulder_pitch_joint")
            if pitch:
                theta0[pitch] = _segment_angle(down, upper, kin.axis[pitch])
    taken = set(roles.values())
    for name in G1_JOINTS:
        if name not in roles and name in kin.axis and name not in taken:
            roles[name] = name
    return roles, {j: theta0.get(j, 0.0) for j in roles.values()}, kin.axis


@functools.lru_cache(maxsize=None)
def _reference() -> tuple[RobotSpec, dict, dict, dict]:
    from frbench.robots.registry import get_robot

    reference = get_robot(REFERENCE_ROBOT)
    return (reference, *_assign(reference))


def reference_spec() -> RobotSpec:
    """The G1 (`REFERENCE_ROBOT`) whose joints are the frame's canonical joints."""
    return _reference()[0]


@functools.lru_cache(maxsize=None)
def humanoid_frame(spec: RobotSpec) -> HumanoidFrame:
    """The G1 joint frame of humanoid ``spec`` (module docstring).

    Raises:
        HumanoidFrameError: ``spec`` is not a humanoid, or a leg's hip pitch, knee or ankle pitch is not found.
    """
    if spec.kind != "humanoid":
        raise HumanoidFrameError(f"robot {spec.name!r} is a {spec.kind}: the G1 joint frame maps humanoids")
    _, ref_roles, ref_theta, ref_axis = _reference()
    roles, theta, axis = _assign(spec)
    missing = [r for r in REQUIRED_ROLES if r not in roles]
    if missing:
        raise HumanoidFrameError(f"robot {spec.name!r}: no joint found for {', '.join(missing)} (a humanoid frame "
                                 f"needs each leg's hip pitch, knee and ankle pitch)")
    position = {name: i for i, name in enumerate(spec.joint_names)}
    index, sign, offset = [], [], []
    for name in G1_JOINTS:
        joint = roles.get(name)
        if joint is None or name not in ref_roles:
            index.append(-1), sign.append(1.0), offset.append(0.0)
            continue
        g1_joint = ref_roles[name]
        s = 1.0 if float(np.dot(axis[joint], ref_axis[g1_joint])) >= 0 else -1.0
        o = s * theta[joint] - ref_theta[g1_joint]
        index.append(position[joint])
        sign.append(s)
        offset.append(0.0 if abs(o) < OFFSET_TOLERANCE else o)
    return HumanoidFrame(spec.name, tuple(index), tuple(sign), tuple(offset))
