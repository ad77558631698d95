"""The training env's observation groups beyond proprioception: the critic's privileged view and the labels.

From the episode engine's state, contacts and physics (`frbench.tasks.recovery.RecoveryTask`), per
environment (N rows, J joints, G mass groups, C contact groups, F feet):

* ``privileged`` s_t: [o_t, height scan clipped to ±1 m, group masses [kg] (G), Kp (J), Kd (J), CoM xy in the
  base yaw frame [m] (2), contact flags (C), foot force norms / 100 N, capped at 500 N (F), friction (1)];
* ``mass`` (G) and ``contact`` (C): the estimator's labels; ``velocity`` (3): base linear velocity, body
  frame [m/s]; ``extrinsics`` (G + 8): RMA's environment factors (masses, mean Kp / 50, mean Kd, mean motor
  strength, friction, payload, CoM xy).

A diverged environment's rows are zeros; NaN and infinities become zeros.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict

from frbench.tasks.observations import rotate_to_body


def observation_groups(o_t: np.ndarray, history: np.ndarray, long_history: np.ndarray | None, state, contacts,
                       params, masses: np.ndarray, com_xy: np.ndarray, scan: np.ndarray,
                       diverged: np.ndarray) -> TensorDict:
    """Every group as float32 tensors (see the module docstring): ``o_t`` (N, 6 + 3J), ``history`` (N, H, ·) and
    ``long_history`` (N, T, ·) or None, the engine's ``state``/``contacts``/``params``, ``masses`` (N, G) [kg],
    ``com_xy`` (N, 2) [m], ``scan`` (N, P) [m], ``diverged`` (N,) bool."""
    s, c, p = state, contacts, params
    n = len(o_t)
    contact = c.group_contact.astype(float)
    privileged = np.concatenate([
        o_t, np.clip(scan, -1.0, 1.0), masses, p.kp, p.kd, com_xy,
        contact, np.minimum(c.foot_force, 500.0) / 100.0, p.friction[:, None],
    ], axis=1)
    velocity = rotate_to_body(s.base_quat, s.base_linvel)
    extrinsics = np.concatenate([
        masses, p.kp.mean(axis=1, keepdims=True) / 50, p.kd.mean(axis=1, keepdims=True),
        p.motor_strength.mean(axis=1, keepdims=True), p.friction[:, None], p.payload[:, None], com_xy,
    ], axis=1)
    groups = {
        "policy": o_t, "history": history.reshape(n, -1), "privileged": privileged,
        "mass": masses, "contact": contact, "velocity": velocity,
        "extrinsics": extrinsics,
    }
    if long_history is not None:
        groups["long_history"] = long_history.reshape(n, -1)
    alive = None if not diverged.any() else ~diverged
    tensors = {key: torch.as_tensor(_zero_invalid(value, alive), dtype=torch.float32) for key, value in groups.items()}
    return TensorDict(tensors, batch_size=[n])


def _zero_invalid(value: np.ndarray, alive: np.ndarray | None) -> np.ndarray:
    """``value`` (N, k) with NaN and infinities as zeros, and the rows not ``alive`` (N,) zero (None: all are
    alive); a float64 ``value`` itself when nothing changes (its float32 tensor is then a converted copy)."""
    if alive is None and value.dtype == np.float64 and np.isfinite(value).all():
        return value
    cleaned = np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0)
    return cleaned if alive is None else np.where(alive[:, None], cleaned, 0.0)
