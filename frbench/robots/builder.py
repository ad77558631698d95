"""Build a `RobotSpec` from a URDF plus the few numbers a file does not hold.

Joint limits and effort come from the file (so they are never typed twice);
the standing height is computed from the default pose by forward kinematics.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.kinematics import standing_height
from frbench.robots.spec import LinkGroup, RobotKind, RobotSpec
from frbench.robots.urdf_tree import merge_fixed_joints, parse_urdf


def _per_joint(value, n: int, what: str, robot: str) -> tuple[float, ...]:
    array = np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 else np.asarray(value, float)
    if array.shape != (n,):
        raise RobotFileError(f"robot {robot!r}: {what} has {array.size} values, expected 1 or {n}")
    return tuple(float(v) for v in array)


def spec_from_urdf(
    *,
    name: str,
    kind: RobotKind,
    urdf_path: str | Path,
    joint_names: Sequence[str],
    default_pose: Sequence[float],
    kp,
    kd,
    foot_links: Sequence[str],
    mass_groups: Sequence[LinkGroup],
    contact_groups: Sequence[LinkGroup],
    knee_groups: Sequence[LinkGroup],
    physics_dt: float = 0.005,
    joint_limit_overrides: Sequence[tuple[str, float, float]] = (),
    torque_limit_overrides: dict[str, float] | None = None,
    collision_shapes: Sequence[tuple[str, str]] = (),
    nominal_height: float | None = None,
    source: str = "",
    license: str = "",
    notes: str = "",
) -> RobotSpec:
    """A `RobotSpec` whose limits are read from ``urdf_path``.

    Args:
        kp, kd: one gain for all joints or one per joint (canonical order).
        joint_limit_overrides: (joint, lower, upper) [rad] replacing the file's.
        torque_limit_overrides: joint → effort [N·m] replacing the file's.
        nominal_height: standing root height [m]; computed from the default
            pose when None.
    """
    urdf_path = Path(urdf_path)
    tree = parse_urdf(urdf_path)
    n = len(joint_names)
    overrides = {j: (lo, hi) for j, lo, hi in joint_limit_overrides}
    torque_overrides = torque_limit_overrides or {}
    lower, upper, effort = [], [], []
    for joint_name in joint_names:
        joint = tree.joints.get(joint_name)
        if joint is None:
            raise RobotFileError(f"{urdf_path}: robot {name!r} expects joint {joint_name!r}, which the file does not define")
        lo, hi = overrides.get(joint_name, (joint.lower, joint.upper))
        if lo is None or hi is None or not lo < hi:
            raise RobotFileError(
                f"{urdf_path}: joint {joint_name!r} has no usable limits (lower={lo}, upper={hi}); "
                "expected <limit lower=... upper=...> with lower < upper"
            )
        torque = torque_overrides.get(joint_name, joint.effort)
        if torque is None or torque <= 0:
            raise RobotFileError(
                f"{urdf_path}: joint {joint_name!r} has no positive effort limit (effort={joint.effort}); "
                "expected <limit effort=...> in N·m"
            )
        lower.append(float(lo))
        upper.append(float(hi))
        effort.append(float(torque))
    pose = _per_joint(default_pose, n, "default_pose", name)
    if nominal_height is None:
        merged = merge_fixed_joints(tree, keep_links=set(foot_links))
        for foot in foot_links:
            if foot not in merged.links:
                raise RobotFileError(f"{urdf_path}: foot link {foot!r} of robot {name!r} is not in the file")
        nominal_height = standing_height(merged, joint_names, pose, foot_links)
    return RobotSpec(
        name=name,
        kind=kind,
        urdf_path=urdf_path,
        joint_names=tuple(joint_names),
        default_pose=pose,
        kp=_per_joint(kp, n, "kp", name),
        kd=_per_joint(kd, n, "kd", name),
        torque_limits=tuple(effort),
        joint_lower=tuple(lower),
        joint_upper=tuple(upper),
        foot_links=tuple(foot_links),
        mass_groups=tuple(mass_groups),
        contact_groups=tuple(contact_groups),
        knee_groups=tuple(knee_groups),
        nominal_height=float(nominal_height),
        physics_dt=physics_dt,
        collision_shapes=tuple(collision_shapes),
        joint_limit_overrides=tuple(joint_limit_overrides),
        source=source,
        license=license,
        notes=notes,
    )
