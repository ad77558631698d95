"""The training batch's robots: which robot each environment simulates, and its physics per episode.

Either one named robot (``TrainEnvConfig.robot``) in every environment, or
``num_morphologies`` robots sampled from the paper's morphology table (those
that cannot stand at the lowest training gains are redrawn), assigned to the
N environments in a shuffled round robin. Per robot variant a friction and a
payload are drawn once (the backend compiles them in); per episode the gains,
motor strength and motor friction are redrawn (`episode_params`).

With ``bodies="wide"`` (`frbench.training.bodies.WideBodies`) each sampled robot is then resized (a size factor
s per robot, ``scales``) and given a file convention; its Kp and Kd (and the gains it must stand at), motor
friction, payload and CoM shift scale with it, so every size meets the paper population's physics in its own
units. ``"paper"`` draws exactly what it always drew.

Ground truth from Pinocchio: group masses (the estimator's labels, payload on
the base), the whole-body CoM and, for humanoids, the head position (`step_reward.HeadPoints`).
Shapes: N environments, J joints, G mass groups.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from frbench.arrays import namespace
from frbench.backends.base import PhysicsParams, RobotState
from frbench.robot_checks.lookup import get_robot
from frbench.robots import ground_truth
from frbench.robots.sim_urdf import crossing_links
from frbench.training.bodies import body_distribution
from frbench.training.feasibility import can_stand
from frbench.training.randomization import CONTROL_RANGES, morphology_spec, sample_morphologies, sample_physics
from frbench.training.step_reward import HeadPoints

#: A named robot's own per-joint Kp and Kd are multiplied by one factor per episode drawn from this range.
NAMED_ROBOT_GAIN_FACTORS = (0.9, 1.1)


def yaw_of(quat):
    """Yaw [rad] (N,) of quaternions (N, 4) wxyz (numpy or torch)."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    return namespace(quat).atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _feasible_morphologies(cfg, rng: np.random.Generator) -> tuple[list, list, int, list]:
    """``num_morphologies`` sampled robots (resized and given a file convention with ``bodies="wide"``, CoM shift
    applied when randomising) that can stand at the lowest training gains (`feasibility.can_stand`; a wide body's
    scaled by its size) and, wide, whose legs do not pass through each other (`sim_urdf.crossing_links`), their
    parameters, how many were redrawn, and their size factors (1 for the paper's)."""
    kp, kd = cfg.gain_ranges.get("kp", CONTROL_RANGES["kp"])[0], cfg.gain_ranges.get("kd", CONTROL_RANGES["kd"])[0]
    bodies = body_distribution(cfg.bodies)
    specs, morphologies, scales, rejected = [], [], [], 0
    while len(specs) < cfg.num_morphologies:
        morphology = sample_morphologies(1, rng, ranges=dict(cfg.morphology_ranges))[0]
        scale, factors = 1.0, None
        if bodies is not None:
            morphology, scale = bodies.draw(morphology, rng)
            factors = bodies.factors(scale)
        if cfg.randomize:  # the paper's CoM shift, baked into the morphology's trunk inertial
            shift = rng.uniform(*CONTROL_RANGES["com_shift"], size=3)
            if factors is not None:
                shift = shift * factors["length"]
            morphology = dataclasses.replace(morphology, trunk_com_shift=tuple(map(float, shift)))
        spec = morphology_spec(morphology, f"morph{len(specs):04d}")
        low_kp, low_kd = (kp, kd) if factors is None else (kp * factors["kp"], kd * factors["kd"])
        crossing = factors is not None and bool(crossing_links(spec))  # e.g. knees inwards on a short trunk
        if not crossing and can_stand(spec, low_kp, low_kd):
            specs.append(spec)
            morphologies.append(morphology)
            scales.append(scale)
        else:
            rejected += 1
        if rejected > 20 * cfg.num_morphologies:
            raise ValueError(f"{rejected} sampled morphologies could not stand at Kp {kp}, Kd {kd}; "
                             "raise the gain range")
    return specs, morphologies, rejected, scales


class TrainingRobots:
    """The robots of a batch of ``cfg.num_envs`` environments (see the module docstring); ``rng`` draws each
    episode's physics (`episode_params`).

    Attributes: ``specs`` (K robots), ``spec`` (the first: joint order, limits, default pose), ``assignment``
    (N,) index into ``specs``, ``variants`` (the backend's per-simulation robots, or None), ``env_masses``
    (N, G) [kg], ``env_friction`` (N,), ``env_payload`` (N,) [kg], ``nominal_height`` (N,) [m], ``head``
    (humanoids: their head points, else None); with sampled morphologies also
    ``morphologies`` and ``rejected`` (redrawn ones); ``scales`` (K,) each robot's size factor (1 but for
    ``bodies="wide"``) and ``bodies`` its `WideBodies` (None: the paper's).

    `drawn` draws them (the robot files, Pinocchio's masses); the constructor holds robots drawn before (a
    device bundle's, `frbench.training.device_bundle`), with their group masses (K, G) [kg] without payload.
    """

    def __init__(self, cfg, rng: np.random.Generator, specs, assignment: np.ndarray, variant_friction: np.ndarray,
                 variant_payload: np.ndarray, group_masses: np.ndarray, head=None, scales=None):
        self.cfg, self.rng = cfg, rng
        self.bodies = body_distribution(cfg.bodies)
        self.scales = np.ones(len(specs)) if scales is None else np.asarray(scales, dtype=float)
        self.specs = list(specs)
        self.spec = self.specs[0]
        self.assignment = np.asarray(assignment)
        self.variant_friction, self.variant_payload = np.asarray(variant_friction), np.asarray(variant_payload)
        k = len(self.specs)
        self.variants = ((self.specs, self.assignment, self.variant_friction, self.variant_payload)
                         if k > 1 or cfg.randomize else None)
        self.group_masses = np.asarray(group_masses, dtype=float)
        masses = self.group_masses.copy()
        masses[:, 0] += self.variant_payload  # the payload sits on the base
        self.env_masses = masses[self.assignment]
        self.env_friction = self.variant_friction[self.assignment]
        self.env_payload = self.variant_payload[self.assignment]
        self.nominal_height = np.array([s.nominal_height for s in self.specs])[self.assignment]
        self.humanoid = self.spec.kind == "humanoid"
        #: The humanoid's head points (`step_reward.HeadPoints`); None for quadrupeds.
        self.head = head
        self.morphologies, self.rejected = [], 0

    @classmethod
    def drawn(cls, cfg, rng: np.random.Generator) -> "TrainingRobots":
        """The robots of ``cfg``, drawn from ``rng`` (the env's generator), or from their own generator when
        ``cfg.population_seed`` is set."""
        rng = rng if cfg.population_seed is None else np.random.default_rng(cfg.population_seed)
        n = cfg.num_envs
        morphologies, rejected = [], 0
        scales = None
        if cfg.robot:
            specs = [get_robot(cfg.robot)]
        else:
            specs, morphologies, rejected, scales = _feasible_morphologies(cfg, rng)
        assignment = np.arange(n) % len(specs)
        rng.shuffle(assignment)
        k = len(specs)
        if cfg.randomize:
            variant_physics = sample_physics(specs[0], k, rng)
            friction, payload = variant_physics.friction, variant_physics.payload
            bodies = body_distribution(cfg.bodies)
            if bodies is not None:  # a payload in proportion to the body
                payload = payload * bodies.factors(scales)["mass"]
        else:
            friction, payload = np.ones(k), np.zeros(k)
        masses = np.array([ground_truth.group_masses(s) for s in specs])
        head = HeadPoints(specs, assignment) if specs[0].kind == "humanoid" else None
        robots = cls(cfg, rng, specs, assignment, friction, payload, masses, head, scales)
        robots.morphologies, robots.rejected = morphologies, rejected
        return robots

    def sample_physics(self, n: int) -> PhysicsParams:
        """Gains, motor strength, friction and payload for ``n`` episodes (every environment's with wide bodies). Sampled morphologies draw one Kp and
        Kd for all joints from the training's absolute range (they have no gains of their own), a wide body's
        multiplied by its size's factors (`bodies.WideBodies.factors`); a named robot
        (``cfg.robot``) keeps its own per-joint gains, scaled by one factor per episode from
        `NAMED_ROBOT_GAIN_FACTORS` — one Kp of 50-80 N·m/rad would replace the G1's 40-200 per joint."""
        cfg = self.cfg
        ranges = {**CONTROL_RANGES, **cfg.gain_ranges}
        if not cfg.robot:
            params = sample_physics(self.spec, n, self.rng, ranges=ranges)
            if self.bodies is not None:
                factors = self._env_factors()
                params.kp, params.kd = params.kp * factors["kp"][:, None], params.kd * factors["kd"][:, None]
            return params
        params = sample_physics(self.spec, n, self.rng, ranges={k: v for k, v in ranges.items() if k not in ("kp", "kd")})
        params.kp = params.kp * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        params.kd = params.kd * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        return params

    def _env_factors(self) -> dict[str, np.ndarray]:
        """The wide bodies' physics factors (`bodies.WideBodies.factors`) of every environment, each (N,)."""
        return {k: v[self.assignment] for k, v in self.bodies.factors(self.scales).items()}

    def episode_params(self) -> PhysicsParams:
        """The physics of the next episode of every environment: randomised (`sample_physics`, the variants'
        friction and payload, a motor friction, a wide body's in proportion to its torque limits) or the specs'
        nominal values."""
        n = self.cfg.num_envs
        if not self.cfg.randomize:
            params = PhysicsParams.nominal(self.spec, n)
            if self.bodies is not None:  # each robot's own nominal gains
                params.kp = np.array([s.kp for s in self.specs], dtype=float)[self.assignment]
                params.kd = np.array([s.kd for s in self.specs], dtype=float)[self.assignment]
            return params
        params = self.sample_physics(n)
        params.friction, params.payload = self.env_friction.copy(), self.env_payload.copy()
        params.motor_friction = self.rng.uniform(*CONTROL_RANGES["motor_friction"], size=(n, self.spec.n_joints))
        if self.bodies is not None:
            params.motor_friction = params.motor_friction * self._env_factors()["torque"][:, None]
        return params

    @staticmethod
    def com_xy(state: RobotState, com_world):
        """Whole-body CoM ``com_world`` (N, 3) [m] (the backend's vectorised `whole_body_com`, payload included)
        minus the base position, in the base yaw frame, (N, 2) [m]; numpy or torch."""
        s = state
        xp = namespace(com_world)
        delta = com_world[:, :2] - s.base_pos[:, :2]
        yaw = yaw_of(s.base_quat)
        c, si = xp.cos(yaw), xp.sin(yaw)
        return xp.stack([c * delta[:, 0] + si * delta[:, 1], -si * delta[:, 0] + c * delta[:, 1]], axis=1)
