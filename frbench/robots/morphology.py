"""Parametric primitive-geometry quadrupeds for FR-Net's morphology randomisation.

FR-Net trains on robots whose trunk, hip, thigh and calf masses and sizes are
drawn from the ranges of the paper's table "Domain randomization ranges"
(:data:`MORPHOLOGY_RANGES`). This module turns one such draw
(:class:`MorphologyParams`) into a URDF string and a :class:`RobotSpec`. It is
pure Python string building plus a little numpy: no simulator is touched, so a
URDF takes well under a millisecond and training can draw thousands of them.

Kinematics and naming follow Unitree's Go2, which the rest of frbench relies on:

* root link ``base``: the trunk, a box of length (x) × width (y) × height (z);
* legs FL, FR, RL, RR (F = +x, R(ear) = −x; L = +y, R(ight) = −y), each with
  revolute joints ``{leg}_hip_joint`` (axis x, at (±hip_x, ±hip_y, 0) on the
  trunk), ``{leg}_thigh_joint`` (axis y, ±hip_length sideways from the hip) and
  ``{leg}_calf_joint`` (axis y, at (0, 0, −thigh_length)), links ``{leg}_hip``
  (a cylinder whose axis is y), ``{leg}_thigh`` and ``{leg}_calf`` (boxes hanging
  along −z), and a fixed ``{leg}_foot_joint`` at (0, 0, −calf_length) to the
  sphere ``{leg}_foot``;
* signs as on Go2: a positive thigh angle swings the foot backward, a negative
  calf angle folds the knee; hip angles, hip limits and the standing hip angle
  are mirrored on the right legs (left gets ``+stand_hip``, right ``−stand_hip``),
  so a positive ``stand_hip`` splays every foot outward.

Cross sections: a leg segment's *width* is its lateral (y) size and its *height*
its fore-aft (x) size, as in the Go1/Go2 collision boxes that the paper's numbers
match. The paper's "hip length" is taken to be the hip→thigh lateral offset.

Every link carries an ``<inertial>`` whose origin is the link's geometric centre
and whose tensor is the solid box / cylinder / sphere of the link's own mass and
dimensions, unless the params give a diagonal override (presets that publish
inertias). Numbers are written with ``repr`` so they round-trip exactly: the
file's total mass equals :func:`total_mass` to the last bit of each term.

Presets
-------
:data:`SPOT_LIKE` and :data:`LITE3_LIKE` are built from the published numbers in
``/work/shared/notes/robots.md``. Neither robot has an installable URDF, so
these are approximations: boxes instead of Spot's bevelled trunk (it changes how
it rolls), no foot compliance, inertias placed at the geometric centre instead of
the published centre of mass. Presets are *not* clipped to the randomisation
ranges (Spot's leg sections, both robots' hip offsets, Lite3's thigh length lie
outside them).

* Spot's total mass: the public model (MuJoCo Menagerie ``spot.xml``, BSD-3) sums
  to 50.34 kg with a 32.86 kg trunk, while the manufacturer's spec sheet states
  32.5 kg. ``SPOT_LIKE`` uses the spec sheet's 32.5 kg, because it describes the
  real robot, and the public model's trunk also lumps payload hardware. The leg
  links keep their published masses (hip 1.68, thigh 2.34, calf 0.35 kg, plus a
  0.04 kg foot sphere) and the trunk gets the rest:
  32.5 − 4·(1.68 + 2.34 + 0.35 + 0.04) = 14.86 kg.
* Spot's knee torque limit depends on the knee angle (30.6–113.2 N·m); a URDF
  effort limit is a constant, so the angle dependence is dropped and the upper
  end, 113.2 N·m, is used.
* Spot's leg inertias are Menagerie's principal moments rotated into the link
  frame (they come out diagonal). Its trunk inertia is *not* used: Menagerie
  gives an isotropic 0.13144 kg·m² placeholder for the 32.86 kg trunk, so the
  trunk gets the solid-box inertia of 14.86 kg instead. Spot publishes no joint
  velocity limits or hip radius; Go2's defaults are kept.
* Lite3's inertias are the diagonal tensors of DeepRoboticsLab's ``Lite3.urdf``
  (BSD-3; its left-side hip tensor, the right side lists the same moments with
  x and z swapped). Its joint limits are converted to Go2's sign convention; its
  calf, a Ø0.030 cylinder, becomes a 0.03 × 0.03 box.

File conventions
----------------
By default a morphology's file has Go2's joint convention (the canonical one of
`frbench.robots.joint_frame`). Three fields give it another, as real robot files
have, without changing what the canonical frame sees:

* ``knees``: where the standing knees of the file's front and rear legs point.
  A forward knee is the backward leg mirrored front to back (thigh and calf
  angles negated, limits mirrored). Four forward knees make the file the robot
  *turned around* (its front legs are the canonical rear legs, ANYmal- and
  Solo-like), so `joint_frame` turns it back; one pair forward is mirrored per
  leg (knees pointing inwards or outwards).
* ``joint_axes``: the directions (±1) of the file's hip (x), thigh and calf (y)
  joint axes (Mini Cheetah's file turns thigh and calf about −y).
* ``zero_pose``: the canonical (thigh, calf) angles [rad] of the file's joint
  zero, written as a rotation in the thigh and calf joints' origins (Spirit 40
  folds its legs at zero: (π/2, −π)).

The standing pose and limits of `frbench.robots.morphology_frame.default_pose`
and ``joint_limits`` are in the file's convention; mapped by the file's canonical frame (`canonical = sign · q +
offset`, `expected_frame`) they are the Go2-convention pose and limits of the
same morphology (`canonical_pose`, `canonical_limits`). With the default
fields every value, and the URDF text, is what it was before these fields.

Units are SI throughout: metres, kilograms, radians, newton-metres, seconds. A morphology's URDF and
`RobotSpec` are written by `frbench.robots.morphology_urdf`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from frbench.robots.spec import QUADRUPED_LEGS

__all__ = [
    "CONVENTION_FIELDS",
    "FOOT_LINKS",
    "HIP_X_MARGIN",
    "JOINT_NAMES",
    "KNEE_DIRECTIONS",
    "MORPHOLOGY_RANGES",
    "MorphologyParams",
    "hip_position",
    "morphology_ranges",
    "nominal_height",
    "sample",
    "total_mass",
    "validate",
]

#: FR-Net's morphology randomisation ranges (paper, Table "Domain randomization
#: ranges"), field name → (low, high) in kg or m. The only place these numbers live.
MORPHOLOGY_RANGES: dict[str, tuple[float, float]] = {
    "trunk_mass": (4.0, 28.0),
    "trunk_length": (0.37, 0.65),
    "trunk_width": (0.09, 0.30),
    "trunk_height": (0.11, 0.19),
    "hip_mass": (0.30, 0.69),
    "hip_length": (0.03, 0.05),
    "thigh_mass": (0.6, 4.0),
    "thigh_length": (0.21, 0.35),
    "thigh_width": (0.02, 0.04),
    "thigh_height": (0.03, 0.05),
    "calf_mass": (0.10, 0.86),
    "calf_length": (0.21, 0.35),
    "calf_width": (0.016, 0.020),
    "calf_height": (0.013, 0.019),
}

#: Default distance [m] between the trunk's front (rear) face and the hip joints.
HIP_X_MARGIN = 0.02

#: Actuated joints in frbench's canonical order (FL, FR, RL, RR × hip, thigh, calf).
JOINT_NAMES: tuple[str, ...] = tuple(
    f"{leg}_{part}_joint" for leg in QUADRUPED_LEGS for part in ("hip", "thigh", "calf")
)
#: Foot links, legs in canonical order.
FOOT_LINKS: tuple[str, ...] = tuple(f"{leg}_foot" for leg in QUADRUPED_LEGS)

Inertia3 = tuple[float, float, float]

#: The values of ``MorphologyParams.knees``: where a standing knee points.
KNEE_DIRECTIONS = ("backward", "forward")
#: The fields of a file's joint convention (module docstring, "File conventions"); at their defaults the file
#: is Go2's convention and `frbench.training.randomization.params_hash` leaves them out.
CONVENTION_FIELDS = ("knees", "joint_axes", "zero_pose")

# Fields that must be > 0 (masses, sizes, limits of effort/speed, stiffness).
_POSITIVE_FIELDS = (
    *MORPHOLOGY_RANGES,
    "hip_radius", "foot_radius", "foot_mass",
    "hip_torque", "thigh_torque", "calf_torque",
    "hip_velocity", "thigh_velocity", "calf_velocity",
    "kp",
)
_OPTIONAL_POSITIVE_FIELDS = ("hip_x", "hip_y")
_INERTIA_FIELDS = ("trunk_inertia", "hip_inertia", "thigh_inertia", "calf_inertia")
# (lower field, upper field, standing-pose field) per joint family.
_LIMIT_FIELDS = (
    ("hip_lower", "hip_upper", "stand_hip"),
    ("thigh_front_lower", "thigh_front_upper", "stand_thigh_front"),
    ("thigh_rear_lower", "thigh_rear_upper", "stand_thigh_rear"),
    ("calf_lower", "calf_upper", "stand_calf"),
)


@dataclass(frozen=True)
class MorphologyParams:
    """One quadruped morphology, SI units. Defaults are Go2-like.

    The first 14 fields are FR-Net's randomised parameters (see
    :data:`MORPHOLOGY_RANGES`); their defaults are Go2's measured values clipped
    into those ranges, so ``MorphologyParams()`` is itself a point of the
    randomisation space. The other fields are not randomised by the paper.
    Build variants with :func:`dataclasses.replace`.
    """

    trunk_mass: float = 6.921
    """Trunk (``base``) mass [kg]. Go2: 6.921."""
    trunk_length: float = 0.3762
    """Trunk box size along x [m]. Go2: 0.3762."""
    trunk_width: float = 0.0935
    """Trunk box size along y [m]. Go2: 0.0935."""
    trunk_height: float = 0.114
    """Trunk box size along z [m]. Go2: 0.114."""
    hip_mass: float = 0.678
    """Mass of one hip link [kg]. Go2: 0.678."""
    hip_length: float = 0.05
    """Lateral offset hip joint → thigh joint [m], also the hip cylinder's length.
    Go2's offset is 0.0955, clipped to the range's upper end 0.05."""
    thigh_mass: float = 1.152
    """Mass of one thigh link [kg]. Go2: 1.152."""
    thigh_length: float = 0.213
    """Thigh joint → calf joint distance [m]. Go2: 0.213."""
    thigh_width: float = 0.0245
    """Thigh box size along y (lateral) [m]. Go2: 0.0245."""
    thigh_height: float = 0.034
    """Thigh box size along x (fore-aft) [m]. Go2: 0.034."""
    calf_mass: float = 0.154
    """Mass of one calf link, without the foot [kg]. Go2: 0.154."""
    calf_length: float = 0.213
    """Calf joint → foot centre distance [m]. Go2: 0.213."""
    calf_width: float = 0.020
    """Calf box size along y (lateral) [m]. Go2's Ø0.024 calf clipped to 0.020."""
    calf_height: float = 0.019
    """Calf box size along x (fore-aft) [m]. Go2's Ø0.024 calf clipped to 0.019."""

    hip_radius: float = 0.046
    """Radius of the hip cylinder (axis y) [m]. Go2: 0.046."""
    foot_radius: float = 0.022
    """Radius of the foot sphere [m]. Go2: 0.022."""
    foot_mass: float = 0.04
    """Mass of one foot sphere [kg]. Go2: 0.04."""
    hip_x: float | None = None
    """|x| of the hip joints on the trunk [m]; ``None``: trunk_length/2 − HIP_X_MARGIN."""
    hip_y: float | None = None
    """|y| of the hip joints on the trunk [m]; ``None``: trunk_width/2."""

    hip_torque: float = 23.7
    """Hip (abduction) effort limit [N·m]."""
    thigh_torque: float = 23.7
    """Thigh effort limit [N·m]."""
    calf_torque: float = 45.43
    """Calf (knee) effort limit [N·m]."""
    hip_velocity: float = 30.1
    """Hip velocity limit [rad/s]."""
    thigh_velocity: float = 30.1
    """Thigh velocity limit [rad/s]."""
    calf_velocity: float = 15.7
    """Calf velocity limit [rad/s]."""

    hip_lower: float = -1.047
    """Lower hip limit of the left legs [rad]; right legs use −hip_upper."""
    hip_upper: float = 1.047
    """Upper hip limit of the left legs [rad]; right legs use −hip_lower."""
    thigh_front_lower: float = -1.571
    """Lower thigh limit of the front legs [rad]."""
    thigh_front_upper: float = 3.491
    """Upper thigh limit of the front legs [rad]."""
    thigh_rear_lower: float = -0.524
    """Lower thigh limit of the rear legs [rad]."""
    thigh_rear_upper: float = 4.538
    """Upper thigh limit of the rear legs [rad]."""
    calf_lower: float = -2.723
    """Lower calf limit [rad] (most folded knee)."""
    calf_upper: float = -0.838
    """Upper calf limit [rad] (most stretched knee)."""

    stand_hip: float = 0.1
    """Standing hip angle of the left legs [rad]; right legs use −stand_hip."""
    stand_thigh_front: float = 0.8
    """Standing thigh angle of the front legs [rad]."""
    stand_thigh_rear: float = 1.0
    """Standing thigh angle of the rear legs [rad]."""
    stand_calf: float = -1.5
    """Standing calf angle [rad]."""
    trunk_com_shift: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Offset of the trunk's centre of mass from the trunk box centre, base frame [m] (domain
    randomisation's "CoM shift"; not a morphology range)."""
    kp: float = 20.0
    """PD stiffness of every joint [N·m/rad]."""
    kd: float = 0.5
    """PD damping of every joint [N·m·s/rad] (≥ 0)."""

    knees: tuple[str, str] = ("backward", "backward")
    """Where the standing knees of the file's front and rear legs point, each ``"backward"`` (Go2) or
    ``"forward"``; both forward: the robot turned around (module docstring, "File conventions")."""
    joint_axes: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Directions (±1) of the file's hip (x), thigh (y) and calf (y) joint axes (Mini Cheetah: (1, −1, −1))."""
    zero_pose: tuple[float, float] = (0.0, 0.0)
    """Canonical (thigh, calf) angles [rad] at the file's joint zero; (0, 0): legs straight down (Spirit 40:
    (π/2, −π), folded)."""

    trunk_inertia: Inertia3 | None = None
    """Diagonal (Ixx, Iyy, Izz) of the trunk about its centre [kg·m²]; ``None``: solid box."""
    hip_inertia: Inertia3 | None = None
    """Diagonal inertia of one hip link [kg·m²]; ``None``: solid cylinder."""
    thigh_inertia: Inertia3 | None = None
    """Diagonal inertia of one thigh link [kg·m²]; ``None``: solid box."""
    calf_inertia: Inertia3 | None = None
    """Diagonal inertia of one calf link [kg·m²]; ``None``: solid box."""




# --------------------------------------------------------------------------- validation


def _check_positive(name: str, value: object) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``value`` is a finite number > 0."""
    if not _is_finite_number(value) or value <= 0:
        raise ValueError(f"MorphologyParams.{name} must be positive and finite, got {value!r}")


def _is_finite_number(value: object) -> bool:
    """True for finite real numbers (bools excluded)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) and math.isfinite(value)


def _check_inertia(name: str, value: object) -> None:
    """Raise ``ValueError`` unless ``value`` is 3 positive moments obeying the triangle inequality."""
    try:
        moments = tuple(value)  # type: ignore[arg-type]
    except TypeError:
        raise ValueError(f"MorphologyParams.{name} must be (Ixx, Iyy, Izz), got {value!r}") from None
    if len(moments) != 3 or not all(_is_finite_number(m) and m > 0 for m in moments):
        raise ValueError(f"MorphologyParams.{name} must be 3 positive finite moments, got {value!r}")
    a, b, c = moments
    if a + b < c or b + c < a or a + c < b:
        raise ValueError(f"MorphologyParams.{name} {value!r} violates the triangle inequality")


def validate(params: MorphologyParams) -> None:
    """Check ``params``; raise ``ValueError`` naming the first offending field.

    Masses, sizes, effort and velocity limits, ``kp`` and given hip positions
    must be positive and finite; ``kd`` finite and ≥ 0; angles finite with
    lower < upper and the standing pose inside the limits; inertia overrides
    three positive moments obeying the triangle inequality.
    """
    for name in _POSITIVE_FIELDS:
        _check_positive(name, getattr(params, name))
    for name in _OPTIONAL_POSITIVE_FIELDS:
        if getattr(params, name) is not None:
            _check_positive(name, getattr(params, name))
    if not _is_finite_number(params.kd) or params.kd < 0:
        raise ValueError(f"MorphologyParams.kd must be finite and >= 0, got {params.kd!r}")
    for lower, upper, stand in _LIMIT_FIELDS:
        for name in (lower, upper, stand):
            if not _is_finite_number(getattr(params, name)):
                raise ValueError(f"MorphologyParams.{name} must be finite, got {getattr(params, name)!r}")
        lo, hi, q = getattr(params, lower), getattr(params, upper), getattr(params, stand)
        if not lo < hi:
            raise ValueError(f"MorphologyParams.{lower} ({lo}) must be below {upper} ({hi})")
        if not lo <= q <= hi:
            raise ValueError(f"MorphologyParams.{stand} ({q}) lies outside [{lower}, {upper}] = [{lo}, {hi}]")
    for name in _INERTIA_FIELDS:
        if getattr(params, name) is not None:
            _check_inertia(name, getattr(params, name))
    shift = params.trunk_com_shift
    if len(shift) != 3 or not all(_is_finite_number(v) for v in shift):
        raise ValueError(f"MorphologyParams.trunk_com_shift must be three finite numbers [m], got {shift!r}")
    _validate_convention(params)


def _validate_convention(params: MorphologyParams) -> None:
    """ValueError naming ``knees``, ``joint_axes`` or ``zero_pose`` when it is not a file convention."""
    knees = params.knees
    if not (isinstance(knees, tuple) and len(knees) == 2 and all(k in KNEE_DIRECTIONS for k in knees)):
        raise ValueError(f"MorphologyParams.knees must be (front, rear), each one of {', '.join(KNEE_DIRECTIONS)}; "
                         f"got {knees!r}")
    axes = params.joint_axes
    if not (len(axes) == 3 and all(_is_finite_number(a) and a in (1.0, -1.0) for a in axes)):
        raise ValueError(f"MorphologyParams.joint_axes must be three of ±1 (hip, thigh, calf), got {axes!r}")
    zero = params.zero_pose
    if not (len(zero) == 2 and all(_is_finite_number(z) and abs(z) <= math.pi for z in zero)):
        raise ValueError(f"MorphologyParams.zero_pose must be two angles in [-pi, pi] [rad] (thigh, calf), got {zero!r}")


# --------------------------------------------------------------------------- sampling


def morphology_ranges(overrides: dict | None = None) -> dict[str, tuple[float, float]]:
    """:data:`MORPHOLOGY_RANGES` with some rows replaced, field name → (low, high) [kg or m].

    Raises:
        ValueError: naming the field when it is not a randomised field, or when its range is not two finite
            numbers 0 < low <= high.
    """
    ranges = dict(MORPHOLOGY_RANGES)
    for name, value in (overrides or {}).items():
        if name not in MORPHOLOGY_RANGES:
            raise ValueError(f"morphology range {name!r}: not a randomised field; expected one of "
                             f"{', '.join(MORPHOLOGY_RANGES)}")
        try:
            low, high = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ValueError(f"morphology range {name}={value!r}: expected two numbers (low, high)") from None
        if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= high):
            raise ValueError(f"morphology range {name}=({low}, {high}): expected finite 0 < low <= high")
        ranges[name] = (low, high)
    return ranges


def sample(rng: np.random.Generator, base: MorphologyParams | None = None,
           ranges: dict | None = None) -> MorphologyParams:
    """Draw a morphology uniformly from :data:`MORPHOLOGY_RANGES`.

    Args:
        rng: the random generator (explicit; the same seed gives the same params).
        base: supplies every non-randomised field; default ``MorphologyParams()``.
        ranges: replacements for some rows of :data:`MORPHOLOGY_RANGES` (see :func:`morphology_ranges`);
            the draw order, and so the stream of random numbers, is unchanged.

    Returns:
        ``base`` with the 14 randomised fields drawn uniformly in [low, high).
        Its hip positions revert to ``None`` (derived from the new trunk) and its
        inertia overrides to ``None`` (they belonged to the old dimensions).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    base = MorphologyParams() if base is None else base
    validate(base)
    table = morphology_ranges(ranges)
    low, high = np.array(list(table.values()), dtype=float).T
    draws = rng.uniform(low, high)
    values = {name: float(v) for name, v in zip(table, draws)}
    reset = dict.fromkeys(_OPTIONAL_POSITIVE_FIELDS + _INERTIA_FIELDS)
    return dataclasses.replace(base, **values, **reset)


# --------------------------------------------------------------------------- derived quantities


def total_mass(params: MorphologyParams) -> float:
    """Robot mass [kg]: trunk + 4·(hip + thigh + calf + foot)."""
    return params.trunk_mass + 4 * (params.hip_mass + params.thigh_mass + params.calf_mass + params.foot_mass)


def hip_position(params: MorphologyParams) -> tuple[float, float]:
    """(|x|, |y|) of the hip joints on the trunk [m], defaults resolved."""
    x = params.trunk_length / 2 - HIP_X_MARGIN if params.hip_x is None else params.hip_x
    y = params.trunk_width / 2 if params.hip_y is None else params.hip_y
    return float(x), float(y)


def nominal_height(params: MorphologyParams) -> float:
    """Height [m] of the ``base`` frame over flat ground in the standing pose.

    Forward kinematics of each leg: with thigh angle θ₁, calf angle θ₂ and hip
    angle φ (splaying outward), the foot centre lies
    ``(l₁ cos θ₁ + l₂ cos(θ₁+θ₂)) cos φ − hip_length sin φ`` below the hip axis,
    and the ground one ``foot_radius`` further. The lower of the front and rear
    legs is returned (the trunk rests on its shorter legs).
    """
    def leg_height(thigh: float) -> float:
        planar = params.thigh_length * math.cos(thigh) + params.calf_length * math.cos(thigh + params.stand_calf)
        return planar * math.cos(params.stand_hip) - params.hip_length * math.sin(params.stand_hip) + params.foot_radius

    height = min(leg_height(params.stand_thigh_front), leg_height(params.stand_thigh_rear))
    if height <= 0:
        raise ValueError(f"standing pose puts the base {height:.3f} m above the ground; check stand_* fields")
    return height
