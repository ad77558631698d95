"""A `RobotSpec` for a URDF given by path: legs, pose, groups, gains inferred; a sidecar overrides.

Legs. Every leaf of the kinematic tree ends a chain of moving joints from the
root; chains that share their last moving joint are one limb (a foot with
sensor frames is one leg). A limb is a *leg* when it has at least three moving
joints, starts with a joint no branching limb shares (arms and fingers share a
waist or shoulder joint; frames hanging off a leg's hip or knee are stretches
of the leg, not branches), and its leaf hangs, at the zero pose, more than half
as far below the root as the lowest such leaf (when no limb hangs below the root at the zero pose,
every such limb is a leg). Four legs make a quadruped (legs FL, FR, RL, RR from
where their hips sit; the last three joints are hip, thigh, calf), two a
humanoid (left, right; the other limbs, branching from the torso, are arms and
head). Any other count is refused with the count and the sidecar keys to set
(``kind``, ``legs``). A humanoid's foot is its leg's lowest leaf when that
carries collision geometry, else the link the leg's last joint moves (fixed
children merged in: Talos' and iCub's soles sit there, their leaves are bare
frames); a foot with no geometry at all is refused, naming the URDF fix and
the sidecar's ``feet``.

Standing pose. Each leg's pitch joints (axis along the body's y) are searched
over their limits for the pose that puts the foot under the hip at
`QUADRUPED_REACH` (quadruped) or `HUMANOID_REACH` (humanoid, foot kept flat) of
the leg's reach, preferring the knee direction with more room inside the
limits; other joints stay at 0 (clipped into their limits). A humanoid's foot
keeps its zero-pose orientation: the ankle pitch cancels the signed sum of the
hip and knee pitch (signs from the joints' axes; iCub's ankle axis is −y). A
continuous joint gets limits of ±π unless the sidecar's ``joint_limits`` names
it, and so does a joint whose file limits span more than a turn (placeholders
such as ±10 rad). A file drawn y-up is turned upright first
(`upright_rotation`, recorded in the spec), a biped drawn facing −x is turned
about z. A humanoid's kinematic standing height puts the lowest point of its
*simulated* geometry (meshes fitted to boxes) on the ground.

Gains and physics step: :mod:`frbench.robots.gains` (quadrupeds),
:mod:`frbench.robots.humanoid_gains` (humanoids). Nominal height: the
sidecar's, else measured by settling in both simulators
(:mod:`frbench.robot_checks.standing`, above the backends). This module runs
no simulator: the spec it derives carries the kinematic height and
``extra["height_source"] = "kinematic"`` (`needs_measured_height`), and
:func:`frbench.robot_checks.lookup.get_robot` puts the measured height in
(`with_standing`).

The sidecar (``<stem>.frbench.toml``, :mod:`frbench.robots.sidecar`) overrides
any of these.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.builder import spec_from_urdf
from frbench.robots.gains import derive_gains
from frbench.robots.humanoid_gains import derive_humanoid_gains
from frbench.robots.kinematics import chain_poses_batch, link_poses, standing_height
from frbench.robots.leg_finder import hanging_limbs, infer_legs, limb_chains, upright_rotation
from frbench.robots.sidecar import (
    HUMANOID_LEG_KEYS,
    QUADRUPED_LEG_KEYS,
    Sidecar,
    check_pose_in_limits,
    read_sidecar,
    sidecar_path,
)
from frbench.robots.sim_urdf import safe_file_stem, sim_robot_file
from frbench.robots.spec import LinkGroup, RobotSpec, quadruped_groups
from frbench.robots.urdf_tree import MOVING_TYPES, UrdfTree, merge_fixed_joints, parse_urdf, rotate_root

QUADRUPED_REACH = 0.7
HUMANOID_REACH = 0.95
#: [rad] limits a continuous joint gets (the sidecar's joint_limits narrows them).
CONTINUOUS_LIMIT = float(np.pi)
#: |axis · y| above this: a pitch joint.
PITCH_AXIS = 0.9
__all__ = ["spec_from_path", "infer_legs", "sidecar_path"]


def _limits(tree: UrdfTree, side: Sidecar, joint: str, label: str) -> tuple[float, float]:
    if joint in side.joint_limits:
        return side.joint_limits[joint]
    j = tree.joints[joint]
    if j.type == "continuous":
        return (-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT)
    if j.lower is None or j.upper is None or not j.lower < j.upper:
        raise RobotFileError(
            f"{label}: joint {joint!r} has no usable limits (lower={j.lower}, upper={j.upper}); "
            f"expected <limit lower=... upper=...> with lower < upper, or joint_limits.{joint} in {side.label}"
        )
    if j.upper - j.lower > 2 * np.pi + 1e-6:  # more than a turn: a placeholder (Solo12's ±10 rad), not a limit
        return (max(float(j.lower), -CONTINUOUS_LIMIT), min(float(j.upper), CONTINUOUS_LIMIT))
    return float(j.lower), float(j.upper)


def _pitch_axis_y(tree: UrdfTree, name: str) -> float:
    """The y component of joint ``name``'s axis in the root frame at the zero pose."""
    joint = tree.joints[name]
    rotation = link_poses(tree, {})[joint.parent][:3, :3] @ joint.origin[:3, :3]
    return float((rotation @ (joint.axis / np.linalg.norm(joint.axis)))[1])


def _pitch_joints(tree: UrdfTree, joints: list[str]) -> list[str]:
    return [name for name in joints if abs(_pitch_axis_y(tree, name)) > PITCH_AXIS]


def _stand_leg(tree: UrdfTree, joints: list[str], foot: str, limits: dict, reach_fraction: float, flat: bool) -> dict[str, float]:
    """Pitch angles putting ``foot`` under the leg's first joint at ``reach_fraction`` of the reach."""
    pitch = _pitch_joints(tree, joints)
    pose = {j: float(np.clip(0.0, *limits[j])) for j in joints}
    if len(pitch) < 2:
        return pose
    upper, knee = pitch[0], pitch[1]
    ankle = pitch[-1] if flat and len(pitch) >= 3 else None
    top = tree.joints[joints[0]].child
    u, k = (g.ravel() for g in np.meshgrid(np.linspace(*limits[upper], 41), np.linspace(*limits[knee], 41), indexing="ij"))
    q = {j: np.full(len(u), v) for j, v in pose.items()}
    q[upper], q[knee] = u, k
    if ankle is not None:  # the foot keeps its zero-pose orientation: signed pitch angles sum to zero
        sign = {j: float(np.sign(_pitch_axis_y(tree, j))) for j in (upper, knee, ankle)}
        q[ankle] = np.clip(-(sign[upper] * u + sign[knee] * k) * sign[ankle], *limits[ankle])
    poses = chain_poses_batch(tree, foot, q)
    offset = poses[foot][:, :3, 3] - poses[top][:, :3, 3]  # (N, 3)
    tilt = np.abs(poses[foot][:, 0, 2]) if ankle is not None else 0.0
    reach = float(np.max(-offset[:, 2]))
    k_lo, k_hi = limits[knee]
    room = 1.0 if abs(k_hi) >= abs(k_lo) else -1.0  # the knee bends towards the side with more room
    wrong_way = np.where((np.sign(k) == -room) & (np.abs(k) > 1e-6), 0.05, 0.0)
    cost = np.abs(offset[:, 0]) + np.abs(-offset[:, 2] - reach_fraction * reach) + tilt + 0.02 * (np.abs(u) + np.abs(k)) + wrong_way
    i = int(np.argmin(cost))
    best = {j: values[i] for j, values in q.items()}
    return {j: float(v) for j, v in best.items()}


def _subtree(tree: UrdfTree, link: str) -> list[str]:
    out, pending = [], [link]
    while pending:
        name = pending.pop()
        out.append(name)
        pending += [j.child for j in tree.child_joints(name)]
    return out


def _humanoid_groups(tree: UrdfTree, legs: dict[str, tuple[list[str], str]], feet: list[str]):
    """Mass groups (trunk, legs, arms), contact groups (pelvis, torso, per leg thigh/shin, per upper limb) and knees."""
    leg_links = {side: [l for l in _subtree(tree, tree.joints[legs[side][0][0]].child) if l not in feet] for side in legs}
    in_leg = {l for links in leg_links.values() for l in links} | set(feet)
    upper_leaves = [leaf for leaf, joints in limb_chains(tree) if leaf not in in_leg and joints]
    # the torso: the deepest link above every upper-body leaf
    paths = [[leaf, *tree.ancestors(leaf)][::-1] for leaf in upper_leaves]
    torso = tree.root
    if paths:
        for depth in range(min(len(p) for p in paths)):
            if len({p[depth] for p in paths}) == 1:
                torso = paths[0][depth]
    trunk = [tree.root] + [l for l in [torso, *tree.ancestors(torso)] if l != tree.root]
    limbs: list[list[str]] = []
    for link in trunk:
        for joint in tree.child_joints(link):
            if joint.child not in trunk and joint.child not in in_leg:
                limbs.append(_subtree(tree, joint.child))
    limb_links = {l for limb in limbs for l in limb}
    trunk += [l for l in tree.links if l not in in_leg and l not in limb_links and l not in trunk]
    mass = [LinkGroup("trunk", tuple(trunk)), LinkGroup("legs", tuple(l for s in legs for l in leg_links[s]) + tuple(feet))]
    if limb_links:
        mass.append(LinkGroup("arms", tuple(l for l in tree.links if l in limb_links)))
    contact = [LinkGroup("pelvis", (tree.root,))]
    if len(trunk) > 1:
        contact.append(LinkGroup("torso", tuple(trunk[1:])))
    knees = []
    for side in legs:
        joints = legs[side][0]
        knee = _pitch_joints(tree, joints)[1:2] or joints[len(joints) // 2:][:1]
        shin = _subtree(tree, tree.joints[knee[0]].child)
        thigh = tuple(l for l in leg_links[side] if l not in shin)
        shin = tuple(l for l in leg_links[side] if l in shin)
        if thigh:
            contact.append(LinkGroup(f"{side}_thigh", thigh))
        if shin:
            contact.append(LinkGroup(f"{side}_shin", shin))
            knees.append(LinkGroup(f"{side}_shin", shin))
    for limb in limbs:
        contact.append(LinkGroup(f"limb_{limb[0]}", tuple(limb)))
    return tuple(mass), tuple(contact), tuple(knees)


def _legs_from_sidecar(tree: UrdfTree, side: Sidecar, kind: str) -> dict[str, tuple[list[str], str]]:
    leaves = {js[-1]: leaf for leaf, js, _ in hanging_limbs(tree)}
    out = {}
    for leg in (QUADRUPED_LEG_KEYS if kind == "quadruped" else HUMANOID_LEG_KEYS):
        joints = list(side.legs[leg])
        out[leg] = (joints, leaves.get(joints[-1]) or tree.joints[joints[-1]].child)
    return out


def _few_names(names: list[str], most: int = 40) -> str:
    """Up to ``most`` names, comma-separated, then how many more."""
    return ", ".join(names[:most]) + (f", ... {len(names) - most} more" if len(names) > most else "")


def safe_name(stem: str) -> str:
    """A registry name from a file stem: lower case, unsafe characters as '_'."""
    return safe_file_stem(stem.lower())


def provisional_spec(urdf: str | Path, sidecar: str | Path | None = None, name: str | None = None) -> tuple[RobotSpec, Sidecar, dict]:
    """The spec before gains and measured height: (spec with placeholder gains, sidecar, legs)."""
    urdf = Path(urdf).resolve()
    side = read_sidecar(Path(sidecar) if sidecar else sidecar_path(urdf))
    tree = parse_urdf(urdf)
    label = str(urdf)
    rotation = upright_rotation(tree)
    tree = rotate_root(tree, rotation)
    if side.legs is not None or side.kind is not None:
        side.check_against(tree, side.kind or ("humanoid" if side.legs and set(side.legs) == set(HUMANOID_LEG_KEYS) else "quadruped"))
    if side.legs is not None:
        kind = side.kind or ("humanoid" if set(side.legs) == set(HUMANOID_LEG_KEYS) else "quadruped")
        legs = _legs_from_sidecar(tree, side, kind)
    else:
        kind, legs = infer_legs(tree, side.kind, label)
    side.check_against(tree, kind)
    leg_keys = QUADRUPED_LEG_KEYS if kind == "quadruped" else HUMANOID_LEG_KEYS
    feet = list(side.feet) if side.feet else [legs[leg][1] for leg in leg_keys]
    leg_joints = [j for leg in leg_keys for j in legs[leg][0]]
    moving = [j.name for j in tree.joints.values() if j.type in MOVING_TYPES]
    if kind == "quadruped":
        extra = [j for j in moving if j not in leg_joints]
        if extra:
            raise RobotFileError(
                f"{label}: {len(extra)} moving joints outside the four legs ({', '.join(extra[:4])}{', ...' if len(extra) > 4 else ''}); "
                "a quadruped by path actuates its 12 leg joints only: make the others fixed in the URDF, or name the legs in "
                f"{side.label}'s [legs]"
            )
        joint_names = leg_joints
        for leg, foot in zip(leg_keys, feet):
            if foot == tree.joints[legs[leg][0][-1]].child:
                raise RobotFileError(
                    f"{label}: leg {leg} ends at its calf link {foot!r}, with no foot link below it; frbench tells foot "
                    "contacts from shin contacts by a separate foot link: add one (a fixed joint to a link with a sphere "
                    f"collision) to the URDF and name it in {side.label}'s feet"
                )
    else:
        joint_names = leg_joints + [j for j in moving if j not in leg_joints]
    side.check_complete(joint_names)
    limits = {j: _limits(tree, side, j, label) for j in joint_names}
    check_pose_in_limits(side, {j: v[0] for j, v in limits.items()}, {j: v[1] for j, v in limits.items()})
    effort, missing = {}, []
    for j in joint_names:
        value = side.effort.get(j) if isinstance(side.effort, dict) else side.effort
        if value is None:
            value = tree.joints[j].effort
            if value is None or value <= 0:
                missing.append((j, value))
                continue
        effort[j] = float(value)
    if missing:  # all of them in one line: Romeo's fingers are fourteen joints of effort 0
        (j, value), more = missing[0], [name for name, _ in missing[1:]]
        others = f", nor have {len(more)} more ({_few_names(more)})" if more else ""
        each = f"effort.{j}" + (" and each of those" if more else "")
        raise RobotFileError(
            f"{label}: joint {j!r} has no positive effort limit (effort={value}){others}; set {each} (N·m) "
            f"or effort for every joint in {side.label}"
        )
    merged = merge_fixed_joints(tree, keep_links=set(feet))
    for foot in feet:
        if foot not in merged.links:
            raise RobotFileError(f"{label}: foot link {foot!r} is not in the file")
        if kind == "humanoid" and not merged.links[foot].collisions:
            raise RobotFileError(
                f"{label}: foot link {foot!r} has no collision geometry, so nothing of the foot touches the ground; "
                f"add a <collision> (a box under the sole) to it in the URDF, or name the links that have one in "
                f"{side.label}'s feet"
            )
    pose = {j: float(np.clip(0.0, *limits[j])) for j in joint_names}
    for leg in leg_keys:
        joints, _ = legs[leg]
        foot = feet[leg_keys.index(leg)]
        reach, flat = (QUADRUPED_REACH, False) if kind == "quadruped" else (HUMANOID_REACH, True)
        pose.update(_stand_leg(merged, joints, foot, limits, reach, flat))
    pose.update(side.default_pose)
    if kind == "quadruped":
        link_of = lambda joint: merged.joints[joint].child  # noqa: E731
        mass, contact, knee = quadruped_groups(
            merged.root,
            tuple(link_of(legs[leg][0][0]) for leg in leg_keys),
            tuple(link_of(legs[leg][0][1]) for leg in leg_keys),
            tuple(link_of(legs[leg][0][2]) for leg in leg_keys),
        )
    else:
        mass, contact, knee = _humanoid_groups(merged, legs, feet)
    overrides = tuple((j, lo, hi) for j, (lo, hi) in limits.items() if (lo, hi) != (tree.joints[j].lower, tree.joints[j].upper))
    ordered_pose = [pose[j] for j in joint_names]
    spec = spec_from_urdf(
        name=name or side.name or safe_name(urdf.stem),
        kind=kind,
        urdf_path=urdf,
        joint_names=joint_names,
        default_pose=ordered_pose,
        kp=1.0,
        kd=0.0,
        foot_links=feet,
        mass_groups=mass,
        contact_groups=contact,
        knee_groups=knee,
        physics_dt=side.physics_dt or 0.005,
        joint_limit_overrides=overrides,
        torque_limit_overrides=effort,
        collision_shapes=tuple((foot, "sphere") for foot in feet) if kind == "quadruped" else (),
        nominal_height=standing_height(merged, joint_names, ordered_pose, feet),
        source=f"user URDF {urdf}",
        license="user-supplied",
    )
    rotated = () if np.allclose(rotation, np.eye(3)) else tuple(float(v) for v in rotation.flatten())
    spec = spec.replace(trim_shins=kind == "quadruped", root_rotation=rotated)
    if kind == "humanoid":  # the simulated geometry (meshes fitted to boxes), lowest point of any link on the ground
        sim_tree = parse_urdf(sim_robot_file(spec).path)
        spec = spec.replace(nominal_height=standing_height(sim_tree, joint_names, ordered_pose, list(sim_tree.links)))
    return spec, side, {leg: tuple(legs[leg][0]) for leg in leg_keys}


#: ``extra`` key of a spec by path naming where its nominal height comes from: "sidecar", "kinematic" (the
#: standing height still to be measured in the simulators) or "measured" (`with_standing`).
HEIGHT_SOURCE = "height_source"


def spec_from_path(urdf: str | Path, sidecar: str | Path | None = None, name: str | None = None) -> RobotSpec:
    """The `RobotSpec` of any quadruped or humanoid URDF (module docstring), with the sidecar's nominal height or
    else the kinematic one (`needs_measured_height`)."""
    spec, side, legs = provisional_spec(urdf, sidecar, name)
    kinematic_height = spec.nominal_height
    derive = derive_humanoid_gains if spec.kind == "humanoid" else derive_gains
    derivation = derive(spec, tuple(legs.values()), side.physics_dt, side.label)
    n = spec.n_joints
    gains = {}
    for key, derived in (("kp", derivation.kp), ("kd", derivation.kd)):
        value = getattr(side, key)
        gains[key] = tuple(value[j] for j in spec.joint_names) if isinstance(value, dict) else ((float(value),) * n if value is not None else derived)
    spec = spec.replace(kp=gains["kp"], kd=gains["kd"], physics_dt=side.physics_dt or derivation.physics_dt)
    if derivation.effort and side.effort is None:  # leg torques capped at what the robot can use (gains, step 3)
        spec = spec.replace(torque_limits=derivation.effort)
    extra = {
        "legs": json.dumps(legs),
        "derivation": json.dumps(derivation.as_dict()),
        "kinematic_height": f"{kinematic_height:.6f}",
        "sidecar": str(side.path) if side.path and side.path.is_file() else "",
    }
    if side.nominal_height is not None:
        spec = spec.replace(nominal_height=side.nominal_height)
    extra[HEIGHT_SOURCE] = "sidecar" if side.nominal_height is not None else "kinematic"
    return spec.replace(extra=tuple(extra.items()))


def needs_measured_height(spec: RobotSpec) -> bool:
    """Whether ``spec`` is a robot by path whose nominal height is still the kinematic one (no sidecar height)."""
    return dict(spec.extra).get(HEIGHT_SOURCE) == "kinematic"


def with_standing(spec: RobotSpec, settled: dict) -> RobotSpec:
    """``spec`` with the standing height measured in the simulators, ``settled`` = {"nominal_height" [m],
    <backend>: {"height", "diverged"}} (`frbench.robot_checks.standing.measured_height`), recorded in
    ``extra["standing"]``; the kinematic height stays when the measurement is not a positive number."""
    extra = dict(spec.extra)
    extra["standing"] = json.dumps(settled)
    extra[HEIGHT_SOURCE] = "measured"
    if np.isfinite(settled["nominal_height"]) and settled["nominal_height"] > 0:
        spec = spec.replace(nominal_height=float(settled["nominal_height"]))
    return spec.replace(extra=tuple(extra.items()))
