"""Left/right mirror of a quadruped's training observations and actions, for rsl-rl-lib's `Symmetry` extension.

rsl-rl's PPO (``algorithm.symmetry_cfg``) calls :func:`mirror_quadruped` on every mini-batch: with
``use_data_augmentation`` each sample is followed by its mirror image (the policy and value losses see both),
with ``use_mirror_loss`` the actor is penalised for acting differently on mirrored observations (Mittal et al.,
"Symmetry Considerations for Learning Task Symmetric Robot Policies", ICRA 2024).

The mirror is the reflection y → −y of the world seen from the base (frbench's quadruped convention,
`frbench.robots.morphology`: legs FL, FR, RL, RR; hip joints about x, thigh and calf joints about y on both
sides; the standing hip angle mirrored on the right legs). Under it:

* left and right legs swap (FL ↔ FR, RL ↔ RR) in every per-joint, per-leg and per-foot block;
* hip angles, hip velocities and hip actions change sign; thigh and calf ones do not;
* angular velocity (ω_x, ω_y, ω_z) → (−ω_x, ω_y, −ω_z) (a pseudovector); projected gravity, linear velocity
  and the CoM offset (x, y, z) → (x, −y, z);
* the height scan's 17 × 11 grid (x-major, y from −0.5 to 0.5 m) reverses its y index;
* masses, gains' means, friction, payload and the 0/1 validity of a reconstruction target are unchanged.

Every map is a permutation with signs, so it is its own inverse. Each observation group is mirrored by the
layout of `frbench.training.observation_groups` (the o_t of `frbench.training.env`); a group this module does not
know is an error, not silently copied.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict

from frbench.terrains import SCAN_POINTS
from frbench.training.algorithm import NEXT_OBS_GROUP, NEXT_VALID_GROUP

#: Joints per leg and legs of frbench's canonical quadruped order (FL, FR, RL, RR × hip, thigh, calf).
JOINTS_PER_LEG, LEGS = 3, 4
#: The leg each leg becomes in the mirror image.
MIRRORED_LEG = (1, 0, 3, 2)
#: Per-joint signs within a leg: the hip (about x) flips, thigh and calf (about y) do not.
JOINT_SIGNS = (-1.0, 1.0, 1.0)


class SignedPermutation:
    """``y = x[..., index] * sign`` over the last axis; built from (source index, sign) blocks."""

    def __init__(self, index: np.ndarray, sign: np.ndarray):
        self.index = torch.as_tensor(np.asarray(index, dtype=np.int64))
        self.sign = torch.as_tensor(np.asarray(sign, dtype=np.float32))

    def __len__(self) -> int:
        return len(self.index)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] != len(self):
            raise ValueError(f"mirror: expected {len(self)} values in the last axis, got {x.shape[-1]}")
        return x[..., self.index.to(x.device)] * self.sign.to(x.device, x.dtype)

    @staticmethod
    def concat(*parts: "SignedPermutation") -> "SignedPermutation":
        """The blocks side by side (each block's indices shifted past the blocks before it)."""
        index, sign, offset = [], [], 0
        for part in parts:
            index.append(part.index.numpy() + offset)
            sign.append(part.sign.numpy())
            offset += len(part)
        return SignedPermutation(np.concatenate(index), np.concatenate(sign))


def identity(n: int) -> SignedPermutation:
    return SignedPermutation(np.arange(n), np.ones(n))


def vector3(signs: tuple[float, float, float]) -> SignedPermutation:
    return SignedPermutation(np.arange(3), np.array(signs))


#: ω (pseudovector) and a polar vector (gravity, velocity, CoM offset) under y → −y.
ANGULAR, POLAR = vector3((-1.0, 1.0, -1.0)), vector3((1.0, -1.0, 1.0))


def legs(per_leg: int, signs=None) -> SignedPermutation:
    """A per-leg block of ``per_leg`` values per leg (legs in FL, FR, RL, RR order): legs swapped, signed."""
    signs = np.ones(per_leg) if signs is None else np.asarray(signs, dtype=float)
    index = np.concatenate([MIRRORED_LEG[leg] * per_leg + np.arange(per_leg) for leg in range(LEGS)])
    return SignedPermutation(index, np.tile(signs, LEGS))


JOINTS = legs(JOINTS_PER_LEG, JOINT_SIGNS)
#: Gains are positive per joint: legs swap, no sign.
JOINT_GAINS = legs(JOINTS_PER_LEG)


def _height_scan() -> SignedPermutation:
    xs, ys = np.unique(SCAN_POINTS[:, 0]), np.unique(SCAN_POINTS[:, 1])
    if not np.allclose(ys, -ys[::-1]):
        raise ValueError("mirror: the height scan's y coordinates are not symmetric about 0")
    nx, ny = len(xs), len(ys)
    index = (np.arange(nx)[:, None] * ny + (ny - 1 - np.arange(ny))[None, :]).reshape(-1)
    return SignedPermutation(index, np.ones(nx * ny))


#: o_t = [ω (3), g (3), q − q̊ (12), q̇ (12), a_{t−1} (12)].
O_T = SignedPermutation.concat(ANGULAR, POLAR, JOINTS, JOINTS, JOINTS)
#: Contact flags: base, then hip/thigh/calf of each leg.
CONTACT = SignedPermutation.concat(identity(1), legs(3))
#: s_t = [o_t, height scan, group masses (4), Kp (12), Kd (12), CoM xy (2), contacts (13), foot forces (4), friction].
PRIVILEGED = SignedPermutation.concat(O_T, _height_scan(), identity(4), JOINT_GAINS, JOINT_GAINS,
                                      SignedPermutation(np.arange(2), np.array([1.0, -1.0])), CONTACT, legs(1),
                                      identity(1))
#: RMA's e_t = [masses (4), mean Kp / 50, mean Kd, mean strength, friction, payload, CoM xy (2)].
EXTRINSICS = SignedPermutation.concat(identity(9), SignedPermutation(np.arange(2), np.array([1.0, -1.0])))


def group_mirrors() -> dict[str, SignedPermutation | None]:
    """Observation group → its mirror (None: mirrored frame by frame with `O_T`)."""
    return {"policy": O_T, "history": None, "long_history": None, "privileged": PRIVILEGED, "mass": identity(4),
            "contact": CONTACT, "velocity": POLAR, "extrinsics": EXTRINSICS, NEXT_OBS_GROUP: O_T,
            NEXT_VALID_GROUP: identity(1)}


def mirror_group(name: str, value: torch.Tensor, mirrors: dict) -> torch.Tensor:
    """One observation group (B, k) mirrored; frame stacks (B, H·42) frame by frame."""
    if name not in mirrors:
        raise ValueError(f"mirror: no left/right mirror for observation group {name!r}")
    mirror = mirrors[name]
    if mirror is None:
        frames = value.reshape(*value.shape[:-1], -1, len(O_T))
        return O_T(frames).reshape(value.shape)
    return mirror(value)


def check_joint_order(env) -> None:
    """A ValueError unless ``env`` drives 12 joints named by leg in frbench's canonical order (FL, FR, RL, RR ×
    hip, thigh, calf; every randomised morphology and Go2), the order the mirror's indices assume."""
    if getattr(env, "num_actions", len(JOINTS)) != len(JOINTS):
        raise ValueError(f"mirror: a quadruped with {len(JOINTS)} actions is needed, this env has {env.num_actions}")
    spec = getattr(env, "spec", None)
    if spec is None:
        return
    found = [tuple(name.split("_")[:2]) for name in spec.joint_names]
    expected = [(leg, part) for leg in ("FL", "FR", "RL", "RR") for part in ("hip", "thigh", "calf")]
    if found != expected:
        raise ValueError(f"mirror: joints {spec.joint_names} are not in the order FL, FR, RL, RR x hip, thigh, calf")


def mirror_quadruped(env=None, obs: TensorDict | None = None, actions: torch.Tensor | None = None):
    """rsl-rl's data augmentation function: ``(obs, actions)`` with the mirrored samples appended along the batch
    (2B rows: the B originals, then their mirrors); either may be None (then None is returned for it).
    ``env`` must drive 12 actions (a quadruped in frbench's canonical order)."""
    if env is not None:
        check_joint_order(env)
    out_obs = out_actions = None
    if obs is not None:
        mirrors = group_mirrors()
        mirrored = TensorDict({k: mirror_group(k, v, mirrors) for k, v in obs.items()}, batch_size=obs.batch_size)
        out_obs = torch.cat([obs, mirrored], dim=0)
    if actions is not None:
        out_actions = torch.cat([actions, JOINTS(actions)], dim=0)
    return out_obs, out_actions

