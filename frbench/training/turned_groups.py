"""The privileged observation groups of a turned robot, seen from its canonical front.

A robot whose four knees point forward is turned around by its canonical joint frame (`frbench.robots.joint_frame`:
legs FL ↔ RR and FR ↔ RL, body x and y negated), so the learner's o_t sees it from behind. The privileged groups
(`frbench.training.observation_groups`) are computed in the robot's own body frame and leg order; on the rows of
turned robots (wide bodies, `frbench.robots.batch_frame.BatchJointFrame.turned`) `turned_groups` rotates them by
180° about the vertical too, so the critic and the estimator's labels (contacts per leg) follow the canonical
legs and axes:

* the height scan's 17 × 11 grid (symmetric about the base) is reversed in x and y: its point order reverses;
* per-leg blocks (Kp and Kd per joint, contact flags after the base's, foot forces) take the turned leg order;
* the CoM offset and the body-frame linear velocity negate x and y;
* o_t (already canonical), masses, friction and the extrinsics' scalars stay.

Every map is a permutation with signs (numpy arrays or torch tensors alike). Shapes: N rows.
"""

from __future__ import annotations

import numpy as np

from frbench.arrays import is_host, namespace, resident
from frbench.terrains import SCAN_POINTS

#: The leg each canonical leg is on a turned robot (FL ↔ RR, FR ↔ RL).
TURNED_LEG = (3, 2, 1, 0)


def _block(index, sign=None) -> tuple[np.ndarray, np.ndarray]:
    index = np.asarray(index, dtype=np.int64)
    return index, np.ones(len(index)) if sign is None else np.asarray(sign, dtype=float)


def _identity(n: int):
    return _block(np.arange(n))


def _legs(per_leg: int):
    return _block(np.concatenate([TURNED_LEG[leg] * per_leg + np.arange(per_leg) for leg in range(len(TURNED_LEG))]))


def _xy(n: int = 2):
    """A vector whose x and y negate (the first ``n`` of its values; ``n`` = 2 or 3)."""
    return _block(np.arange(n), [-1.0, -1.0, 1.0][:n])


def _scan():
    xs, ys = np.unique(SCAN_POINTS[:, 0]), np.unique(SCAN_POINTS[:, 1])
    if not (np.allclose(xs, -xs[::-1]) and np.allclose(ys, -ys[::-1])):
        raise ValueError("turned groups: the height scan's grid is not symmetric about the base")
    return _block(np.arange(len(SCAN_POINTS))[::-1])


def _concat(*blocks) -> tuple[np.ndarray, np.ndarray]:
    index, sign, offset = [], [], 0
    for i, s in blocks:
        index.append(i + offset)
        sign.append(s)
        offset += len(i)
    return np.concatenate(index), np.concatenate(sign)


def group_turns(o_t: int, masses: int, joints: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Group → (index, sign) of its turned view, for o_t of ``o_t`` values, ``masses`` mass groups and ``joints``
    joints (3 per leg, 4 legs; contact groups: the base, then hip, thigh, calf per leg)."""
    per_leg = joints // len(TURNED_LEG)
    contact = _concat(_identity(1), _legs(per_leg))
    return {
        "privileged": _concat(_identity(o_t), _scan(), _identity(masses), _legs(per_leg), _legs(per_leg), _xy(),
                              contact, _legs(1), _identity(1)),
        "mass": _identity(masses), "contact": contact, "velocity": _xy(3),
        "extrinsics": _concat(_identity(masses + 5), _xy()),
    }


def turned_groups(groups: dict, turned: np.ndarray, o_t: int, masses: int, joints: int) -> dict:
    """``groups`` (each (N, k), numpy or torch) with the rows of ``turned`` (N,) bool robots in their turned view
    (module docstring); groups without a turned view (none here) unchanged."""
    turns = group_turns(o_t, masses, joints)
    out = dict(groups)
    for name, (index, sign) in turns.items():
        if name not in groups:
            continue
        value = groups[name]
        if value.shape[-1] != len(index):
            raise ValueError(f"turned groups: {name} has {value.shape[-1]} values, its turn expects {len(index)}")
        if is_host(value):
            out[name] = np.where(turned[:, None], value[:, index] * sign, value)
        else:
            xp = namespace(value)
            rows = resident(turned, value, xp.bool)
            out[name] = xp.where(rows[:, None], value[:, resident(index, value, xp.int64)] * resident(sign, value),
                                 value)
    return out
