"""`RobotSpec`: everything frbench needs to know about a robot, as frozen data.

A robot is a URDF file plus this small record. Every backend, the Pinocchio
ground truth and the tasks read the spec; none of them hard-code a robot.

Conventions
-----------
* Units are SI: metres, kilograms, radians, newton-metres, seconds.
* ``joint_names`` is the *canonical joint order*. Every array indexed by joint
  anywhere in frbench (targets, positions, gains, limits) follows it, whatever
  order the URDF file lists its joints in. Quadrupeds use legs FL, FR, RL, RR,
  each hip (abduction), thigh, calf.
* Link names refer to the links of the *simulation URDF* that
  :mod:`frbench.robots.sim_urdf` derives from ``urdf_path``: fixed joints are
  merged into their parent there, except the joints of ``foot_links``, which stay
  separate links so that foot contacts can be told from shin contacts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

RobotKind = Literal["quadruped", "humanoid"]

#: Names of FR-Net's four mass labels for a quadruped (paper, Sec. III-A).
QUADRUPED_MASS_GROUPS = ("base", "hip", "thigh", "calf")
#: Leg prefixes in canonical order.
QUADRUPED_LEGS = ("FL", "FR", "RL", "RR")


@dataclass(frozen=True)
class LinkGroup:
    """A named set of links, e.g. all four calves (a mass label) or FL's calf."""

    name: str
    links: tuple[str, ...]


@dataclass(frozen=True)
class RobotSpec:
    """A robot as frbench sees it. Arrays are tuples in canonical joint order.

    Attributes:
        name: registry name, lower case (``"go2"``).
        kind: ``"quadruped"`` or ``"humanoid"``.
        urdf_path: the source URDF file.
        joint_names: canonical order of the actuated joints, matched by name.
        default_pose: standing joint angles [rad], shape (n_joints,).
        kp: PD stiffness [N·m/rad], shape (n_joints,).
        kd: PD damping [N·m·s/rad], shape (n_joints,).
        torque_limits: symmetric effort limits [N·m], shape (n_joints,).
        joint_lower, joint_upper: position limits [rad], shape (n_joints,).
        foot_links: one link per foot (quadrupeds: FL, FR, RL, RR order).
        mass_groups: the mass labels (quadrupeds: base, hip, thigh, calf, each
            summing all legs), each a set of links whose masses add up.
        contact_groups: the contact labels (quadrupeds: base then hip, thigh,
            calf of FL, FR, RL, RR = 13). Foot links are not part of them: a
            foot on the ground is not a body contact.
        knee_groups: per leg, the links whose horizontal contact force is the
            paper's "knee" safety force (quadrupeds: thigh and calf).
        nominal_height: standing height of the root link frame over flat
            ground [m].
        physics_dt: physics step [s]; the control period is fixed at 0.02 s.
        collision_shapes: per link, the primitive that replaces its collision
            meshes (``"box"``, ``"sphere"``, ``"capsule"``, ``"cylinder"``);
            unlisted links get ``"box"``.
        joint_limit_overrides: (joint, lower, upper) for joints whose file gives
            no usable limits (e.g. Aliengo's ``continuous`` thighs).
        trim_shins: cut the boxes of each foot's parent link back to the foot
            centre (robots given by path, whose shin meshes often include the
            foot; see `frbench.robots.sim_urdf`).
        root_rotation: 9 numbers, row-major R turning the root link frame
            (new = R · old; e.g. a y-up file made z-up), or () for none.
        source: where the model file comes from.
        license: its licence.
        notes: free text shown by ``frbench robots``.
    """

    name: str
    kind: RobotKind
    urdf_path: Path
    joint_names: tuple[str, ...]
    default_pose: tuple[float, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    torque_limits: tuple[float, ...]
    joint_lower: tuple[float, ...]
    joint_upper: tuple[float, ...]
    foot_links: tuple[str, ...]
    mass_groups: tuple[LinkGroup, ...]
    contact_groups: tuple[LinkGroup, ...]
    knee_groups: tuple[LinkGroup, ...]
    nominal_height: float
    physics_dt: float = 0.005
    collision_shapes: tuple[tuple[str, str], ...] = ()
    joint_limit_overrides: tuple[tuple[str, float, float], ...] = ()
    trim_shins: bool = False
    root_rotation: tuple[float, ...] = ()
    source: str = ""
    license: str = ""
    notes: str = ""
    extra: tuple[tuple[str, str], ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        for attr in ("default_pose", "kp", "kd", "torque_limits", "joint_lower", "joint_upper"):
            value = getattr(self, attr)
            if len(value) != n:
                raise ValueError(
                    f"robot {self.name!r}: {attr} has {len(value)} entries, expected one per "
                    f"joint ({n}: {', '.join(self.joint_names)})"
                )
        if self.kind not in ("quadruped", "humanoid"):
            raise ValueError(f"robot {self.name!r}: kind {self.kind!r}, expected 'quadruped' or 'humanoid'")

    @property
    def n_joints(self) -> int:
        """Number of actuated joints."""
        return len(self.joint_names)

    def shape_of(self, link: str) -> str:
        """Collision primitive used for ``link``'s meshes."""
        return dict(self.collision_shapes).get(link, "box")

    def replace(self, **changes) -> "RobotSpec":
        """A copy with some fields changed (specs are frozen)."""
        return dataclasses.replace(self, **changes)


def quadruped_groups(
    base_link: str, hip_links: tuple[str, ...], thigh_links: tuple[str, ...], calf_links: tuple[str, ...]
) -> tuple[tuple[LinkGroup, ...], tuple[LinkGroup, ...], tuple[LinkGroup, ...]]:
    """FR-Net's mass, contact and knee groups from one link per leg segment.

    Args:
        base_link: the trunk link (after fixed-joint merging).
        hip_links, thigh_links, calf_links: one link per leg, legs in FL, FR,
            RL, RR order.

    Returns:
        (mass_groups [4], contact_groups [13], knee_groups [4]).
    """
    mass = (
        LinkGroup("base", (base_link,)),
        LinkGroup("hip", tuple(hip_links)),
        LinkGroup("thigh", tuple(thigh_links)),
        LinkGroup("calf", tuple(calf_links)),
    )
    contact = [LinkGroup("base", (base_link,))]
    knee = []
    for leg, hip, thigh, calf in zip(QUADRUPED_LEGS, hip_links, thigh_links, calf_links):
        contact += [LinkGroup(f"{leg}_hip", (hip,)), LinkGroup(f"{leg}_thigh", (thigh,)), LinkGroup(f"{leg}_calf", (calf,))]
        knee.append(LinkGroup(f"{leg}_knee", (thigh, calf)))
    return mass, tuple(contact), tuple(knee)
