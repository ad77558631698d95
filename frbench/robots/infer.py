"""A `RobotSpec` for a URDF given by path: legs and groups inferred, a sidecar overrides.

Inference (quadrupeds): every leaf of the kinematic tree whose path from the
root crosses at least three moving joints is a leg; its last three moving
joints are hip, thigh and calf, the leaf is the foot. Legs are named FL, FR,
RL, RR from where their hip sits on the trunk. The standing pose puts each
foot under its hip at 70 % of the leg's reach, searched over the joint limits.

The sidecar is a TOML file beside the URDF, ``<stem>.frbench.toml`` (or given
explicitly), with any of::

    name = "mydog"
    kind = "quadruped"
    kp = 60.0                 # [N·m/rad], or a table joint -> value (default 60)
    kd = 1.5                  # [N·m·s/rad] (default 1.5)
    nominal_height = 0.31     # [m]
    physics_dt = 0.005
    feet = ["FL_foot", "FR_foot", "RL_foot", "RR_foot"]
    [default_pose]            # joint -> angle [rad]
    FL_thigh_joint = 0.8
    [joint_limits]            # joint -> [lower, upper] [rad]
    FL_thigh_joint = [-1.5, 3.4]
    [legs]                    # leg -> [hip, thigh, calf] joint names (skips inference)
    FL = ["FL_hip_joint", "FL_thigh_joint", "FL_calf_joint"]
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.builder import spec_from_urdf
from frbench.robots.kinematics import link_poses
from frbench.robots.spec import QUADRUPED_LEGS, RobotSpec, quadruped_groups
from frbench.robots.urdf_tree import MOVING_TYPES, UrdfTree, merge_fixed_joints, parse_urdf

SIDECAR_SUFFIX = ".frbench.toml"
#: PD gains of a robot given by path when its sidecar names none (see builtin.py on gains).
DEFAULT_KP, DEFAULT_KD = 60.0, 1.5
_SIDECAR_KEYS = {"name", "kind", "kp", "kd", "nominal_height", "physics_dt", "feet", "default_pose", "joint_limits", "legs"}


def sidecar_path(urdf: Path) -> Path:
    """Where the sidecar of ``urdf`` is looked for."""
    return urdf.with_name(urdf.stem + SIDECAR_SUFFIX)


def read_sidecar(path: Path | None) -> dict:
    """The sidecar's table ({} when there is none); unknown keys are refused."""
    if path is None or not path.is_file():
        return {}
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path}: not valid TOML ({exc})") from None
    unknown = set(data) - _SIDECAR_KEYS
    if unknown:
        raise RobotFileError(f"{path}: unknown key(s) {', '.join(sorted(unknown))}; expected some of {', '.join(sorted(_SIDECAR_KEYS))}")
    return data


def _chains(tree: UrdfTree) -> list[tuple[str, list[str]]]:
    """(leaf link, moving joints from the root to it) for every leaf."""
    out = []
    parents = {link for j in tree.joints.values() for link in [j.parent]}
    for leaf in tree.links:
        if leaf in parents:
            continue
        joints, link = [], leaf
        joint = tree.parent_joint(link)
        while joint is not None:
            if joint.type in MOVING_TYPES:
                joints.append(joint.name)
            joint = tree.parent_joint(joint.parent)
        out.append((leaf, joints[::-1]))
    return out


def infer_legs(tree: UrdfTree) -> dict[str, tuple[list[str], str]]:
    """Leg name → ([hip, thigh, calf] joints, foot link), for a four-legged tree."""
    legs = [(leaf, joints[-3:]) for leaf, joints in _chains(tree) if len(joints) >= 3]
    if len(legs) != 4:
        found = ", ".join(leaf for leaf, _ in legs) or "none"
        raise RobotFileError(
            f"{tree.path}: no legs found: expected 4 chains of at least 3 moving joints from the root "
            f"(hip, thigh, calf), found {len(legs)} ({found}); name them in the sidecar's [legs] table"
        )
    poses = link_poses(tree, {})
    named = {}
    for leaf, joints in legs:
        hip_child = tree.joints[joints[0]].child
        x, y = poses[hip_child][:2, 3]
        leg = ("F" if x > 0 else "R") + ("L" if y > 0 else "R")
        if leg in named:
            raise RobotFileError(
                f"{tree.path}: two legs sit at the {leg} corner ({named[leg][1]} and {leaf}); "
                "name them in the sidecar's [legs] table"
            )
        named[leg] = (joints, leaf)
    return named


def _stand_pose(tree: UrdfTree, joints: list[str], foot: str, lower, upper) -> tuple[float, float, float]:
    """(hip, thigh, calf) that puts the foot under the hip at 70 % of the reach."""
    hip_lo, hip_hi = lower[0], upper[0]
    hip = float(np.clip(0.0, hip_lo, hip_hi))
    thighs = np.linspace(lower[1], upper[1], 41)
    calves = np.linspace(lower[2], upper[2], 41)
    hip_link = tree.joints[joints[0]].child
    best, best_cost, samples = None, np.inf, []
    for thigh in thighs:
        for calf in calves:
            poses = link_poses(tree, {joints[0]: hip, joints[1]: thigh, joints[2]: calf})
            offset = poses[foot][:3, 3] - poses[hip_link][:3, 3]
            samples.append((thigh, calf, offset))
    reach = max(-s[2][2] for s in samples)
    for thigh, calf, offset in samples:
        # metres off the target, plus a little for large angles (prefers the branch nearest zero)
        cost = abs(offset[0]) + abs(-offset[2] - 0.7 * reach) + 0.02 * (abs(thigh) + abs(calf))
        if cost < best_cost:
            best, best_cost = (hip, float(thigh), float(calf)), cost
    return best


def spec_from_path(urdf: str | Path, sidecar: str | Path | None = None, name: str | None = None) -> RobotSpec:
    """A quadruped `RobotSpec` for any URDF, inferred and then overridden by the sidecar."""
    urdf = Path(urdf).resolve()
    side = read_sidecar(Path(sidecar) if sidecar else sidecar_path(urdf))
    tree = parse_urdf(urdf)
    kind = side.get("kind", "quadruped")
    if kind != "quadruped":
        raise RobotFileError(f"{urdf}: kind {kind!r}: robots given by path must be quadrupeds (register a humanoid with a RobotSpec in a plugin)")
    limit_overrides = {j: tuple(v) for j, v in side.get("joint_limits", {}).items()}
    if "legs" in side:
        legs = {}
        for leg in QUADRUPED_LEGS:
            if leg not in side["legs"]:
                raise RobotFileError(f"sidecar of {urdf}: [legs] lacks leg {leg!r}; expected FL, FR, RL, RR")
            joints = list(side["legs"][leg])
            leaf = [l for l, js in _chains(tree) if js[-3:] == joints]
            legs[leg] = (joints, leaf[0] if leaf else tree.joints[joints[-1]].child)
    else:
        legs = infer_legs(tree)
    feet = side.get("feet") or [legs[leg][1] for leg in QUADRUPED_LEGS]
    joint_names = [j for leg in QUADRUPED_LEGS for j in legs[leg][0]]
    for joint in joint_names:
        if tree.joints[joint].type == "continuous" and joint not in limit_overrides:
            raise RobotFileError(
                f"{urdf}: joint {joint!r} is continuous (no limits); give it limits in the sidecar's [joint_limits]"
            )
    merged = merge_fixed_joints(tree, keep_links=set(feet))
    pose = []
    for leg in QUADRUPED_LEGS:
        joints, _ = legs[leg]
        lower = [limit_overrides.get(j, (tree.joints[j].lower, tree.joints[j].upper))[0] for j in joints]
        upper = [limit_overrides.get(j, (tree.joints[j].lower, tree.joints[j].upper))[1] for j in joints]
        if any(v is None for v in (*lower, *upper)):
            bad = next(j for j, lo, hi in zip(joints, lower, upper) if lo is None or hi is None)
            raise RobotFileError(f"{urdf}: joint {bad!r} has no limits; expected <limit lower=... upper=...>")
        pose += _stand_pose(merged, joints, legs[leg][1], lower, upper)
    pose_table = side.get("default_pose", {})
    pose = [float(pose_table.get(j, v)) for j, v in zip(joint_names, pose)]
    link_of = lambda joint: next(l for l in [merged.joints[joint].child])  # noqa: E731
    hips = tuple(link_of(legs[leg][0][0]) for leg in QUADRUPED_LEGS)
    thighs = tuple(link_of(legs[leg][0][1]) for leg in QUADRUPED_LEGS)
    calves = tuple(link_of(legs[leg][0][2]) for leg in QUADRUPED_LEGS)
    mass, contact, knee = quadruped_groups(merged.root, hips, thighs, calves)
    as_list = lambda value: [value[j] for j in joint_names] if isinstance(value, dict) else value  # noqa: E731
    return spec_from_urdf(
        name=name or side.get("name") or urdf.stem.lower(),
        kind="quadruped",
        urdf_path=urdf,
        joint_names=joint_names,
        default_pose=pose,
        kp=as_list(side.get("kp", DEFAULT_KP)),
        kd=as_list(side.get("kd", DEFAULT_KD)),
        foot_links=feet,
        mass_groups=mass,
        contact_groups=contact,
        knee_groups=knee,
        physics_dt=float(side.get("physics_dt", 0.005)),
        joint_limit_overrides=tuple((j, float(lo), float(hi)) for j, (lo, hi) in limit_overrides.items()),
        nominal_height=side.get("nominal_height"),
        source=f"user URDF {urdf}",
        license="user-supplied",
    )
