"""A URDF as a small, editable kinematic tree: parse, check, merge fixed joints, write.

Only what frbench needs: links with inertials and collision geometry, joints
with origins, axes and limits. Visuals, transmissions and simulator extensions
are dropped. Every error is a :class:`~frbench.errors.RobotFileError` naming the
file and the link or joint.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frbench.errors import RobotFileError
from frbench.portable_products import dot, norm
from frbench.robots.paths import resolve_mesh

MOVING_TYPES = ("revolute", "continuous", "prismatic")


# --------------------------------------------------------------------------- rotations
def rpy_to_matrix(rpy) -> np.ndarray:
    """URDF roll-pitch-yaw [rad] → rotation matrix R = Rz(y)·Ry(p)·Rx(r), shape (3, 3)."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_rpy(rot: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rpy_to_matrix`, shape (3,)."""
    pitch = np.arcsin(np.clip(-rot[2, 0], -1.0, 1.0))
    if abs(np.cos(pitch)) > 1e-9:
        roll = np.arctan2(rot[2, 1], rot[2, 2])
        yaw = np.arctan2(rot[1, 0], rot[0, 0])
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = np.arctan2(-rot[0, 1], rot[1, 1])
    return np.array([roll, pitch, yaw])


def transform(xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Homogeneous transform (4, 4) from a URDF origin."""
    out = np.eye(4)
    out[:3, :3] = rpy_to_matrix(rpy)
    out[:3, 3] = np.asarray(xyz, dtype=float)
    return out


# --------------------------------------------------------------------------- data
@dataclass
class Collision:
    """One collision element. ``origin`` (4, 4) in the link frame.

    ``kind`` is box | sphere | cylinder | mesh; ``size`` holds box full sizes (3,),
    sphere (radius,), cylinder (radius, length), mesh the scale (3,).
    """

    kind: str
    size: tuple[float, ...]
    origin: np.ndarray
    mesh: Path | None = None


@dataclass
class Link:
    """A link: mass [kg], CoM (3,) and inertia about the CoM (3, 3) in the link frame."""

    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    has_inertial: bool = False
    collisions: list[Collision] = field(default_factory=list)
    merged: list[str] = field(default_factory=list)


@dataclass
class Joint:
    """A joint; ``origin`` (4, 4) places the child frame in the parent frame."""

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None


@dataclass
class UrdfTree:
    """A parsed URDF. ``links`` and ``joints`` keep file order."""

    path: Path
    name: str
    links: dict[str, Link]
    joints: dict[str, Joint]

    @property
    def root(self) -> str:
        """The link that is no joint's child."""
        children = {j.child for j in self.joints.values()}
        roots = [name for name in self.links if name not in children]
        return roots[0]

    def child_joints(self, link: str) -> list[Joint]:
        """Joints whose parent is ``link``, in file order."""
        return [j for j in self.joints.values() if j.parent == link]

    def parent_joint(self, link: str) -> Joint | None:
        """The joint whose child is ``link`` (None for the root)."""
        for joint in self.joints.values():
            if joint.child == link:
                return joint
        return None

    def moving_joints(self) -> list[Joint]:
        """Revolute, continuous and prismatic joints, in file order."""
        return [j for j in self.joints.values() if j.type in MOVING_TYPES]

    def ancestors(self, link: str) -> list[str]:
        """Links from ``link``'s parent up to the root."""
        out = []
        joint = self.parent_joint(link)
        while joint is not None:
            out.append(joint.parent)
            joint = self.parent_joint(joint.parent)
        return out

    def copy(self) -> "UrdfTree":
        """A deep copy."""
        return dataclasses.replace(
            self,
            links={k: dataclasses.replace(v, collisions=list(v.collisions), merged=list(v.merged)) for k, v in self.links.items()},
            joints={k: dataclasses.replace(v) for k, v in self.joints.items()},
        )

    def total_mass(self) -> float:
        """Sum of link masses [kg]."""
        return float(sum(link.mass for link in self.links.values()))


# --------------------------------------------------------------------------- parsing
def _floats(text: str | None, n: int, where: str, default=None) -> tuple[float, ...]:
    if text is None:
        if default is None:
            raise RobotFileError(f"{where}: missing value, expected {n} numbers")
        return tuple(default)
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        raise RobotFileError(f"{where}: {text!r} is not {n} numbers") from None
    if len(values) != n or not all(np.isfinite(values)):
        raise RobotFileError(f"{where}: {text!r}, expected {n} finite numbers")
    return values


def _origin(element: ET.Element | None, where: str) -> np.ndarray:
    if element is None:
        return np.eye(4)
    return transform(
        _floats(element.get("xyz"), 3, f"{where} origin xyz", (0, 0, 0)),
        _floats(element.get("rpy"), 3, f"{where} origin rpy", (0, 0, 0)),
    )


def _parse_collision(element: ET.Element, where: str, urdf_dir: Path) -> Collision:
    geometry = element.find("geometry")
    if geometry is None or len(geometry) == 0:
        raise RobotFileError(f"{where}: collision without <geometry>")
    shape = geometry[0]
    origin = _origin(element.find("origin"), where)
    if shape.tag == "box":
        return Collision("box", _floats(shape.get("size"), 3, f"{where} box size"), origin)
    if shape.tag == "sphere":
        return Collision("sphere", _floats(shape.get("radius"), 1, f"{where} sphere radius"), origin)
    if shape.tag == "cylinder":
        radius = _floats(shape.get("radius"), 1, f"{where} cylinder radius")[0]
        length = _floats(shape.get("length"), 1, f"{where} cylinder length")[0]
        return Collision("cylinder", (radius, length), origin)
    if shape.tag == "mesh":
        filename = shape.get("filename") or ""
        mesh = resolve_mesh(filename, urdf_dir)
        if not mesh.is_file():
            raise RobotFileError(f"{where}: mesh file {filename!r} not found (looked at {mesh})")
        scale = _floats(shape.get("scale"), 3, f"{where} mesh scale", (1, 1, 1))
        return Collision("mesh", scale, origin, mesh)
    raise RobotFileError(f"{where}: unsupported collision geometry <{shape.tag}>, expected box, sphere, cylinder or mesh")


def _parse_link(element: ET.Element, label: str, urdf_dir: Path) -> Link:
    name = element.get("name")
    where = f"{label}: link {name!r}"
    link = Link(name=name)
    inertial = element.find("inertial")
    if inertial is not None:
        link.has_inertial = True
        mass_el = inertial.find("mass")
        link.mass = _floats(mass_el.get("value") if mass_el is not None else None, 1, f"{where} mass")[0]
        frame = _origin(inertial.find("origin"), f"{where} inertial")
        link.com = frame[:3, 3].copy()
        inertia_el = inertial.find("inertia")
        if inertia_el is None:
            raise RobotFileError(f"{where}: <inertial> without <inertia>")
        names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        ixx, ixy, ixz, iyy, iyz, izz = (_floats(inertia_el.get(k, "0"), 1, f"{where} inertia {k}")[0] for k in names)
        local = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        link.inertia = frame[:3, :3] @ local @ frame[:3, :3].T
    for index, collision in enumerate(element.findall("collision")):
        link.collisions.append(_parse_collision(collision, f"{where} collision {index}", urdf_dir))
    return link


def _parse_joint(element: ET.Element, label: str, links: dict[str, Link]) -> Joint:
    name = element.get("name")
    where = f"{label}: joint {name!r}"
    jtype = element.get("type")
    if jtype not in ("fixed", "revolute", "continuous", "prismatic", "floating", "planar"):
        raise RobotFileError(f"{where}: type {jtype!r}, expected revolute, continuous, prismatic or fixed")
    parent, child = element.find("parent"), element.find("child")
    if parent is None or child is None:
        raise RobotFileError(f"{where}: missing <parent> or <child>")
    for end in (parent.get("link"), child.get("link")):
        if end not in links:
            raise RobotFileError(f"{where}: refers to link {end!r}, which the file does not define")
    axis_el = element.find("axis")
    axis = np.array(_floats(axis_el.get("xyz") if axis_el is not None else None, 3, f"{where} axis", (1, 0, 0)))
    if jtype in MOVING_TYPES and norm(axis) < 1e-9:
        raise RobotFileError(f"{where}: zero joint axis")
    joint = Joint(name, jtype, parent.get("link"), child.get("link"), _origin(element.find("origin"), where), axis)
    limit = element.find("limit")
    if limit is not None:
        for key in ("lower", "upper", "effort", "velocity"):
            if limit.get(key) is not None:
                setattr(joint, key, _floats(limit.get(key), 1, f"{where} limit {key}")[0])
    return joint


def parse_urdf(path: str | Path, text: str | None = None) -> UrdfTree:
    """Parse a URDF file (or ``text`` labelled with ``path``) into a `UrdfTree`."""
    path = Path(path)
    label = str(path)
    if text is None:
        if not path.is_file():
            raise RobotFileError(f"{label}: no such URDF file")
        text = path.read_text(encoding="utf-8", errors="replace")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(f"{label}: not valid XML ({exc})") from None
    if root.tag != "robot":
        raise RobotFileError(f"{label}: root element <{root.tag}>, expected <robot>")
    links: dict[str, Link] = {}
    for element in root.findall("link"):
        link = _parse_link(element, label, path.parent)
        if link.name in links:
            raise RobotFileError(f"{label}: link {link.name!r} defined twice")
        links[link.name] = link
    if not links:
        raise RobotFileError(f"{label}: no <link> elements")
    joints: dict[str, Joint] = {}
    for element in root.findall("joint"):
        joint = _parse_joint(element, label, links)
        joints[joint.name] = joint
    tree = UrdfTree(path=path, name=root.get("name") or path.stem, links=links, joints=joints)
    parent_of: dict[str, str] = {}
    for joint in joints.values():
        if joint.child in parent_of:
            raise RobotFileError(
                f"{label}: link {joint.child!r} has two parent joints ({parent_of[joint.child]!r} and {joint.name!r}); "
                "a URDF must be a tree: remove one of them"
            )
        parent_of[joint.child] = joint.name
    for start in links:  # a loop: following parents from a link comes back to it
        seen, link = [start], start
        while link in parent_of:
            link = joints[parent_of[link]].parent
            if link == start:
                raise RobotFileError(
                    f"{label}: joints form a loop through link {start!r} ({' -> '.join(seen)} -> {start}); a URDF must be a tree"
                )
            if link in seen:
                break
            seen.append(link)
    roots = [n for n in links if n not in parent_of]
    if len(roots) != 1:
        raise RobotFileError(f"{label}: {len(roots)} root links ({', '.join(roots)}), expected exactly one")
    return tree


# --------------------------------------------------------------------------- editing
def _combine(a_mass, a_com, a_inertia, b_mass, b_com, b_inertia):
    """Mass, CoM and inertia about the CoM of two rigid bodies in one frame."""
    mass = a_mass + b_mass
    if mass <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = (a_mass * a_com + b_mass * b_com) / mass
    total = np.zeros((3, 3))
    for m, c, inertia in ((a_mass, a_com, a_inertia), (b_mass, b_com, b_inertia)):
        d = c - com
        total += inertia + m * (dot(d, d) * np.eye(3) - np.outer(d, d))
    return mass, com, total


def merge_fixed_joints(tree: UrdfTree, keep_links: set[str]) -> UrdfTree:
    """Fold every fixed joint's child link into its parent, except links in ``keep_links``.

    Inertials combine exactly (parallel-axis theorem), collisions and child
    joints are re-expressed in the parent frame, so total mass, whole-body CoM
    and the kinematics are unchanged. Returns a new tree.
    """
    tree = tree.copy()
    while True:
        joint = next(
            (j for j in tree.joints.values() if j.type == "fixed" and j.child not in keep_links),
            None,
        )
        if joint is None:
            return tree
        parent, child = tree.links[joint.parent], tree.links[joint.child]
        rot, pos = joint.origin[:3, :3], joint.origin[:3, 3]
        child_com = rot @ child.com + pos
        child_inertia = rot @ child.inertia @ rot.T
        parent.mass, parent.com, parent.inertia = _combine(
            parent.mass, parent.com, parent.inertia, child.mass, child_com, child_inertia
        )
        parent.has_inertial = parent.has_inertial or child.has_inertial
        for collision in child.collisions:
            parent.collisions.append(dataclasses.replace(collision, origin=joint.origin @ collision.origin))
        parent.merged += [child.name, *child.merged]
        for grandchild in tree.child_joints(child.name):
            grandchild.parent = parent.name
            grandchild.origin = joint.origin @ grandchild.origin
        del tree.joints[joint.name]
        del tree.links[child.name]


def rotate_root(tree: UrdfTree, rotation) -> UrdfTree:
    """A copy of ``tree`` whose root link frame is turned by ``rotation`` (3, 3): new = R · old.

    The root's inertial, collisions and child joints are re-expressed, so the
    robot is unchanged but its root frame axes are R's rows (e.g. a y-up file made z-up).
    """
    rot = np.asarray(rotation, dtype=float).reshape(3, 3)
    if np.allclose(rot, np.eye(3)):
        return tree
    tree = tree.copy()
    turn = np.eye(4)
    turn[:3, :3] = rot
    root = tree.links[tree.root]
    root.com = rot @ root.com
    root.inertia = rot @ root.inertia @ rot.T
    root.collisions = [dataclasses.replace(c, origin=turn @ c.origin) for c in root.collisions]
    for joint in tree.child_joints(root.name):
        joint.origin = turn @ joint.origin
    return tree


# --------------------------------------------------------------------------- writing
def _fmt(values) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.atleast_1d(values))


def _origin_xml(matrix: np.ndarray) -> str:
    return f'<origin xyz="{_fmt(matrix[:3, 3])}" rpy="{_fmt(matrix_to_rpy(matrix[:3, :3]))}"/>'


def _geometry_xml(collision: Collision) -> str:
    if collision.kind == "box":
        return f'<box size="{_fmt(collision.size)}"/>'
    if collision.kind == "sphere":
        return f'<sphere radius="{_fmt(collision.size[0])}"/>'
    if collision.kind == "cylinder":
        return f'<cylinder radius="{_fmt(collision.size[0])}" length="{_fmt(collision.size[1])}"/>'
    return f'<mesh filename="{collision.mesh}" scale="{_fmt(collision.size)}"/>'


def write_urdf(tree: UrdfTree) -> str:
    """URDF text of ``tree``: inertials (CoM frame unrotated), collisions, joints. No visuals."""
    lines = [f'<robot name="{tree.name}">']
    for link in tree.links.values():
        lines.append(f'  <link name="{link.name}">')
        if link.has_inertial:
            i = link.inertia
            lines += [
                "    <inertial>",
                f'      <origin xyz="{_fmt(link.com)}" rpy="0 0 0"/>',
                f'      <mass value="{float(link.mass):.12g}"/>',
                f'      <inertia ixx="{i[0, 0]:.12g}" ixy="{i[0, 1]:.12g}" ixz="{i[0, 2]:.12g}" '
                f'iyy="{i[1, 1]:.12g}" iyz="{i[1, 2]:.12g}" izz="{i[2, 2]:.12g}"/>',
                "    </inertial>",
            ]
        for collision in link.collisions:
            lines += [
                "    <collision>",
                f"      {_origin_xml(collision.origin)}",
                f"      <geometry>{_geometry_xml(collision)}</geometry>",
                "    </collision>",
            ]
        lines.append("  </link>")
    for joint in tree.joints.values():
        lines.append(f'  <joint name="{joint.name}" type="{joint.type}">')
        lines.append(f"    {_origin_xml(joint.origin)}")
        lines.append(f'    <parent link="{joint.parent}"/>')
        lines.append(f'    <child link="{joint.child}"/>')
        if joint.type in MOVING_TYPES:
            lines.append(f'    <axis xyz="{_fmt(joint.axis)}"/>')
            attrs = " ".join(
                f'{key}="{getattr(joint, key):.12g}"'
                for key in ("lower", "upper", "effort", "velocity")
                if getattr(joint, key) is not None
            )
            lines.append(f"    <limit {attrs}/>")
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
