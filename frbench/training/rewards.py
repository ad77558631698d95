"""FR-Net's reward terms (paper, Table "Reward terms for quadrupedal recovery").

Every term is a function of one :class:`RewardInputs` (arrays with N rows, SI
units) returning the **unweighted** term, shape (N,): float64 numpy arrays for
numpy inputs (evaluation, the CPU trainer), torch tensors on the inputs' device
and float dtype for torch inputs (the training env on a device). The terms are written
once against the Array API standard (`frbench.arrays`); the numpy path is
bit for bit the numpy-only code it replaced.
:func:`compute_rewards` weights them with a :class:`RewardConfig` and sums.

====================  =====================================================  ==========
term                  value (unweighted)                                     paper weight
====================  =====================================================  ==========
base_orientation      g_x² + g_y²                                            −0.5
upright_orientation   exp(−(g_z + 1)² / (2 ε²))                              6.0
target_posture        exp(−Σ_j (q_j − q_stand,j)²) if |g_z + 1| < ε else 0   4.0
feet_contact          number of feet in contact                              0.3
body_contact          1 if any non-foot link touches anything else 0         −0.2
safety_force          Σ_knees ‖f^xy‖ [N]                                     −1e−2
body_bias             clip(‖p^xy − p^xy_init‖, 0, 4) [m]                     −0.1
position_limits       number of joints outside [q_lower, q_upper]            −1.0
velocity_limit        Σ_j max(|q̇_j| − 0.8, 0) [rad/s]                         −0.1
joint_acceleration    Σ_j ((q̇_j − q̇_prev,j) / dt)² [rad²/s⁴]                 −2.5e−6
joint_velocity        Σ_j q̇_j² [rad²/s²]                                     −1e−2
action_smoothing      Σ_j (a_t,j − a_t−1,j)²                                 −0.01
joint_torques         Σ_j τ_j² [N²·m²]                                       −5e−4
====================  =====================================================  ==========

``g`` is the projected gravity, the unit gravity direction in the body frame
((0, 0, −1) when upright, (0, 0, +1) on the back).

frbench adds terms the table does not have (each needs a reason in the config):

====================  =====================================================  ==========
term                  value (unweighted)                                     used for
====================  =====================================================  ==========
base_height           clip(h_base / h_nominal, 0, 1)                          all robots
head_height           clip(h_head / h_head,nominal, 0, 1)                     humanoids
feet_on_ground        fraction of feet in contact, 0 while h_base < h_nom/2   humanoids
upper_body_posture    exp(−Σ_upper (q − q_stand)²) if |g_z + 1| < ε else 0    humanoids
action_jerk           Σ_j (a_t − 2 a_t−1 + a_t−2)²  (HoST's smoothness)        humanoids
====================  =====================================================  ==========

Readings where the paper is ambiguous
-------------------------------------
* **ε** (:data:`DEFAULT_EPSILON` = 0.4). The paper writes the upright term with
  σ in the text and ε in the equation and the table, and gates the target
  posture with "|g_z + 1| < ε"; one ε serves both, as in the equation. With
  ε = 0.4 the upright term is 1 upright, 0.61 at 53° of tilt (the edge of the
  posture gate, g_z = −0.6), 0.04 lying on the side (g_z = 0) and
  exp(−4/0.32) ≈ 3.7e−6 on the back, so the gradient spans the whole roll from
  the side to upright, and the posture term switches on below ≈ 53° of tilt.
* **velocity_limit**. The paper writes max(|q̇| − 0.8, 0). Two readings exist:
  0.8 rad/s absolute (literal) or 0.8 × each joint's velocity limit (legged_gym's
  ``soft_dof_vel_limit`` convention). frbench takes the **literal** reading:
  ``RewardConfig.velocity_threshold`` defaults to 0.8 rad/s, summed over
  joints. For the other reading pass per-joint thresholds
  (``velocity_threshold=tuple(0.8 * limit for limit in joint_velocity_limits)``);
  the value is a threshold in rad/s either way. With Go2's limits (30.1 and
  15.7 rad/s) the second reading would almost never fire.
* The squared terms (``g_xy²``, ``q̇²``, ``τ²``, ``(a_t − a_t−1)²``, ``q̈²``) are
  squared norms summed over components; ``(q − q_stand)²`` inside the exponential
  too.
* **Per step, scaled by dt.** The paper trains in Isaac Gym with rsl-rl, whose
  legged_gym environments multiply every weight by the control period
  (0.02 s). The table's weights read like such weights, and rsl-rl's PPO
  hyperparameters (value clipping 0.2, no reward normalisation) are tuned for
  that scale (returns of tens, not thousands). So ``RewardConfig.scale_by_dt``
  defaults to True: the reward of one control step is Σ_i w_i · r_i · dt. Set
  it to False to get Σ_i w_i · r_i. The scale does not change the optimal
  policy. legged_gym's ``only_positive_rewards`` clipping is not in the paper
  and not applied.
* A weight set to a value other than the paper's, or a term dropped, must come
  with a reason (``RewardConfig.overrides_reason``), so logs keep the paper's
  value visible: :meth:`RewardConfig.deviations`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Mapping

import numpy as np

from frbench.arrays import sum_sq
from frbench.training.reward_inputs import RewardInputs

__all__ = [
    "DEFAULT_EPSILON",
    "DEFAULT_VELOCITY_THRESHOLD",
    "PAPER_WEIGHTS",
    "REWARD_TERMS",
    "STABILITY_TERMS",
    "RewardConfig",
    "RewardInputs",
    "action_jerk",
    "action_smoothing",
    "base_orientation",
    "body_bias",
    "body_contact",
    "check_weights",
    "compute_rewards",
    "term_arguments",
    "feet_contact",
    "feet_on_ground",
    "head_height",
    "joint_acceleration",
    "joint_torques",
    "joint_velocity",
    "position_limits",
    "safety_force",
    "stability_terms",
    "target_posture",
    "upper_body_posture",
    "upright_orientation",
    "velocity_limit",
]

#: ε of the upright Gaussian and of the target-posture gate (see the module docstring).
DEFAULT_EPSILON = 0.4
#: Joint speed above which ``velocity_limit`` penalises [rad/s] (literal reading of the paper).
DEFAULT_VELOCITY_THRESHOLD = 0.8
#: Upper clip of the body-bias displacement [m] (paper).
BODY_BIAS_CLIP_M = 4.0

#: The paper's weights, exactly as in its table. The only place these numbers live.
PAPER_WEIGHTS: dict[str, float] = {
    "base_orientation": -0.5,
    "upright_orientation": 6.0,
    "target_posture": 4.0,
    "feet_contact": 0.3,
    "body_contact": -0.2,
    "safety_force": -1.0e-2,
    "body_bias": -0.1,
    "position_limits": -1.0,
    "velocity_limit": -0.1,
    "joint_acceleration": -2.5e-6,
    "joint_velocity": -1.0e-2,
    "action_smoothing": -0.01,
    "joint_torques": -5.0e-4,
}

#: The paper's "Stability Control" terms, which an ablation drops.
STABILITY_TERMS: tuple[str, ...] = ("safety_force", "body_bias")
stability_terms = STABILITY_TERMS


def _f(x: RewardInputs, value):
    """``value`` as an array in the inputs' namespace, device and float dtype (float64 for numpy)."""
    return x.as_float(value)


# --------------------------------------------------------------------------- orientation and posture


def base_orientation(x: RewardInputs):
    """g_x² + g_y²: 0 upright or on the back, 1 on the side. Paper weight −0.5."""
    return sum_sq(_f(x, x.projected_gravity)[:, :2])


def upright_orientation(x: RewardInputs, epsilon: float = DEFAULT_EPSILON):
    """exp(−(g_z + 1)² / (2 ε²)): 1 upright, exp(−2/ε²) on the back. Paper weight 6.0."""
    gz = _f(x, x.projected_gravity)[:, 2]
    return x.xp.exp(-((gz + 1.0) ** 2) / (2.0 * epsilon**2))


def target_posture(x: RewardInputs, epsilon: float = DEFAULT_EPSILON, sigma2: float = 1.0):
    """exp(−Σ_j (q_j − q_stand,j)² / σ²) where |g_z + 1| < ε, else 0. Paper weight 4.0, σ² = 1 rad²."""
    xp = x.xp
    gz = _f(x, x.projected_gravity)[:, 2]
    close = xp.exp(-sum_sq(_f(x, x.q) - _f(x, x.q_stand)) / sigma2)
    return xp.where(xp.abs(gz + 1.0) < epsilon, close, 0.0)


# --------------------------------------------------------------------------- contacts


def _count(x: RewardInputs, flags):
    """Row-wise number of true entries of (N, k) flags, in the inputs' float dtype (N,)."""
    xp = x.xp
    return x.as_float(xp.sum(xp.astype(x.as_bool(flags), xp.int64), axis=1))


def feet_contact(x: RewardInputs):
    """Number of feet in contact, 0..F. Paper weight 0.3."""
    return _count(x, x.foot_contact)


def body_contact(x: RewardInputs):
    """1 if any non-foot link touches anything, else 0. Paper weight −0.2."""
    return _f(x, x.as_bool(x.body_contact))


# --------------------------------------------------------------------------- stability


def safety_force(x: RewardInputs):
    """Σ over knee groups of the horizontal contact force norm [N]. Paper weight −1e−2."""
    return x.xp.sum(_f(x, x.knee_force_xy), axis=1)


def body_bias(x: RewardInputs):
    """Horizontal distance of the base from its start, clipped to [0, 4] m. Paper weight −0.1."""
    d = _f(x, x.base_xy) - _f(x, x.init_xy)
    return x.xp.clip(x.xp.sqrt(sum_sq(d)), 0.0, BODY_BIAS_CLIP_M)


# --------------------------------------------------------------------------- motion constraints


def position_limits(x: RewardInputs):
    """Number of joints strictly outside [q_lower, q_upper]. Paper weight −1.0."""
    q = _f(x, x.q)
    return _count(x, (q > _f(x, x.q_upper)) | (q < _f(x, x.q_lower)))


def velocity_limit(x: RewardInputs, threshold=DEFAULT_VELOCITY_THRESHOLD):
    """Σ_j max(|q̇_j| − threshold_j, 0) [rad/s]; threshold scalar or (J,). Paper weight −0.1.

    The default 0.8 rad/s is the paper's formula read literally (module docstring).
    """
    xp = x.xp
    excess = xp.abs(_f(x, x.qd)) - _f(x, threshold)
    return xp.sum(xp.maximum(excess, 0.0), axis=1)


def joint_acceleration(x: RewardInputs):
    """Σ_j ((q̇_j − q̇_prev,j) / dt)² [rad²/s⁴], finite difference over one control step. Paper weight −2.5e−6."""
    return sum_sq((_f(x, x.qd) - _f(x, x.qd_prev)) / x.dt)


def joint_velocity(x: RewardInputs):
    """Σ_j q̇_j² [rad²/s²]. Paper weight −1e−2."""
    return sum_sq(_f(x, x.qd))


def action_smoothing(x: RewardInputs):
    """Σ_j (a_t,j − a_t−1,j)² (action units²). Paper weight −0.01."""
    return sum_sq(_f(x, x.action) - _f(x, x.action_prev))


def joint_torques(x: RewardInputs):
    """Σ_j τ_j² [N²·m²]. Paper weight −5e−4."""
    return sum_sq(_f(x, x.tau))


def base_height(x: RewardInputs):
    """clip(h / h_nominal, 0, 1): base height above the terrain relative to standing. Not in the paper.

    frbench's training adds it (weight 2, recorded as a deviation): without a
    term that pays for rising, policies trained on the paper's table within
    2 M steps rolled onto their bellies and stayed there (0 % success); the
    notes' plain-PPO data point and MuJoCo Playground's getup task both use a
    height term.
    """
    if x.base_height is None or x.nominal_height is None:
        raise ValueError("base_height needs RewardInputs.base_height and nominal_height")
    return x.xp.clip(_f(x, x.base_height) / _f(x, x.nominal_height), 0.0, 1.0)


# --------------------------------------------------------------------------- humanoid terms


def _needs(x: RewardInputs, term: str, *names: str) -> None:
    missing = [n for n in names if getattr(x, n) is None]
    if missing:
        raise ValueError(f"{term} needs RewardInputs.{' and '.join(missing)}")


def head_height(x: RewardInputs):
    """clip(h_head / h_head,nominal, 0, 1): how far the head has risen towards standing (HoST, HumanUP)."""
    _needs(x, "head_height", "head_height", "nominal_head_height")
    ratio = _f(x, x.head_height) / _f(x, x.nominal_head_height)
    return x.xp.clip(ratio, 0.0, 1.0)


def feet_on_ground(x: RewardInputs):
    """Fraction of the feet touching the ground, counted only once the base is above half its standing height
    (a robot lying with its soles on the floor earns nothing)."""
    _needs(x, "feet_on_ground", "base_height", "nominal_height")
    xp = x.xp
    fraction = xp.mean(_f(x, x.as_bool(x.foot_contact)), axis=1)
    risen = _f(x, x.base_height) >= 0.5 * _f(x, x.nominal_height)
    return xp.where(risen, fraction, 0.0)


def upper_body_posture(x: RewardInputs, epsilon: float = DEFAULT_EPSILON):
    """exp(−Σ_{waist, arms} (q − q_stand)²) [rad²] while upright (|g_z + 1| < ε), else 0."""
    _needs(x, "upper_body_posture", "upper_body")
    xp = x.xp
    gz = _f(x, x.projected_gravity)[:, 2]
    # a boolean column index (numpy and torch both take it; its copy's memory order is the numpy path's rounding)
    error = (_f(x, x.q) - _f(x, x.q_stand))[:, x.as_bool(x.upper_body)]
    return xp.where(xp.abs(gz + 1.0) < epsilon, xp.exp(-sum_sq(error)), 0.0)


def action_jerk(x: RewardInputs):
    """Σ_j (a_t − 2 a_{t−1} + a_{t−2})², the second difference of the actions (HoST's smoothness term)."""
    _needs(x, "action_jerk", "action_prev2")
    return sum_sq(_f(x, x.action) - 2.0 * _f(x, x.action_prev) + _f(x, x.action_prev2))


#: Term name → function of the inputs (parameterised terms at their defaults).
REWARD_TERMS: dict[str, Callable[[RewardInputs], "np.ndarray"]] = {
    "base_orientation": base_orientation,
    "upright_orientation": upright_orientation,
    "target_posture": target_posture,
    "feet_contact": feet_contact,
    "body_contact": body_contact,
    "safety_force": safety_force,
    "body_bias": body_bias,
    "position_limits": position_limits,
    "velocity_limit": velocity_limit,
    "joint_acceleration": joint_acceleration,
    "joint_velocity": joint_velocity,
    "action_smoothing": action_smoothing,
    "joint_torques": joint_torques,
    "base_height": base_height,
    "head_height": head_height,
    "feet_on_ground": feet_on_ground,
    "upper_body_posture": upper_body_posture,
    "action_jerk": action_jerk,
}

# Terms that take a parameter from the config: name → config → keyword arguments.
_TERM_KWARGS: dict[str, Callable[["RewardConfig"], dict]] = {
    "upright_orientation": lambda c: {"epsilon": c.epsilon},
    "target_posture": lambda c: {"epsilon": c.epsilon, "sigma2": c.posture_sigma2},
    "velocity_limit": lambda c: {"threshold": c.velocity_threshold},
    "upper_body_posture": lambda c: {"epsilon": c.epsilon},
}


# --------------------------------------------------------------------------- config and total


@dataclass(frozen=True)
class RewardConfig:
    """Which terms count and how much.

    Attributes:
        weights: term name → weight; a term missing here is not computed
            (ablation). Defaults to :data:`PAPER_WEIGHTS`.
        epsilon: ε of the upright Gaussian and the posture gate [-] (g_z units).
        velocity_threshold: joint speed above which ``velocity_limit`` penalises
            [rad/s], a scalar or one value per joint.
        posture_sigma2: width σ² [rad²] of the target-posture kernel exp(−Σ(q − q_stand)²/σ²);
            the paper's formula has σ² = 1.
        scale_by_dt: multiply every weighted term by ``inputs.dt`` (legged_gym's
            convention; see the module docstring).
        overrides_reason: term name → why its weight differs from the paper's
            (or why it is dropped). Required for every deviation, refused for a
            term that does not deviate.
    """

    weights: Mapping[str, float] = field(default_factory=lambda: dict(PAPER_WEIGHTS))
    epsilon: float = DEFAULT_EPSILON
    velocity_threshold: float | tuple[float, ...] = DEFAULT_VELOCITY_THRESHOLD
    posture_sigma2: float = 1.0
    scale_by_dt: bool = True
    overrides_reason: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        weights = {str(k): float(v) for k, v in dict(self.weights).items()}
        reasons = {str(k): str(v) for k, v in dict(self.overrides_reason).items()}
        object.__setattr__(self, "weights", weights)
        object.__setattr__(self, "overrides_reason", reasons)
        if not isinstance(self.velocity_threshold, (int, float)):
            object.__setattr__(self, "velocity_threshold", tuple(float(v) for v in self.velocity_threshold))
        unknown = sorted(set(weights) - set(REWARD_TERMS))
        if unknown:
            raise ValueError(f"unknown reward terms {unknown}; known: {', '.join(REWARD_TERMS)}")
        bad = [k for k, v in weights.items() if not math.isfinite(v)]
        if bad:
            raise ValueError(f"reward weights must be finite: {bad}")
        if not (math.isfinite(self.epsilon) and self.epsilon > 0):
            raise ValueError(f"epsilon must be positive, got {self.epsilon!r}")
        deviating = {name for name, w in PAPER_WEIGHTS.items() if weights.get(name) != w}
        deviating |= set(weights) - set(PAPER_WEIGHTS)  # terms the paper does not have
        missing = sorted(deviating - set(reasons))
        if missing:
            raise ValueError(
                f"weights of {missing} differ from the paper's ({', '.join(f'{m}={PAPER_WEIGHTS[m]}' for m in missing)}); "
                "give a reason in overrides_reason"
            )
        needless = sorted(set(reasons) - deviating)
        if needless:
            raise ValueError(f"overrides_reason names {needless}, whose weights equal the paper's")

    def deviations(self) -> dict[str, tuple[float | None, float | None, str]]:
        """Term → (paper weight or None if the paper has no such term, weight used or None if dropped, reason)."""
        return {
            name: (PAPER_WEIGHTS.get(name), self.weights.get(name), reason)
            for name, reason in self.overrides_reason.items()
        }

    def without(self, names: tuple[str, ...] | list[str], reason: str) -> "RewardConfig":
        """A copy with terms ``names`` dropped, each recorded with ``reason``."""
        unknown = sorted(set(names) - set(REWARD_TERMS))
        if unknown:
            raise ValueError(f"unknown reward terms {unknown}")
        weights = {k: v for k, v in self.weights.items() if k not in names}
        reasons = {**self.overrides_reason, **{n: reason for n in names}}
        return replace(self, weights=weights, overrides_reason=reasons)

    def with_weight(self, name: str, weight: float, reason: str) -> "RewardConfig":
        """A copy with one weight changed (``reason`` recorded unless it is the paper's value)."""
        weights = {**self.weights, name: float(weight)}
        reasons = dict(self.overrides_reason)
        if PAPER_WEIGHTS.get(name) == float(weight):
            reasons.pop(name, None)
        else:
            reasons[name] = reason
        return replace(self, weights=weights, overrides_reason=reasons)


def check_weights(weights: dict[str, float]) -> None:
    """Raise ``ValueError`` naming any unknown term or non-finite weight of a term → weight mapping."""
    unknown = sorted(set(weights) - set(REWARD_TERMS))
    if unknown:
        raise ValueError(f"unknown reward terms {unknown}; valid terms: {', '.join(sorted(REWARD_TERMS))}")
    bad = {k: v for k, v in weights.items() if not np.isfinite(v)}
    if bad:
        raise ValueError(f"reward weights must be finite numbers, got {bad}")


def term_arguments(config: RewardConfig, inputs: RewardInputs | None = None) -> dict[str, dict]:
    """Each weighted term's keyword arguments from ``config`` (ε, σ², the velocity threshold), arrays made in the
    namespace and device of ``inputs`` when given: a device caller converts them once, not every step."""
    out = {}
    for name in config.weights:
        kwargs = _TERM_KWARGS[name](config) if name in _TERM_KWARGS else {}
        if inputs is not None:
            kwargs = {k: (inputs.as_float(v) if isinstance(v, tuple) else v) for k, v in kwargs.items()}
        out[name] = kwargs
    return out


def compute_rewards(inputs: RewardInputs, config: RewardConfig | None = None,
                    arguments: dict[str, dict] | None = None) -> tuple:
    """The reward of one control step for N environments, numpy or torch (the inputs' arrays decide; torch
    stays on its device).

    Args:
        inputs: the step's signals (shapes checked).
        config: weights and parameters; default: the paper's.
        arguments: `term_arguments` of ``config`` made once by the caller (default: made here).

    Returns:
        (total (N,), terms) where ``terms`` maps each term in ``config.weights``
        to its weighted contribution (N,) — multiplied by ``inputs.dt`` when
        ``config.scale_by_dt`` — and ``total`` is their sum.
    """
    config = RewardConfig() if config is None else config
    inputs.check()
    arguments = term_arguments(config) if arguments is None else arguments
    scale = inputs.dt if config.scale_by_dt else 1.0
    total = inputs.as_float(inputs.xp.zeros(inputs.num_envs))
    terms: dict = {}
    for name, weight in config.weights.items():
        value = REWARD_TERMS[name](inputs, **arguments[name]) * (weight * scale)
        terms[name] = value
        total = total + value
    return total, terms


# ---------------------------------------------------------------- frbench's training tables
#: Why frbench's training rewards differ from the paper's table (see docs/training.md).
