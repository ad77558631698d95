"""Where a robot file's legs are and which way is up: pure derivation from the URDF's kinematic tree.

`upright_rotation` turns a file whose base frame is not z-up, x-forward (limbs hanging along another axis) into
one that is; `leg_candidates` lists the limbs that hang down; `infer_legs` names them (FL, FR, RL, RR or L, R)
for `frbench.robots.infer`, or says in one line which sidecar key would name them.
"""

from __future__ import annotations

import re

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.kinematics import link_poses
from frbench.robots.urdf_tree import MOVING_TYPES, UrdfTree

#: A limb hanging lower than this fraction of the lowest leaf's drop is a leg.
LEG_DROP_FRACTION = 0.5
#: [m] when no limb hangs lower than this at the zero pose, the legs are drawn level with the body.
FLAT_DROP = 0.02


def limb_chains(tree: UrdfTree) -> list[tuple[str, list[str]]]:
    """(leaf link, moving joints from the root to it) for every leaf."""
    out = []
    parents = {j.parent for j in tree.joints.values()}
    for leaf in tree.links:
        if leaf in parents:
            continue
        joints, joint = [], tree.parent_joint(leaf)
        while joint is not None:
            if joint.type in MOVING_TYPES:
                joints.append(joint.name)
            joint = tree.parent_joint(joint.parent)
        out.append((leaf, joints[::-1]))
    return out


def hanging_limbs(tree: UrdfTree) -> list[tuple[str, list[str], float]]:
    """One (lowest leaf, moving joints, drop below the root at the zero pose [m]) per last moving joint."""
    poses = link_poses(tree, {})
    by_last: dict[str, tuple[str, list[str], float]] = {}
    for leaf, joints in limb_chains(tree):
        if not joints:
            continue
        drop = -float(poses[leaf][2, 3])
        if joints[-1] not in by_last or drop > by_last[joints[-1]][2]:
            by_last[joints[-1]] = (leaf, joints, drop)
    return list(by_last.values())


_FRONT = re.compile(r"(^|[^a-z])(front|f[lr]|[lr]f)([^a-z]|$)")


def upright_rotation(tree: UrdfTree) -> np.ndarray:
    """R (3, 3) turning the root frame so the legs hang along −z and the body's long axis is x (identity if they do).

    Files drawn y-up (pybullet_data's laikago) have their legs along −y at the
    zero pose; the leg direction is snapped to the nearest axis, the long axis
    of the feet's footprint becomes x, pointing to the legs whose names say
    front (FL, LF, front, ...).

    A biped (two leg candidates, `leg_candidates`, hanging below the root) is
    judged by its legs alone, so hands reaching forward do not tip it
    (G1 with hands), and is turned about z so that the leg whose names say
    left is at +y (iCub's root frame has x backward and y to the right).
    """
    limbs = [limb for limb in hanging_limbs(tree) if len(limb[1]) >= 3]
    if not limbs:
        return np.eye(3)
    poses = link_poses(tree, {})
    biped = _biped_rotation(tree, limbs, poses)
    if biped is not None:
        return biped
    feet = np.array([poses[leaf][:3, 3] for leaf, _, _ in limbs])
    mean = feet.mean(axis=0)
    axis = int(np.argmax(np.abs(mean)))
    if np.linalg.norm(mean) < 1e-6 or (axis == 2 and mean[2] < 0):
        return np.eye(3)
    up = np.zeros(3)
    up[axis] = -np.sign(mean[axis])
    others = [k for k in range(3) if k != axis]
    drops = -(feet @ up)
    lowest = [i for i in range(len(limbs)) if drops[i] > LEG_DROP_FRACTION * drops.max()]
    if len(lowest) == 2:  # a biped: its feet spread sideways; left is where the leg named left is
        side_axis = max(others, key=lambda k: abs(feet[lowest[0], k] - feet[lowest[1], k]))
        left = np.zeros(3)
        left[side_axis] = 1.0
        named_left = [i for i in lowest if re.search(r"(^|[^a-z])(left|l)([^a-z]|$)|^l", " ".join([limbs[i][0], *limbs[i][1]]).lower())]
        if named_left and feet[named_left[0], side_axis] < feet[[i for i in lowest if i not in named_left] or lowest, side_axis].mean():
            left = -left
        return np.array([np.cross(left, up), left, up])
    forward_axis = max(others, key=lambda k: np.ptp(feet[:, k]))
    forward = np.zeros(3)
    forward[forward_axis] = 1.0
    front = [i for i, (leaf, joints, _) in enumerate(limbs) if _FRONT.search(" ".join([leaf, *joints]).lower())]
    if front and feet[front, forward_axis].mean() < feet[:, forward_axis].mean():
        forward = -forward
    return np.array([forward, np.cross(up, forward), up])


def _named_left(limb) -> bool:
    leaf, joints = limb[0], limb[1]
    return bool(re.search(r"(^|[^a-z])(left|l)([^a-z]|$)|^l", " ".join([leaf, *joints]).lower()))


def _unbranched(limbs):
    """The limbs whose first joint starts no other limb's branch: one limb per first joint.

    Limbs that share their first joint are one limb when each is a stretch of the longest
    (sensor and collision frames hanging off a leg's hip or knee: Romeo, Alexander); they
    branch when they part ways (arms off a waist, fingers off a wrist), and then none counts.
    """
    out = []
    for first in dict.fromkeys(joints[0] for _, joints, _ in limbs):
        same = [limb for limb in limbs if limb[1][0] == first]
        longest = max(same, key=lambda limb: len(limb[1]))
        if all(limb[1] == longest[1][: len(limb[1])] for limb in same):
            out.append(longest)
    return out


def _biped_rotation(tree: UrdfTree, limbs, poses) -> np.ndarray | None:
    """The rotation of `upright_rotation` for a biped, or None when the limbs that are no arms are not two legs."""
    own = _unbranched(limbs)
    if len(own) < 2:
        return None
    feet = np.array([poses[leaf][:3, 3] for leaf, _, _ in own])
    mean = feet.mean(axis=0)
    axis = int(np.argmax(np.abs(mean)))
    if np.linalg.norm(mean) < 1e-6:
        return None
    up = np.zeros(3)
    up[axis] = -np.sign(mean[axis])
    drops = -(feet @ up)
    lowest = [own[i] for i in range(len(own)) if drops[i] > LEG_DROP_FRACTION * drops.max()]
    if len(lowest) != 2:
        return None
    low = np.array([poses[leaf][:3, 3] for leaf, _, _ in lowest])
    side_axis = max((k for k in range(3) if k != axis), key=lambda k: abs(low[0, k] - low[1, k]))
    left = np.zeros(3)
    left[side_axis] = 1.0
    named = [i for i in range(2) if _named_left(lowest[i])]
    if len(named) == 1 and low[named[0], side_axis] < low[1 - named[0], side_axis]:
        left = -left
    return np.array([np.cross(left, up), left, up])


def leg_candidates(tree: UrdfTree) -> list[tuple[str, list[str]]]:
    """(foot link, joints) of every limb that is a leg (module docstring)."""
    limbs = _unbranched([limb for limb in hanging_limbs(tree) if len(limb[1]) >= 3])  # arms and fingers share a waist or shoulder joint
    if not limbs:
        return []
    lowest = max(drop for _, _, drop in limbs)
    if lowest < FLAT_DROP:  # legs drawn level with the body at the zero pose: every long limb is a leg
        return [(leaf, joints) for leaf, joints, _ in limbs]
    return [(leaf, joints) for leaf, joints, drop in limbs if drop > LEG_DROP_FRACTION * lowest]


def infer_legs(tree: UrdfTree, kind: str | None, label: str) -> tuple[str, dict[str, tuple[list[str], str]]]:
    """(kind, leg name → (joints, foot link)) from the tree; refuses counts other than 4 or 2."""
    legs = leg_candidates(tree)
    if kind is None:
        kind = {4: "quadruped", 2: "humanoid"}.get(len(legs))
    wanted = {"quadruped": 4, "humanoid": 2}.get(kind)
    if kind is None or len(legs) != wanted:
        found = ", ".join(leaf for leaf, _ in legs) or "none"
        what = f"a {kind} needs {wanted}" if kind else "a quadruped needs 4, a humanoid 2"
        raise RobotFileError(
            f"{tree.path}: found {len(legs)} legs ({found}), chains of at least 3 moving joints hanging below the "
            f"root; {what}: name them in the sidecar's [legs] table (and set kind)"
        )
    poses = link_poses(tree, {})
    named: dict[str, tuple[list[str], str]] = {}
    for leaf, joints in legs:
        joints = joints[-3:] if kind == "quadruped" else joints
        x, y = poses[tree.joints[joints[0]].child][:2, 3]
        leg = (("F" if x > 0 else "R") + ("L" if y > 0 else "R")) if kind == "quadruped" else ("left" if y > 0 else "right")
        if leg in named:
            raise RobotFileError(
                f"{label}: two legs sit at the {leg} {'corner' if kind == 'quadruped' else 'side'} "
                f"({named[leg][1]} and {leaf}); name them in the sidecar's [legs] table"
            )
        # a humanoid's lowest leaf is often a frame without geometry (Talos' sole_link, iCub's frames): its foot
        # is then the link its last joint moves, fixed children merged in, where the sole's geometry sits
        foot = leaf if kind == "quadruped" or tree.links[leaf].collisions else tree.joints[joints[-1]].child
        named[leg] = (joints, foot)
    return kind, named
