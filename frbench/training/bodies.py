"""The training population's body distributions (``TrainEnvConfig.bodies``): the paper's table, or wider bodies.

``"paper"`` draws each robot from the paper's morphology table (`frbench.robots.morphology.MORPHOLOGY_RANGES`,
about 21-35 kg) in Go2's joint convention. ``"wide"`` (`WideBodies`, the one place of its numbers) spans the
sizes and joint conventions of real quadrupeds, with the paper's table as the floor of its variety: each robot is
a paper-table draw, then

* **sized**: a total mass M drawn log-uniformly in `WideBodies.mass_range` (2-60 kg; the unseen quadrupeds
  weigh 2.5-56 kg) and a size factor s = (M / m₀)^(1/3) over the draw's mass m₀. Lengths scale by s (hip
  positions included), masses by s³, so the robot is the draw, geometrically similar. What makes a body of
  that size stand and move alike scales with it (Froude scaling: time ∝ s^½): torque limits by s⁴ (a torque
  holds m·g·L), the PD stiffness by s⁴, the damping by s^4.5 (the same damping ratio on inertias ∝ s⁵), and in
  training the episode's motor friction by s⁴, the payload by s³ and the CoM shift by s
  (`frbench.training.population.TrainingRobots`). Velocity limits and angles stay. The training's Kp per unit
  of m·g·h (h the standing height) is thus the paper population's at every size.
* **knees**: the file's front and rear knees point one of `WideBodies.knee_layouts`: all backward (Go2), all
  forward (the robot turned around, like ANYmal and Solo12 as frbench stands them), or one pair forward
  (knees pointing inwards or outwards);
* **joint convention**: with probability `WideBodies.flipped_fraction` the file turns thigh and calf about −y
  (Mini Cheetah), with `WideBodies.folded_fraction` its joint zero folds the legs (Spirit 40's (π/2, −π)).

The conventions live in the robot file (`frbench.robots.morphology`, "File conventions"): the learner's
canonical joint frame (`frbench.robots.joint_frame`) is what normalises them, as it does for the unseen robots.
Every wide body's canonical standing pose and limits are those of its paper draw in Go2's convention.

No body is a robot file of the unseen grid or the humanoid set: every one is primitive geometry from the
generator (``tests/test_unseen_grid.py`` checks that no table names one).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

import numpy as np

from frbench.robots.morphology import MorphologyParams, hip_position, total_mass

#: Fields of `MorphologyParams` that are lengths [m] (scale by s).
LENGTH_FIELDS = ("trunk_length", "trunk_width", "trunk_height", "hip_length", "thigh_length", "thigh_width",
                 "thigh_height", "calf_length", "calf_width", "calf_height", "hip_radius", "foot_radius")
#: Fields that are masses [kg] (scale by s³).
MASS_FIELDS = ("trunk_mass", "hip_mass", "thigh_mass", "calf_mass", "foot_mass")
#: Fields that are torque limits [N·m].
TORQUE_FIELDS = ("hip_torque", "thigh_torque", "calf_torque")
#: Inertia overrides [kg·m²] (scale by s⁵ where set).
INERTIA_FIELDS = ("trunk_inertia", "hip_inertia", "thigh_inertia", "calf_inertia")


@dataclass(frozen=True)
class WideBodies:
    """The ``"wide"`` body distribution (module docstring); every number of it lives here.

    Attributes:
        mass_range: (low, high) total mass [kg], drawn log-uniformly.
        knee_layouts: the (front, rear) knee directions drawn from, uniformly.
        flipped_axes: the file's (hip, thigh, calf) joint axes of a flipped convention (Mini Cheetah's).
        flipped_fraction: the fraction of files with ``flipped_axes``.
        folded_zero: the canonical (thigh, calf) angles [rad] of a folded joint zero (Spirit 40's).
        folded_fraction: the fraction of files whose joint zero is ``folded_zero``.
        torque_exponent, kp_exponent, kd_exponent: torque limits, Kp and Kd scale by s to these powers.
    """

    mass_range: tuple[float, float] = (2.0, 60.0)
    knee_layouts: tuple[tuple[str, str], ...] = (("backward", "backward"), ("forward", "forward"),
                                                 ("backward", "forward"), ("forward", "backward"))
    flipped_axes: tuple[float, float, float] = (1.0, -1.0, -1.0)
    flipped_fraction: float = 0.5
    folded_zero: tuple[float, float] = (math.pi / 2, -math.pi)
    folded_fraction: float = 0.5
    torque_exponent: float = 4.0
    kp_exponent: float = 4.0
    kd_exponent: float = 4.5

    def draw(self, params: MorphologyParams, rng: np.random.Generator) -> tuple[MorphologyParams, float]:
        """(the wide body of paper-table draw ``params``, its size factor s): four draws from ``rng`` in this
        order: log-mass, knee layout, flipped axes, folded zero."""
        low, high = (math.log(m) for m in self.mass_range)
        mass = math.exp(rng.uniform(low, high))
        layout = self.knee_layouts[int(rng.integers(len(self.knee_layouts)))]
        flipped = bool(rng.random() < self.flipped_fraction)
        folded = bool(rng.random() < self.folded_fraction)
        scale = (mass / total_mass(params)) ** (1.0 / 3.0)
        body = dataclasses.replace(
            self.scaled(params, scale), knees=tuple(layout),
            joint_axes=self.flipped_axes if flipped else (1.0, 1.0, 1.0),
            zero_pose=self.folded_zero if folded else (0.0, 0.0))
        return body, scale

    def scaled(self, params: MorphologyParams, scale: float) -> MorphologyParams:
        """``params`` made ``scale`` times as long (module docstring: lengths ·s, masses ·s³, inertias ·s⁵,
        torque limits, Kp and Kd by their exponents); hip positions are resolved first and scaled with it."""
        s = float(scale)
        hip_x, hip_y = hip_position(params)
        changes = {name: getattr(params, name) * s for name in LENGTH_FIELDS}
        changes.update({name: getattr(params, name) * s ** 3 for name in MASS_FIELDS})
        changes.update({name: getattr(params, name) * s ** self.torque_exponent for name in TORQUE_FIELDS})
        changes.update({name: tuple(v * s ** 5 for v in getattr(params, name)) for name in INERTIA_FIELDS
                        if getattr(params, name) is not None})
        changes.update(hip_x=hip_x * s, hip_y=hip_y * s, kp=params.kp * s ** self.kp_exponent,
                       kd=params.kd * s ** self.kd_exponent,
                       trunk_com_shift=tuple(v * s + 0.0 for v in params.trunk_com_shift))
        return dataclasses.replace(params, **changes)

    def factors(self, scale) -> dict[str, np.ndarray]:
        """The training's per-episode physics factors of bodies of size factors ``scale`` (K,): ``kp``, ``kd``,
        ``torque`` (the motor friction), ``mass`` (the payload) and ``length`` (the CoM shift), each (K,)."""
        s = np.asarray(scale, dtype=float)
        return {"kp": s ** self.kp_exponent, "kd": s ** self.kd_exponent, "torque": s ** self.torque_exponent,
                "mass": s ** 3, "length": s}


#: ``TrainEnvConfig.bodies`` → its distribution (None: the paper's table in Go2's convention).
BODIES: Mapping[str, WideBodies | None] = MappingProxyType({"paper": None, "wide": WideBodies()})


def body_distribution(name: str) -> WideBodies | None:
    """The distribution named ``name`` (`BODIES`); a ValueError naming ``bodies`` when there is none."""
    if name not in BODIES:
        raise ValueError(f"bodies {name!r}: expected one of {', '.join(BODIES)}")
    return BODIES[name]
