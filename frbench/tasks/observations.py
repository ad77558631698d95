"""What a policy sees: proprioception as named arrays, plus the privileged view for training.

Proprioception (the paper's o_t, 42 values for a quadruped), each (N, k):

* ``base_angvel`` [rad/s], body frame (3);
* ``projected_gravity`` the unit gravity direction in the body frame (3):
  (0, 0, −1) when upright, (0, 0, +1) on the back;
* ``joint_pos`` [rad] (n_joints), canonical order;
* ``joint_vel`` [rad/s] (n_joints);
* ``previous_action`` the joint targets q* [rad] sent at the previous step
  (the default pose at t = 0) (n_joints).

Optional sensor noise (off by default) is uniform with the scales of
`NOISE_SCALES`, drawn from a generator passed in.

The math is written once for numpy and torch (`frbench.arrays`): evaluation passes numpy arrays (the
numbers are bit for bit those of the numpy-only code before), the device training path
(`frbench.training.env` on MuJoCo Warp) torch tensors that stay on their device.
"""

from __future__ import annotations

import numpy as np

from frbench.backends.base import RobotState
from frbench.arrays import like, namespace

PROPRIOCEPTION_KEYS = ("base_angvel", "projected_gravity", "joint_pos", "joint_vel", "previous_action")
#: Half-widths of uniform sensor noise, per key (legged_gym's values).
NOISE_SCALES = {"base_angvel": 0.2, "projected_gravity": 0.05, "joint_pos": 0.01, "joint_vel": 1.5}


#: Column orders of a cross product: (a × b)_i = a[NEXT_i] b[PREV_i] − a[PREV_i] b[NEXT_i].
_NEXT, _PREV = (1, 2, 0), (2, 0, 1)


def cross_rows(a, b):
    """Row-wise cross products of (…, 3) arrays (numpy or torch, `frbench.arrays`): the products and
    differences ``np.cross`` computes, one column at a time (without its axis handling)."""
    xp = namespace(a, b)
    return xp.stack([a[..., i] * b[..., j] - a[..., j] * b[..., i] for i, j in zip(_NEXT, _PREV)], axis=-1)


def rotate_to_body(quat, vectors):
    """World vectors (N, 3) (or one (1, 3), broadcast) expressed in the body frames of quaternions (N, 4) wxyz;
    numpy arrays or torch tensors (on their device)."""
    w, xyz = quat[..., :1], quat[..., 1:]
    # v_body = R^T v = v - 2 w (u × v) + 2 u × (u × v), with u = xyz (rotation by the conjugate)
    t = 2.0 * cross_rows(xyz, vectors)
    return vectors - w * t + cross_rows(xyz, t)


def projected_gravity(quat):
    """Unit gravity direction in the body frame, (N, 3), of quaternions (N, 4) wxyz (numpy or torch)."""
    xp = namespace(quat)
    down = xp.zeros_like(quat[..., 1:])  # (0, 0, −1) per row, made where ``quat`` lives
    down[..., 2] = -1.0
    return rotate_to_body(quat, down)


def proprioception(
    state: RobotState, previous_action, noise_rng: np.random.Generator | None = None, gravity=None,
) -> dict:
    """The policy's observation dict (see the module docstring); ``gravity`` (N, 3): `projected_gravity` of
    ``state.base_quat`` when the caller has it already (it is copied). ``state``'s arrays may be numpy arrays
    or torch tensors (the device training path); the noise, drawn from a numpy generator, only for numpy."""
    xp = namespace(state.base_angvel)
    obs = {
        "base_angvel": xp.asarray(state.base_angvel, copy=True),
        "projected_gravity": projected_gravity(state.base_quat) if gravity is None else xp.asarray(gravity, copy=True),
        "joint_pos": xp.asarray(state.q, copy=True),
        "joint_vel": xp.asarray(state.qd, copy=True),
        "previous_action": xp.asarray(like(previous_action, state.q), copy=True),
    }
    if noise_rng is not None:
        for key, scale in NOISE_SCALES.items():
            obs[key] = obs[key] + noise_rng.uniform(-scale, scale, size=obs[key].shape)
    return obs


def flatten(obs: dict, default_pose):
    """The paper's o_t (N, 6 + 3·n_joints): [ω, g, q − q̊, q̇, a_{t−1} − q̊] (42 for a quadruped); numpy or
    torch, ``default_pose`` (n_joints,) in the same namespace or a numpy array / sequence."""
    xp = namespace(obs["joint_pos"])
    default_pose = like(default_pose, obs["joint_pos"])
    return xp.concat(
        [
            obs["base_angvel"],
            obs["projected_gravity"],
            obs["joint_pos"] - default_pose,
            obs["joint_vel"],
            obs["previous_action"] - default_pose,
        ],
        axis=1,
    )


#: Bounds of the body angular velocity [rad/s] and joint velocities [rad/s] in the Gymnasium observation space
#: (values beyond them are clipped).
MAX_ANGULAR_VELOCITY, MAX_JOINT_VELOCITY = 50.0, 50.0


def observation_bounds(spec) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of the Gymnasium observation o_t, each (6 + 3·n_joints,) float32: ±`MAX_ANGULAR_VELOCITY`, ±1
    for gravity, the joint range around q̊, ±`MAX_JOINT_VELOCITY`, the joint range around q̊ again."""
    default = np.asarray(spec.default_pose)
    lower, upper = np.asarray(spec.joint_lower) - default, np.asarray(spec.joint_upper) - default
    n = spec.n_joints
    high = np.concatenate([np.full(3, MAX_ANGULAR_VELOCITY), np.ones(3), upper, np.full(n, MAX_JOINT_VELOCITY), upper])
    low = np.concatenate([np.full(3, -MAX_ANGULAR_VELOCITY), -np.ones(3), lower, np.full(n, -MAX_JOINT_VELOCITY), lower])
    return low.astype(np.float32), high.astype(np.float32)
