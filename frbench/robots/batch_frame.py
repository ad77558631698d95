"""The canonical joint frames of a batch of robots: one `JointFrame` per environment.

A training batch whose robots share one canonical frame maps every environment through it (`batch_joint_frame`
returns that `JointFrame`). Robots of different file conventions (``bodies="wide"``: knees forward, flipped axes,
legs folded at zero) each have their own; `BatchJointFrame` maps environment i through the frame of its robot,
with the `JointFrame` interface the training env uses (`observation`, `targets`, `to_canonical`, `to_joints`,
`velocities`, `body_vectors`, `canonical_spec`), on numpy arrays or torch tensors (N rows): the same maths
(`frbench.robots.joint_frame.CanonicalMaps`) on per-environment rows.

Their canonical standing poses must agree, the learner's one q̊ (a wide body's is its paper draw's Go2 pose).
Shapes: N environments, J joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.robots.joint_frame import TURNED_BODY_FLIP, CanonicalMaps, JointFrame, JointFrameError, joint_frame

#: Canonical standing poses [rad] of one batch differ by at most this.
POSE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class BatchJointFrame(CanonicalMaps):
    """Environment i read and written through ``frames[assignment[i]]`` (module docstring).

    Attributes:
        frames: the batch's robots' `JointFrame` (K).
        assignment: (N,) each environment's index into ``frames``.
        turned: (N,) bool, set from them: environment i's robot is turned around (its canonical front is its rear).
    """

    frames: tuple[JointFrame, ...]
    assignment: tuple[int, ...]

    def __post_init__(self) -> None:
        frames = [self.frames[k] for k in self.assignment]
        turned = np.array([f.turned for f in frames], dtype=bool)
        object.__setattr__(self, "turned", turned)
        self._set_rows([f.sign for f in frames], [f.offset for f in frames],
                       [f.order for f in frames] if turned.any() else None,
                       np.where(turned[:, None], np.array(TURNED_BODY_FLIP), 1.0) if turned.any() else None)

    def canonical_spec(self, spec):
        """``spec`` (the batch's first robot) as a canonical-frame policy sees it (`JointFrame.canonical_spec` of
        its frame, ``frames[0]``)."""
        return self.frames[0].canonical_spec(spec)

    def to_dict(self) -> dict:
        """JSON form (a device bundle's): every frame's fields and the assignment."""
        return {"frames": [dict(robot=f.robot, sign=list(f.sign), offset=list(f.offset), knees=list(f.knees),
                                turned=f.turned) for f in self.frames], "assignment": list(self.assignment)}

    @classmethod
    def from_dict(cls, data: dict) -> "BatchJointFrame":
        """The frame `to_dict` wrote."""
        frames = tuple(JointFrame(f["robot"], tuple(f["sign"]), tuple(f["offset"]), tuple(f["knees"]), f["turned"])
                       for f in data["frames"])
        return cls(frames, tuple(int(k) for k in data["assignment"]))


def batch_joint_frame(specs, assignment) -> JointFrame | BatchJointFrame:
    """The canonical joint frame of a batch: environment i is robot ``specs[assignment[i]]``. One `JointFrame` when
    every robot has the same signs, offsets and joint order (the batch maps through it, as always), else a
    `BatchJointFrame`.

    Raises:
        JointFrameError: a robot has no frame, or two robots' canonical standing poses differ by more than
            `POSE_TOLERANCE` (the learner has one q̊).
    """
    cache: dict = {}
    frames = tuple(cache.setdefault(spec.urdf_path, joint_frame(spec)) for spec in specs)
    first = frames[0]
    if all((f.sign, f.offset, f.turned) == (first.sign, first.offset, first.turned) for f in frames):
        return first
    pose = np.asarray(first.canonical_spec(specs[0]).default_pose)
    for spec, frame in zip(specs, frames):
        other = np.asarray(frame.canonical_spec(spec).default_pose)
        if np.abs(other - pose).max() > POSE_TOLERANCE:
            raise JointFrameError(f"robots {specs[0].name!r} and {spec.name!r} stand at different canonical poses "
                                  f"(up to {np.abs(other - pose).max():.3g} rad apart); a training batch has one q̊")
    return BatchJointFrame(frames, tuple(int(k) for k in np.asarray(assignment)))
