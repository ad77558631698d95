"""A morphology's joint convention: its standing pose and joint limits in the canonical (Go2's) frame and in its
robot file's own convention (knee directions, joint axes, zero pose: `MorphologyParams.knees`, ``joint_axes``,
``zero_pose``; `frbench.robots.morphology`, "File conventions"), and the canonical joint frame
(`frbench.robots.joint_frame`) the file must come out with. Angles in rad, arrays of 12 joints, legs FL, FR, RL,
RR x hip, thigh, calf.
"""

from __future__ import annotations

import dataclasses

from frbench.robots.morphology import CONVENTION_FIELDS, MorphologyParams
from frbench.robots.spec import QUADRUPED_LEGS

__all__ = [
    "canonical_limits",
    "canonical_pose",
    "default_pose",
    "expected_frame",
    "is_go2_convention",
    "is_turned",
    "joint_limits",
    "knee_mirror",
    "leg_signs",
]

_CONVENTION_DEFAULTS = {f.name: f for f in dataclasses.fields(MorphologyParams) if f.name in CONVENTION_FIELDS}


def leg_signs(leg: str) -> tuple[float, float]:
    """(x sign, y sign) of a leg prefix: F → +x, R(ear) → −x, L → +y, R(ight) → −y."""
    return (1.0 if leg[0] == "F" else -1.0), (1.0 if leg[1] == "L" else -1.0)


def canonical_pose(params: MorphologyParams) -> tuple[float, ...]:
    """Standing joint angles [rad] in Go2's (the canonical) convention, shape (12,), legs FL, FR, RL, RR (hip
    mirrored on the right)."""
    pose: list[float] = []
    for leg in QUADRUPED_LEGS:
        sx, sy = leg_signs(leg)
        thigh = params.stand_thigh_front if sx > 0 else params.stand_thigh_rear
        pose += [sy * params.stand_hip + 0.0, thigh, params.stand_calf]  # + 0.0: no -0.0
    return tuple(float(q) for q in pose)


def canonical_limits(params: MorphologyParams) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(lower, upper) position limits [rad] in Go2's (the canonical) convention, each shape (12,).

    Right legs mirror the hip range: [−hip_upper, −hip_lower].
    """
    lower: list[float] = []
    upper: list[float] = []
    for leg in QUADRUPED_LEGS:
        sx, sy = leg_signs(leg)
        hip = (params.hip_lower, params.hip_upper) if sy > 0 else (-params.hip_upper, -params.hip_lower)
        if sx > 0:
            thigh = (params.thigh_front_lower, params.thigh_front_upper)
        else:
            thigh = (params.thigh_rear_lower, params.thigh_rear_upper)
        for lo, hi in (hip, thigh, (params.calf_lower, params.calf_upper)):
            lower.append(float(lo))
            upper.append(float(hi))
    return tuple(lower), tuple(upper)


def is_go2_convention(params: MorphologyParams) -> bool:
    """Whether the file has Go2's convention (every convention field at its default)."""
    return all(getattr(params, name) == field.default for name, field in _CONVENTION_DEFAULTS.items())


def is_turned(params: MorphologyParams) -> bool:
    """Whether the file is the robot turned around: both pairs of knees point forward (module docstring)."""
    return params.knees == ("forward", "forward")


def expected_frame(params: MorphologyParams) -> tuple[tuple[float, ...], tuple[float, ...], bool]:
    """(sign (12,), offset (12,) [rad], turned) of the file's canonical joint frame, ``canonical[j] =
    sign[j] · q[order[j]] + offset[j]`` (`frbench.robots.joint_frame.JointFrame`), from the convention fields: per
    canonical leg, hip sign ``a_h`` (−a_h turned), thigh and calf signs ``m · a`` (m = −1 for a forward knee),
    offsets ``zero_pose`` (0 where zero)."""
    turned = is_turned(params)
    a_h, a_t, a_c = (float(a) for a in params.joint_axes)
    sign, offset = [], []
    for k in range(len(QUADRUPED_LEGS)):
        mirror = knee_mirror(params, QUADRUPED_LEGS[_file_leg(k, turned)])
        sign += [-a_h if turned else a_h, mirror * a_t, mirror * a_c]
        offset += [0.0] + [float(z) + 0.0 for z in params.zero_pose]
    return tuple(sign), tuple(offset), turned


def _file_leg(k: int, turned: bool) -> int:
    """The file's leg (index into FL, FR, RL, RR) that is canonical leg ``k`` (the same leg unless turned)."""
    return len(QUADRUPED_LEGS) - 1 - k if turned else k


def knee_mirror(params: MorphologyParams, leg: str) -> float:
    """−1 when the file's leg ``leg`` (FL, FR, RL, RR) has its knee forward, else +1."""
    direction = params.knees[0] if leg_signs(leg)[0] > 0 else params.knees[1]
    return -1.0 if direction == "forward" else 1.0


def _file_angles(params: MorphologyParams, canonical: tuple[float, ...]) -> tuple[float, ...]:
    """Canonical joint angles [rad] (12,) as the file's: per file leg the inverse of its canonical frame."""
    sign, offset, turned = expected_frame(params)
    out = [0.0] * len(canonical)
    for k in range(len(QUADRUPED_LEGS)):
        leg = _file_leg(k, turned)
        for j in range(3):
            c = 3 * k + j
            out[3 * leg + j] = float(sign[c] * (canonical[c] - offset[c])) + 0.0
    return tuple(out)


def default_pose(params: MorphologyParams) -> tuple[float, ...]:
    """Standing joint angles [rad], shape (12,), in the file's convention (`canonical_pose` for Go2's)."""
    pose = canonical_pose(params)
    return pose if is_go2_convention(params) else _file_angles(params, pose)


def joint_limits(params: MorphologyParams) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(lower, upper) position limits [rad], each shape (12,), in the file's convention (`canonical_limits` for
    Go2's; a limit pair whose sign flips swaps ends)."""
    lower, upper = canonical_limits(params)
    if is_go2_convention(params):
        return lower, upper
    a, b = _file_angles(params, lower), _file_angles(params, upper)
    return tuple(min(x, y) for x, y in zip(a, b)), tuple(max(x, y) for x, y in zip(a, b))
