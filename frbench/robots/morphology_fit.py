"""A quadruped's 14 morphology-table quantities, measured from its URDF (the inverse of `morphology_urdf`).

FR-Net randomises the 14 fields of :data:`frbench.robots.morphology.MORPHOLOGY_RANGES`. This module measures the
same quantities on any quadruped `RobotSpec`, so a robot can be placed relative to that table. The URDF is read
with :func:`frbench.robots.urdf_tree.parse_urdf` and its fixed joints are merged as the simulation URDF merges
them (:func:`~frbench.robots.urdf_tree.merge_fixed_joints`, foot links kept apart), so the link groups are the
links the simulators see:

* masses [kg]: ``trunk_mass`` is the root link with everything rigidly fixed to it (sensors, motor rotors
  housed in the trunk); ``hip_mass``, ``thigh_mass`` and ``calf_mass`` are the child link of that leg joint with
  its fixed children, mean over the four legs. The foot link is *not* in ``calf_mass``: the generator writes
  the foot as its own sphere link (``foot_mass``), and the table's calf mass excludes it; the foot's mass is
  reported apart (:attr:`MorphologyFit.foot_mass`).
* lengths [m], mean over the legs, from the joint origins: ``hip_length`` = |lateral (y) offset| of the thigh
  joint from the hip joint, in the trunk's axes; ``thigh_length`` = distance thigh joint → calf joint;
  ``calf_length`` = distance calf joint → foot contact point (the centre of the foot link's sphere collision,
  else the foot link's origin).
* sizes [m]: the axis-aligned bounding box, in the link's own frame, of the link's largest collision element
  (by bounding-box volume; a merged rotor cylinder or a 1 mm sensor box does not count). A link whose
  collisions are all meshes takes the bounds of all its mesh vertices together (a mesh-described link often
  splits one body into parts, e.g. Go2's upper and lower calf). Trunk: length = x, width = y, height = z size.
  Thigh and calf: width = y (lateral), height = x (fore-aft) size, the generator's convention. A size is
  ``None`` when the link has no collision element or only meshes whose vertices cannot be read here
  (:attr:`MorphologyFit.sources` says which).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.mesh_vertices import binary_stl_vertices, text_mesh_vertices
from frbench.robots.morphology import MORPHOLOGY_RANGES
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import Collision, UrdfTree, merge_fixed_joints, parse_urdf, rotate_root

__all__ = ["MorphologyFit", "measure_morphology"]

# Unit box corners, shape (8, 3), each coordinate ±1/2.
_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])


@dataclass(frozen=True)
class MorphologyFit:
    """A robot's values of the 14 table fields.

    Attributes:
        robot: registry name of the robot.
        values: field name (the keys of ``MORPHOLOGY_RANGES``, same order) → value [kg or m], or ``None`` when
            it cannot be measured from the file.
        sources: field name → how the value was obtained (``"links"``, ``"joints"``, ``"box"``, ``"cylinder"``,
            ``"sphere"``, ``"mesh bounds"``, or why it is missing).
        foot_mass: mean mass of one foot link [kg] (not a table field; kept out of ``calf_mass``).
    """

    robot: str
    values: dict[str, float | None]
    sources: dict[str, str]
    foot_mass: float


def _points(collision: Collision) -> np.ndarray | None:
    """Points (n, 3) in the link frame whose bounding box is the element's; None for an unreadable mesh."""
    if collision.kind == "box":
        local = _CORNERS * np.asarray(collision.size)
    elif collision.kind == "sphere":
        local = _CORNERS * 2 * collision.size[0]
    elif collision.kind == "cylinder":  # axis z of its own frame
        radius, length = collision.size
        local = _CORNERS * np.array([2 * radius, 2 * radius, length])
    else:
        local = text_mesh_vertices(collision.mesh)
        if local is None:
            local = binary_stl_vertices(collision.mesh)
        if local is None or len(local) == 0:
            return None
        local = local * np.asarray(collision.size)
    return local @ collision.origin[:3, :3].T + collision.origin[:3, 3]


def _bounds(collisions: list[Collision]) -> tuple[np.ndarray | None, str]:
    """Bounding-box size (3,) [m] in the link frame and its source (see the module docstring)."""
    if not collisions:
        return None, "no collision geometry"
    primitives = [c for c in collisions if c.kind != "mesh"]
    if primitives:
        extents = [np.ptp(_points(c), axis=0) for c in primitives]
        best = int(np.argmax([np.prod(e) for e in extents]))
        return extents[best], primitives[best].kind
    clouds = [_points(c) for c in collisions]
    if any(cloud is None for cloud in clouds):
        return None, "mesh format not readable here"
    return np.ptp(np.vstack(clouds), axis=0), "mesh bounds"


def _foot_point(tree: UrdfTree, foot: str, calf: str) -> np.ndarray:
    """The foot contact point (sphere centre, else foot origin) in the calf link's frame, shape (3,) [m]."""
    link = tree.links[foot]
    sphere = next((c for c in link.collisions if c.kind == "sphere"), None)
    point = np.append(sphere.origin[:3, 3] if sphere is not None else np.zeros(3), 1.0)
    name = foot
    while name != calf:
        joint = tree.parent_joint(name)
        if joint is None or joint.type != "fixed":
            raise RobotFileError(f"{tree.path}: foot link {foot!r} is not rigidly attached to calf link {calf!r}")
        point, name = joint.origin @ point, joint.parent
    return point[:3]


def _mean(values: list[float]) -> float:
    return float(np.mean(values))


def measure_morphology(spec: RobotSpec) -> MorphologyFit:
    """The 14 table quantities of a quadruped ``spec`` measured from its URDF [kg, m].

    Args:
        spec: a quadruped spec (12 joints in canonical order: FL, FR, RL, RR × hip, thigh, calf; 4 foot links).

    Returns:
        The measured values; see the module docstring for the link groups and conventions.

    Raises:
        RobotFileError: naming the robot when it is not a quadruped or its file does not have that layout.
    """
    if spec.kind != "quadruped" or spec.n_joints != 12 or len(spec.foot_links) != 4:
        raise RobotFileError(f"robot {spec.name!r}: morphology fit needs a quadruped with 12 joints and 4 feet")
    tree = parse_urdf(spec.urdf_path)
    if spec.root_rotation:
        tree = rotate_root(tree, spec.root_rotation)
    tree = merge_fixed_joints(tree, keep_links=set(spec.foot_links))
    missing = [name for name in spec.joint_names if name not in tree.joints]
    if missing:
        raise RobotFileError(f"{spec.urdf_path}: robot {spec.name!r} joint {missing[0]!r} is not in the file")
    per_leg: dict[str, list[float]] = {k: [] for k in ("hip_mass", "thigh_mass", "calf_mass", "foot_mass",
                                                      "hip_length", "thigh_length", "calf_length")}
    for leg in range(4):
        hip, thigh, calf = (tree.joints[name] for name in spec.joint_names[3 * leg:3 * leg + 3])
        if not (thigh.parent == hip.child and calf.parent == thigh.child):
            raise RobotFileError(f"{spec.urdf_path}: joints {hip.name}, {thigh.name}, {calf.name} of robot "
                                 f"{spec.name!r} are not one chain hip → thigh → calf")
        for part, joint in (("hip", hip), ("thigh", thigh), ("calf", calf)):
            per_leg[f"{part}_mass"].append(tree.links[joint.child].mass)
        per_leg["foot_mass"].append(tree.links[spec.foot_links[leg]].mass)
        per_leg["hip_length"].append(abs(float((hip.origin[:3, :3] @ thigh.origin[:3, 3])[1])))
        per_leg["thigh_length"].append(float(np.linalg.norm(calf.origin[:3, 3])))
        per_leg["calf_length"].append(float(np.linalg.norm(_foot_point(tree, spec.foot_links[leg], calf.child))))
    values: dict[str, float | None] = dict.fromkeys(MORPHOLOGY_RANGES)
    sources: dict[str, str] = {}
    for name, samples in per_leg.items():
        if name != "foot_mass":
            values[name] = _mean(samples)
            sources[name] = "links" if name.endswith("mass") else "joints"
    root = tree.links[tree.root]
    values["trunk_mass"], sources["trunk_mass"] = float(root.mass), "links"
    size, source = _bounds(root.collisions)
    for axis, name in enumerate(("trunk_length", "trunk_width", "trunk_height")):
        values[name], sources[name] = (None if size is None else float(size[axis])), source
    for part in ("thigh", "calf"):
        links = [tree.joints[spec.joint_names[3 * leg + (1 if part == "thigh" else 2)]].child for leg in range(4)]
        fits = [_bounds(tree.links[link].collisions) for link in links]
        for axis, name in ((1, f"{part}_width"), (0, f"{part}_height")):
            known = [size[axis] for size, _ in fits if size is not None]
            values[name] = _mean(known) if len(known) == 4 else None
            sources[name] = fits[0][1] if len(known) == 4 else next(src for size, src in fits if size is None)
    return MorphologyFit(spec.name, values, sources, _mean(per_leg["foot_mass"]))
