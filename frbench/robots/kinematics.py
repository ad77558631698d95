"""Forward kinematics over a `UrdfTree`, for standing heights and leg inference.

Small and numpy-only: robots are trees of a few dozen links, and this runs
once per robot when its spec is built (Pinocchio is the ground truth for
masses and CoM; this module only places link frames).
"""

from __future__ import annotations

import numpy as np

from frbench.portable_products import unit
from frbench.robots.urdf_tree import UrdfTree


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = unit(axis)
    x, y, z = axis
    c, s, t = np.cos(angle), np.sin(angle), 1 - np.cos(angle)
    return np.array(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    )


def link_poses(tree: UrdfTree, q: dict[str, float]) -> dict[str, np.ndarray]:
    """World transforms (4, 4) of every link, root at the identity.

    Args:
        tree: the kinematic tree.
        q: joint angle [rad] (or displacement [m]) per moving joint name;
            missing joints are at 0.
    """
    poses = {tree.root: np.eye(4)}
    pending = [tree.root]
    while pending:
        parent = pending.pop()
        for joint in tree.child_joints(parent):
            local = joint.origin.copy()
            angle = q.get(joint.name, 0.0)
            motion = np.eye(4)
            if joint.type in ("revolute", "continuous"):
                motion[:3, :3] = _axis_rotation(joint.axis, angle)
            elif joint.type == "prismatic":
                motion[:3, 3] = unit(joint.axis) * angle
            poses[joint.child] = poses[parent] @ local @ motion
            pending.append(joint.child)
    return poses


def _axis_rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) about ``axis`` by ``angles`` (N,) (Rodrigues)."""
    x, y, z = unit(axis)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def chain_poses_batch(tree: UrdfTree, link: str, q: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """World transforms (N, 4, 4) of ``link`` and its ancestors for N configurations (joint -> angles (N,)): one leg's FK."""
    n = len(next(iter(q.values()))) if q else 1
    path = [link, *tree.ancestors(link)][::-1]
    poses = {path[0]: np.tile(np.eye(4), (n, 1, 1))}
    for parent, child in zip(path, path[1:]):
        joint = tree.parent_joint(child)
        motion = np.tile(np.eye(4), (n, 1, 1))
        angle = np.broadcast_to(np.asarray(q.get(joint.name, 0.0), dtype=float), (n,))
        if joint.type in ("revolute", "continuous"):
            motion[:, :3, :3] = _axis_rotations(joint.axis, angle)
        elif joint.type == "prismatic":
            motion[:, :3, 3] = unit(joint.axis)[None] * angle[:, None]
        poses[child] = poses[parent] @ joint.origin @ motion
    return poses


def lowest_point(tree: UrdfTree, poses: dict[str, np.ndarray], links) -> float:
    """Lowest z [m] of the links' collision geometry (sphere bottoms, box corners, frame origins)."""
    lowest = np.inf
    for name in links:
        pose = poses[name]
        link = tree.links[name]
        lowest = min(lowest, pose[2, 3])
        for collision in link.collisions:
            world = pose @ collision.origin
            if collision.kind == "sphere":
                lowest = min(lowest, world[2, 3] - collision.size[0])
            elif collision.kind == "box":
                half = np.asarray(collision.size) / 2
                corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
                lowest = min(lowest, float(np.min((world[:3, :3] @ corners.T)[2] + world[2, 3])))
            elif collision.kind == "cylinder":
                radius, length = collision.size
                axis = world[:3, 2]
                # lowest point of a cylinder: end-cap centre minus radius along the horizontal-most direction
                ends = world[2, 3] + np.array([-1, 1]) * axis[2] * length / 2
                lowest = min(lowest, float(np.min(ends) - radius * np.sqrt(max(0.0, 1 - axis[2] ** 2))))
    return float(lowest)


def standing_height(tree: UrdfTree, joint_names, pose, foot_links) -> float:
    """Height [m] of the root frame over flat ground with the feet's lowest point on it."""
    poses = link_poses(tree, dict(zip(joint_names, pose)))
    return -lowest_point(tree, poses, foot_links)


def chain_to_link(spec, link: str) -> tuple[list, list[int]]:
    """The joints of ``spec``'s simulation URDF from its root link to ``link``, root first, and each one's index in
    the canonical joint order (−1 for a joint that does not move); StopIteration when ``link`` has no such chain."""
    from frbench.robots.sim_urdf import sim_robot_file
    from frbench.robots.urdf_tree import parse_urdf

    tree = parse_urdf(sim_robot_file(spec).path)
    chain, child = [], link
    while child != tree.root:
        joint = next(j for j in tree.joints.values() if j.child == child)
        chain.append(joint)
        child = joint.parent
    chain.reverse()
    return chain, [spec.joint_names.index(j.name) if j.type in ("revolute", "continuous") else -1 for j in chain]
