"""The training env's observation groups beyond proprioception: the critic's privileged view and the labels.

`PrivilegedGroups` is what training passes the core env (`frbench.tasks.core_env.CoreEnv`, ``privileged``):
called on it, it reads the episode engine's state, contacts and physics and the batch's robots and terrain, and
gives per environment (N rows, J joints, G mass groups, C contact groups, F feet):

* ``privileged`` s_t: [o_t, height scan clipped to ±1 m, group masses [kg] (G), Kp (J), Kd (J), CoM xy in the
  base yaw frame [m] (2), contact flags (C), foot force norms / 100 N, capped at 500 N (F), friction (1)];
* ``mass`` (G) and ``contact`` (C): the estimator's labels; ``velocity`` (3): base linear velocity, body
  frame [m/s]; ``extrinsics`` (G + 8): RMA's environment factors (masses, mean Kp / 50, mean Kd, mean motor
  strength, friction, payload, CoM xy).

The core env adds ``policy`` and the histories and cleans every group (`CoreEnv.observation_groups`).
"""

from __future__ import annotations

import numpy as np

from frbench.arrays import float_dtype, namespace, resident
from frbench.tasks.observations import rotate_to_body
from frbench.training.population import yaw_of
from frbench.training.turned_groups import turned_groups

#: Largest foot force [N] the critic sees, and its scale [N].
FOOT_FORCE_CAP_N, FOOT_FORCE_SCALE_N = 500.0, 100.0


def privileged_groups(o_t, scan, masses, kp, kd, com_xy, group_contact, foot_force, friction, motor_strength,
                      payload, base_quat, base_linvel) -> dict:
    """The groups of the module docstring from their parts, numpy arrays or torch tensors on one device (the
    training env assembles them here, in this order, whatever its arrays): o_t (N, 6 + 3J), the height scan
    (N, 187) [m], group masses (N, G) [kg], Kp and Kd (N, J), CoM xy in the base yaw frame (N, 2) [m], contact
    flags (N, C) bool, foot force norms (N, F) [N], friction, motor strength (N, J), payload (N,) [kg], base
    quaternion (N, 4) wxyz and linear velocity (N, 3) [m/s], world frame."""
    xp = namespace(o_t)
    contact = xp.astype(group_contact, float_dtype(xp, o_t))
    privileged = xp.concat([
        o_t, xp.clip(scan, -1.0, 1.0), masses, kp, kd, com_xy,
        contact, xp.minimum(foot_force, FOOT_FORCE_CAP_N) / FOOT_FORCE_SCALE_N, friction[:, None],
    ], axis=1)
    velocity = rotate_to_body(base_quat, base_linvel)
    extrinsics = xp.concat([
        masses, xp.mean(kp, axis=1, keepdims=True) / 50, xp.mean(kd, axis=1, keepdims=True),
        xp.mean(motor_strength, axis=1, keepdims=True), friction[:, None], payload[:, None], com_xy,
    ], axis=1)
    return {"privileged": privileged, "mass": masses, "contact": contact, "velocity": velocity,
            "extrinsics": extrinsics}


class PrivilegedGroups:
    """The groups above for the batch's ``robots`` (`population.TrainingRobots`) on the tiles ``starts`` put
    them on (`start_sources.CurriculumStarts`, ``tile_row``), the height scan from ``raster``
    (`height_raster.HeightRaster`); with the learner's ``frame`` a `BatchJointFrame` that turns some robots
    around, their rows seen from their canonical front (`turned_groups`)."""

    def __init__(self, raster, starts, robots, frame=None):
        self.raster, self.starts, self.robots = raster, starts, robots
        turned = getattr(frame, "turned", None)
        #: (N,) bool rows of turned robots, or None (no row is)
        self.turned = turned if isinstance(turned, np.ndarray) and turned.any() else None

    def __call__(self, env, o_t):
        """Each group (N, ·) of the core env ``env`` now, its policy observation ``o_t`` (N, 6 + 3J) given (see the
        module docstring): float64 numpy arrays, or torch tensors on the device of the env's arrays."""
        s, c, p = env.state, env.contacts, env.params.like(o_t)
        scan = self.raster.scan(self.starts.tiles(o_t), s.base_pos, yaw_of(s.base_quat))
        com_xy = self.robots.com_xy(s, env.whole_body_com())
        groups = privileged_groups(o_t, scan, resident(self.robots.env_masses, o_t), p.kp, p.kd, com_xy,
                                   c.group_contact, c.foot_force, p.friction, p.motor_strength, p.payload, s.base_quat,
                                   s.base_linvel)
        if self.turned is None:
            return groups
        return turned_groups(groups, self.turned, o_t.shape[1], self.robots.env_masses.shape[1], p.kp.shape[1])
