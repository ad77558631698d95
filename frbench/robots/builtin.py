"""The six robots frbench ships: Go2, Go1, Aliengo, G1, Spot-like and Lite3-like.

Numbers come from ``shared/notes/robots.md`` (their sources are the model files
and the manufacturers' sheets). Each factory builds its spec on first lookup.

Gains: the PD alone must hold each robot at its default pose within 10 % of
its kinematic standing height (the ``frbench robot check`` standing test).
The Kp 20 / Kd 0.5 that locomotion codebases use sags Go1 by 27 % and Aliengo
by 34 % in both simulators, so the quadrupeds use stiffer gains inside the
paper's randomisation range (Kp 20–80, Kd 0.6–2.0): Go2 40/1, Go1 60/1,
Aliengo 80/2. Kd stays low enough for explicit PD without armature to be
stable on light calves (kd·dt/I below about 1; at 2 the loop chatters). A policy that wants other gains may set them per simulation
(`frbench.backends.base.PhysicsParams`).
"""

from __future__ import annotations

from typing import Callable

from frbench.robots import morphology_presets
from frbench.robots.builder import spec_from_urdf
from frbench.robots.morphology_urdf import cached_spec
from frbench.robots.paths import cache_dir, example_robot_data, pybullet_data_file
from frbench.robots.spec import QUADRUPED_LEGS, LinkGroup, RobotSpec, quadruped_groups


def _leg_joints(fmt_hip: str, fmt_thigh: str, fmt_calf: str) -> tuple[str, ...]:
    return tuple(name for leg in QUADRUPED_LEGS for name in (fmt_hip.format(leg), fmt_thigh.format(leg), fmt_calf.format(leg)))


def _quadruped_pose(hip: float, thigh_front: float, thigh_rear: float, calf: float) -> tuple[float, ...]:
    """Default pose in canonical order; left hips +hip, right hips −hip."""
    pose = []
    for leg in QUADRUPED_LEGS:
        side = 1.0 if leg[1] == "L" else -1.0
        pose += [side * hip, thigh_front if leg[0] == "F" else thigh_rear, calf]
    return tuple(pose)


def _unitree_quadruped(name, urdf, base, hip, thigh, calf, foot, pose, kp, kd, source, **extra) -> RobotSpec:
    mass, contact, knee = quadruped_groups(
        base,
        tuple(hip.format(leg) for leg in QUADRUPED_LEGS),
        tuple(thigh.format(leg) for leg in QUADRUPED_LEGS),
        tuple(calf.format(leg) for leg in QUADRUPED_LEGS),
    )
    return spec_from_urdf(
        name=name,
        kind="quadruped",
        urdf_path=urdf,
        joint_names=_leg_joints(hip + "_joint", thigh + "_joint", calf + "_joint") if "joints" not in extra else extra.pop("joints"),
        default_pose=pose,
        kp=kp,
        kd=kd,
        foot_links=tuple(foot.format(leg) for leg in QUADRUPED_LEGS),
        mass_groups=mass,
        contact_groups=contact,
        knee_groups=knee,
        source=source,
        **extra,
    )


def go2() -> RobotSpec:
    """Unitree Go2 from example-robot-data (convex collision meshes fitted to boxes, spherical feet)."""
    return _unitree_quadruped(
        "go2",
        example_robot_data("go2_description/urdf/go2.urdf"),
        "base", "{}_hip", "{}_thigh", "{}_calf", "{}_foot",
        _quadruped_pose(0.1, 0.8, 1.0, -1.5),
        kp=40.0, kd=1.0,
        source="example-robot-data 6.0.0 go2_description/urdf/go2.urdf",
        license="BSD-3-Clause (package); upstream Unitree MPL-2.0",
        collision_shapes=tuple((f"{leg}_{part}", shape) for leg in QUADRUPED_LEGS for part, shape in (("foot", "sphere"), ("hip", "cylinder"))),
    )


def go1() -> RobotSpec:
    """Unitree Go1 from example-robot-data (primitive collisions)."""
    return _unitree_quadruped(
        "go1",
        example_robot_data("go1_description/urdf/go1.urdf"),
        "base", "{}_hip", "{}_thigh", "{}_calf", "{}_foot",
        _quadruped_pose(0.1, 0.9, 0.9, -1.8),
        kp=60.0, kd=1.0,
        source="example-robot-data 6.0.0 go1_description/urdf/go1.urdf",
        license="BSD-3-Clause (package); upstream Unitree",
        notes="root link 'base' (1e-6 kg) carries the merged trunk",
    )


def aliengo() -> RobotSpec:
    """Unitree Aliengo from pybullet_data; its continuous thigh joints get the published limits."""
    return _unitree_quadruped(
        "aliengo",
        pybullet_data_file("aliengo/aliengo.urdf"),
        "trunk", "{}_hip", "{}_upper", "{}_lower", "{}_toe",
        _quadruped_pose(0.0, 0.9, 0.9, -1.8),
        kp=80.0, kd=2.0,
        source="pybullet_data (pybullet 3.2.7) aliengo/aliengo.urdf",
        license="none stated in pybullet_data",
        joint_limit_overrides=tuple((f"{leg}_upper_joint", -2.094, 4.189) for leg in QUADRUPED_LEGS),
        notes="thigh joints are 'continuous' in the file; limits [-2.094, 4.189] rad from Unitree's spec",
    )


G1_JOINTS = (
    "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint",
    "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
    "right_ankle_pitch_joint", "right_ankle_roll_joint",
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint", "left_elbow_joint",
    "left_wrist_roll_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
    "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint", "right_elbow_joint",
    "right_wrist_roll_joint", "right_wrist_pitch_joint", "right_wrist_yaw_joint",
)


def _g1_gains() -> tuple[tuple[float, ...], tuple[float, ...]]:
    """PD gains per G1 joint.

    Explicit PD without armature (Bullet has none) is stable only while
    ``kd·dt/I < 2`` and ``kp·dt²/I`` stays small, with I the joint-space inertia
    (0.4 g·m² at the ankle and wrist roll joints). The light distal joints
    therefore get small damping; the ankle pitch keeps enough stiffness
    (> m·g·h / 2 ≈ 115 N·m/rad) to balance the standing robot.
    """
    table = (  # joint-name fragment → (kp [N·m/rad], kd [N·m·s/rad]); first match wins
        ("ankle_pitch", (300.0, 0.8)), ("ankle_roll", (40.0, 0.1)), ("wrist_roll", (20.0, 0.1)),
        ("wrist", (20.0, 0.2)), ("hip", (200.0, 4.0)), ("knee", (300.0, 6.0)), ("waist", (200.0, 4.0)),
        ("shoulder_yaw", (40.0, 0.5)), ("shoulder", (40.0, 1.0)), ("elbow", (40.0, 1.0)),
    )
    kp, kd = [], []
    for joint in G1_JOINTS:
        gains = next(v for k, v in table if k in joint)
        kp.append(gains[0])
        kd.append(gains[1])
    return tuple(kp), tuple(kd)


def _g1_pose() -> tuple[float, ...]:
    pose = dict.fromkeys(G1_JOINTS, 0.0)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        pose[f"{side}_hip_pitch_joint"] = -0.1
        pose[f"{side}_knee_joint"] = 0.3
        pose[f"{side}_ankle_pitch_joint"] = -0.2
        pose[f"{side}_shoulder_pitch_joint"] = 0.2
        pose[f"{side}_shoulder_roll_joint"] = 0.2 * sign
        pose[f"{side}_elbow_joint"] = 1.28
    return tuple(pose[j] for j in G1_JOINTS)


def g1() -> RobotSpec:
    """Unitree G1, 29 dof, from example-robot-data (meshes fitted to boxes; spherical foot contacts)."""
    kp, kd = _g1_gains()
    side_groups = []
    for side in ("left", "right"):
        side_groups += [
            LinkGroup(f"{side}_thigh", (f"{side}_hip_pitch_link", f"{side}_hip_roll_link", f"{side}_hip_yaw_link")),
            LinkGroup(f"{side}_shin", (f"{side}_knee_link", f"{side}_ankle_pitch_link")),
            LinkGroup(f"{side}_upper_arm", (f"{side}_shoulder_pitch_link", f"{side}_shoulder_roll_link", f"{side}_shoulder_yaw_link")),
            LinkGroup(f"{side}_forearm", (f"{side}_elbow_link", f"{side}_wrist_roll_link", f"{side}_wrist_pitch_link", f"{side}_wrist_yaw_link")),
        ]
    groups = {g.name: g for g in side_groups}
    both = lambda part: tuple(l for s in ("left", "right") for l in groups[f"{s}_{part}"].links)  # noqa: E731
    mass_groups = (
        LinkGroup("trunk", ("pelvis", "waist_yaw_link", "waist_roll_link", "torso_link")),
        LinkGroup("legs", both("thigh") + both("shin") + ("left_ankle_roll_link", "right_ankle_roll_link")),
        LinkGroup("arms", both("upper_arm") + both("forearm")),
    )
    contact_groups = (
        LinkGroup("pelvis", ("pelvis", "waist_yaw_link", "waist_roll_link")),
        LinkGroup("torso", ("torso_link",)),
        *side_groups,
    )
    knee_groups = (groups["left_shin"], groups["right_shin"])
    return spec_from_urdf(
        name="g1",
        kind="humanoid",
        urdf_path=example_robot_data("g1_description/urdf/g1_29dof_rev_1_0.urdf"),
        joint_names=G1_JOINTS,
        default_pose=_g1_pose(),
        kp=kp,
        kd=kd,
        foot_links=("left_ankle_roll_link", "right_ankle_roll_link"),
        mass_groups=mass_groups,
        contact_groups=contact_groups,
        knee_groups=knee_groups,
        physics_dt=0.002,
        source="example-robot-data 6.0.0 g1_description/urdf/g1_29dof_rev_1_0.urdf",
        license="BSD-3-Clause",
        notes="all 29 joints actuated; physics step 2 ms (stable in both simulators without armature)",
    )


def _morphology_robot(preset_name: str, name: str, source: str) -> RobotSpec:
    params = getattr(morphology_presets, preset_name)
    return cached_spec(params, name, cache_dir() / "morphology" / f"{name}.urdf", source=source)


def spot_like() -> RobotSpec:
    """A Spot-like quadruped generated from published dimensions (see morphology_presets.SPOT_LIKE)."""
    return _morphology_robot("SPOT_LIKE", "spot_like", "frbench morphology generator, Spot published dimensions")


def lite3_like() -> RobotSpec:
    """A Lite3-like quadruped generated from published dimensions (see morphology_presets.LITE3_LIKE)."""
    return _morphology_robot("LITE3_LIKE", "lite3_like", "frbench morphology generator, Lite3 published dimensions")


#: Built-in robots: name → factory.
BUILTIN_ROBOTS: dict[str, Callable[[], RobotSpec]] = {
    "go2": go2,
    "go1": go1,
    "aliengo": aliengo,
    "spot_like": spot_like,
    "lite3_like": lite3_like,
    "g1": g1,
}
