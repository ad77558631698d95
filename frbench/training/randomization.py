"""FR-Net's domain randomisation (paper, Table "Domain randomization ranges").

Two parts, both drawn from an explicit ``numpy.random.Generator`` (same seed,
same values; no global RNG):

* **Control** rows: :data:`CONTROL_RANGES`, sampled per environment by
  :func:`sample_physics` into the backends' :class:`PhysicsParams` (Kp, Kd,
  motor strength, terrain friction, payload) and by :func:`sample_extra` into
  :class:`ExtraRandomization` (CoM shift, motor friction), which the backends do
  not support yet: it is returned so the training environment can wire it in
  later (and put the CoM shift into the privileged observation), and is
  otherwise unused.
* **Morphology** rows: :func:`sample_morphologies` draws
  :class:`MorphologyParams` from ``morphology.MORPHOLOGY_RANGES`` and
  :func:`morphology_spec` turns one into a :class:`RobotSpec` with its URDF
  written to a content-keyed cache folder.

Readings where the paper is ambiguous
-------------------------------------
* **Kp and Kd are absolute gains**, not factors: the table says "Kp factor
  [20, 80] N·m/rad" and "Kd factor [0.6, 2.0] N·m·s/rad". The units and the
  magnitudes (Go2 runs Kp 20, Kd 0.5) say gains; a factor of 20–80 on any
  robot's gains would be absurd. The sampled gains replace the spec's.
* **One Kp and one Kd per environment**, shared by all its joints (the table
  lists a single "factor"; the generated morphologies themselves use one gain
  for all joints). ``per_joint_gains=True`` draws each joint independently
  instead. The paper's privileged observation holds 24 gains (12 Kp, 12 Kd):
  the (N, J) arrays of :class:`PhysicsParams` concatenated give exactly that
  either way.
* **Motor strength is per joint** (each motor its own scale in [0.9, 1.1]; the
  table's "N·m" unit is read as a dimensionless scale, which is what the
  backends' ``motor_strength`` is). Motor friction is per joint too [N·m].
* **CoM shift** is drawn independently on x, y and z of the base, each in
  [−0.05, 0.05] m (the privileged observation uses the xy part).
* **Payload** [−2, 2] kg is added to the base (negative: lighter trunk; the
  lightest sampled trunk, 4 kg, stays above 2 kg).
* **Ground friction** is not a control row of the table but is part of the
  privileged observation (μ). Range [0.5, 1.25], legged_gym's default
  ``friction_range``.
* A key left out of ``ranges`` is not randomised: the spec's Kp/Kd, strength 1,
  friction 1, payload 0, no CoM shift, no motor friction.

To re-randomise a subset of environments at reset, sample ``len(ids)`` rows
and write them into those rows.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from frbench.backends.base import PhysicsParams
from frbench.robots import morphology, morphology_urdf
from frbench.robots.morphology import MorphologyParams
from frbench.robots.paths import cache_dir
from frbench.robots.spec import RobotSpec

__all__ = [
    "CONTROL_RANGES",
    "PAPER_CONTROL_KEYS",
    "ExtraRandomization",
    "morphology_spec",
    "morphology_specs",
    "params_hash",
    "sample_extra",
    "sample_morphologies",
    "sample_physics",
]

#: Control randomisation, name → (low, high). See the module docstring for readings.
CONTROL_RANGES: dict[str, tuple[float, float]] = {
    "kp": (20.0, 80.0),  # PD stiffness [N·m/rad], absolute
    "kd": (0.6, 2.0),  # PD damping [N·m·s/rad], absolute
    "motor_strength": (0.9, 1.1),  # torque scale [-]
    "com_shift": (-0.05, 0.05),  # base CoM offset per axis [m]
    "payload": (-2.0, 2.0),  # mass added to the base [kg]
    "motor_friction": (0.2, 1.25),  # joint Coulomb friction [N·m]
    "friction": (0.5, 1.25),  # terrain friction coefficient [-]; not in the paper's table
}
#: The keys of :data:`CONTROL_RANGES` that come from the paper's table.
PAPER_CONTROL_KEYS: tuple[str, ...] = ("kp", "kd", "motor_strength", "com_shift", "payload", "motor_friction")


@dataclass
class ExtraRandomization:
    """Randomisation the backends do not apply yet (see the module docstring).

    Attributes:
        com_shift: (N, 3) offset of the base's centre of mass in the base frame [m].
        motor_friction: (N, J) Coulomb friction torque of each joint [N·m].
    """

    com_shift: np.ndarray
    motor_friction: np.ndarray


def _range(ranges: Mapping[str, tuple[float, float]], key: str) -> tuple[float, float] | None:
    """``ranges[key]`` checked (low ≤ high, finite), or None when absent."""
    if key not in ranges:
        return None
    low, high = (float(v) for v in ranges[key])
    if not (np.isfinite(low) and np.isfinite(high) and low <= high):
        raise ValueError(f"randomisation range {key!r} = {ranges[key]!r}: expected finite (low, high) with low <= high")
    return low, high


def _check_unknown(ranges: Mapping[str, tuple[float, float]]) -> None:
    unknown = sorted(set(ranges) - set(CONTROL_RANGES))
    if unknown:
        raise ValueError(f"unknown randomisation ranges {unknown}; known: {', '.join(CONTROL_RANGES)}")


def sample_physics(
    spec: RobotSpec,
    num_envs: int,
    rng: np.random.Generator,
    ranges: Mapping[str, tuple[float, float]] = CONTROL_RANGES,
    *,
    per_joint_gains: bool = False,
) -> PhysicsParams:
    """Per-environment physical parameters for the backends, drawn uniformly.

    Args:
        spec: the robot (joint count; nominal gains for keys left out of ``ranges``).
        num_envs: N.
        rng: the generator; draws happen in a fixed order (kp, kd,
            motor_strength, friction, payload), skipping absent keys.
        ranges: name → (low, high); see :data:`CONTROL_RANGES`.
        per_joint_gains: draw Kp and Kd per joint instead of once per environment.

    Returns:
        ``PhysicsParams`` with kp, kd, motor_strength (N, J) and friction,
        payload (N,), float64.
    """
    _check_unknown(ranges)
    nominal = PhysicsParams.nominal(spec, num_envs)
    j = spec.n_joints
    gain_shape = (num_envs, j) if per_joint_gains else (num_envs, 1)

    def draw(key: str, shape: tuple[int, ...], default: np.ndarray) -> np.ndarray:
        bounds = _range(ranges, key)
        if bounds is None:
            return default
        return np.broadcast_to(rng.uniform(*bounds, size=shape), default.shape).copy()

    return PhysicsParams(
        kp=draw("kp", gain_shape, nominal.kp),
        kd=draw("kd", gain_shape, nominal.kd),
        motor_strength=draw("motor_strength", (num_envs, j), nominal.motor_strength),
        friction=draw("friction", (num_envs,), nominal.friction),
        payload=draw("payload", (num_envs,), nominal.payload),
    )


def sample_extra(
    spec: RobotSpec,
    num_envs: int,
    rng: np.random.Generator,
    ranges: Mapping[str, tuple[float, float]] = CONTROL_RANGES,
) -> ExtraRandomization:
    """CoM shift (N, 3) [m] and motor friction (N, J) [N·m], drawn uniformly (zeros for absent keys)."""
    _check_unknown(ranges)
    com = _range(ranges, "com_shift")
    friction = _range(ranges, "motor_friction")
    return ExtraRandomization(
        com_shift=np.zeros((num_envs, 3)) if com is None else rng.uniform(*com, size=(num_envs, 3)),
        motor_friction=(
            np.zeros((num_envs, spec.n_joints)) if friction is None else rng.uniform(*friction, size=(num_envs, spec.n_joints))
        ),
    )


# --------------------------------------------------------------------------- morphologies


def sample_morphologies(count: int, rng: np.random.Generator, base: MorphologyParams | None = None,
                        ranges: dict | None = None) -> list[MorphologyParams]:
    """``count`` morphologies drawn uniformly from ``morphology.MORPHOLOGY_RANGES``.

    ``base`` supplies the non-randomised fields (limits, torques, standing pose,
    gains); default ``MorphologyParams()`` (Go2-like). ``ranges`` replaces some
    rows of the table (``morphology.morphology_ranges``).
    """
    if count < 0:
        raise ValueError(f"count must be >= 0, got {count}")
    return [morphology.sample(rng, base, ranges) for _ in range(count)]


def params_hash(params: MorphologyParams) -> str:
    """A 16-hex-digit key of every field of ``params`` (floats by ``repr``, exact); the file-convention fields
    (`morphology.CONVENTION_FIELDS`) only where they differ from Go2's, so the keys of Go2-convention
    morphologies are those they had before those fields existed."""
    text = repr(tuple((f.name, getattr(params, f.name)) for f in dataclasses.fields(params)
                      if f.name not in morphology.CONVENTION_FIELDS or getattr(params, f.name) != f.default))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _default_cache_dir() -> Path:
    return cache_dir() / "morphology"


def morphology_spec(params: MorphologyParams, name: str, cache_dir: str | Path | None = None) -> RobotSpec:
    """The :class:`RobotSpec` of a generated morphology, its URDF written if needed.

    The URDF goes to ``cache_dir/<params_hash(params)>/<name>.urdf`` (default
    ``cache_dir``: ``$FRBENCH_CACHE/morphology``). An existing file with the same
    text is left alone; otherwise the file is written atomically, so concurrent
    writers are safe.

    Args:
        params: the morphology.
        name: the robot's name (spec name, URDF ``<robot name>``, file name).
        cache_dir: root folder of the cache.

    Returns:
        ``morphology_urdf.spec_from_params(params, name, path)``.
    """
    root = _default_cache_dir() if cache_dir is None else Path(cache_dir)
    return morphology_urdf.cached_spec(params, name, root / params_hash(params) / f"{name}.urdf")


def morphology_specs(
    params: list[MorphologyParams], cache_dir: str | Path | None = None, prefix: str = "morph"
) -> list[RobotSpec]:
    """:func:`morphology_spec` of each, named ``{prefix}{i:04d}``."""
    return [morphology_spec(p, f"{prefix}{i:04d}", cache_dir) for i, p in enumerate(params)]
