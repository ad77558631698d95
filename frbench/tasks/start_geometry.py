"""The lowest collision point and the horizontal reach of a robot in a drawn start, for placing it above the terrain.

`StartGeometry.lowest_offset_and_reach` computes what `frbench.robots.kinematics.link_poses` and
`lowest_point` give for one configuration, with the same floating-point operations in the same order (every
4 × 4 product, the same rotation entries, the same norms), so the drawn starts are bit-identical; what does not
depend on the joint angles (the traversal, unit joint axes, box corners) is prepared once per robot instead of
at every draw. Python float and numpy float64 arithmetic are both IEEE double with one rounding per operation,
so the rotation entries are formed from Python floats.
"""

from __future__ import annotations

import numpy as np

from frbench.portable_products import norm, unit
from frbench.robots.urdf_tree import UrdfTree

#: Corner signs of a box, in `frbench.robots.kinematics.lowest_point`'s order (8, 3).
_BOX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
_IDENTITY = np.eye(4)
#: Reach margin [m] added to the farthest link origin (`frbench.tasks.initial_states`).
REACH_MARGIN_M = 0.15


class StartGeometry:
    """One robot's forward kinematics for start placement.

    Args:
        tree: the robot's simulation URDF tree.
        joint_names: the canonical joint order of the angle vectors passed to `lowest_offset_and_reach`.
    """

    def __init__(self, tree: UrdfTree, joint_names):
        column = {name: i for i, name in enumerate(joint_names)}
        #: (parent link, child link, joint origin (4, 4), kind, unit axis, column of q or -1), parents first
        self.chain = []
        pending = [tree.root]
        while pending:  # `link_poses`' traversal
            parent = pending.pop()
            for joint in tree.child_joints(parent):
                kind = {"revolute": "rotate", "continuous": "rotate", "prismatic": "slide"}.get(joint.type, "fixed")
                if kind == "rotate":
                    axis = tuple(float(v) for v in unit(joint.axis))
                else:
                    axis = unit(joint.axis)
                self.chain.append((parent, joint.child, joint.origin, kind, axis, column.get(joint.name, -1)))
                pending.append(joint.child)
        self.root = tree.root
        #: per link in file order: [(kind, origin (4, 4), data)] with data the radius (sphere), the corner
        #: offsets (8, 3) (box) or (radius, length) (cylinder)
        self.collisions = []
        for name, link in tree.links.items():
            shapes = []
            for collision in link.collisions:
                if collision.kind == "sphere":
                    shapes.append(("sphere", collision.origin, collision.size[0]))
                elif collision.kind == "box":
                    shapes.append(("box", collision.origin, _BOX_SIGNS * (np.asarray(collision.size) / 2)))
                elif collision.kind == "cylinder":
                    shapes.append(("cylinder", collision.origin, tuple(collision.size)))
            self.collisions.append((name, shapes))

    def link_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Transforms (4, 4) of every link with the root at the identity, at joint angles ``q`` (n_joints,)
        [rad] (`frbench.robots.kinematics.link_poses` of the same angles, bit for bit)."""
        poses = {self.root: _IDENTITY}
        for parent, child, origin, kind, axis, k in self.chain:
            angle = q[k] if k >= 0 else 0.0
            if kind == "rotate":
                motion = _rotation4(axis, angle)
            elif kind == "slide":
                motion = np.eye(4)
                motion[:3, 3] = axis * angle
            else:
                motion = _IDENTITY
            poses[child] = poses[parent] @ origin @ motion
        return poses

    def lowest_offset_and_reach(self, rotation: np.ndarray, q: np.ndarray) -> tuple[float, float]:
        """(lowest collision point z relative to the base [m], horizontal reach [m]) with the base rotated by
        ``rotation`` (4, 4) (translation zero) and the joints at ``q`` (n_joints,) [rad]."""
        world = {name: rotation @ pose for name, pose in self.link_poses(q).items()}
        lowest = np.inf
        for name, shapes in self.collisions:
            pose = world[name]
            lowest = min(lowest, pose[2, 3])
            for kind, origin, data in shapes:
                placed = pose @ origin
                if kind == "sphere":
                    lowest = min(lowest, placed[2, 3] - data)
                elif kind == "box":
                    lowest = min(lowest, float(np.min((placed[:3, :3] @ data.T)[2] + placed[2, 3])))
                else:
                    radius, length = data
                    axis = placed[:3, 2]
                    ends = placed[2, 3] + np.array([-1, 1]) * axis[2] * length / 2
                    lowest = min(lowest, float(np.min(ends) - radius * np.sqrt(max(0.0, 1 - axis[2] ** 2))))
        reach = max(_planar_norm(pose) for pose in world.values()) + REACH_MARGIN_M
        return float(lowest), reach


def _rotation4(axis: tuple[float, float, float], angle) -> np.ndarray:
    """The (4, 4) transform of a rotation by ``angle`` [rad] about the unit ``axis``: the entries of
    `frbench.robots.kinematics._axis_rotation` (np.cos and np.sin of the same angle, then the same products)."""
    x, y, z = axis
    c, s = float(np.cos(angle)), float(np.sin(angle))
    t = 1 - c
    return np.array([
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0.0],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0.0],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ])


def _planar_norm(pose: np.ndarray):
    """|(x, y)| [m] of a transform's translation (`frbench.portable_products.norm`)."""
    return norm(pose[:2, 3])
