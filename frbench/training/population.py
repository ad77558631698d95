"""The training batch's robots: which robot each environment simulates, and its physics per episode.

Either one named robot (``TrainEnvConfig.robot``) in every environment, or
``num_morphologies`` robots sampled from the paper's morphology table (those
that cannot stand at the lowest training gains are redrawn), assigned to the
N environments in a shuffled round robin. Per robot variant a friction and a
payload are drawn once (the backend compiles them in); per episode the gains,
motor strength and motor friction are redrawn (`episode_params`).

Ground truth from Pinocchio: group masses (the estimator's labels, payload on
the base), the whole-body CoM and, for humanoids, the head position (`step_reward.HeadPoints`).
Shapes: N environments, J joints, G mass groups.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from frbench.backends.base import PhysicsParams, RobotState
from frbench.robot_checks.lookup import get_robot
from frbench.robots import ground_truth
from frbench.training.feasibility import can_stand
from frbench.training.randomization import CONTROL_RANGES, morphology_spec, sample_morphologies, sample_physics
from frbench.training.step_reward import HeadPoints

#: A named robot's own per-joint Kp and Kd are multiplied by one factor per episode drawn from this range.
NAMED_ROBOT_GAIN_FACTORS = (0.9, 1.1)


def yaw_of(quat: np.ndarray) -> np.ndarray:
    """Yaw [rad] (N,) of quaternions (N, 4) wxyz."""
    w, x, y, z = quat.T
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class TrainingRobots:
    """The robots of a batch of ``cfg.num_envs`` environments (see the module docstring), drawn from ``rng``.

    Attributes: ``specs`` (K robots), ``spec`` (the first: joint order, limits, default pose), ``assignment``
    (N,) index into ``specs``, ``variants`` (the backend's per-simulation robots, or None), ``env_masses``
    (N, G) [kg], ``env_friction`` (N,), ``env_payload`` (N,) [kg], ``nominal_height`` (N,) [m], ``head``
    (humanoids: their head points, else None); with sampled morphologies also
    ``morphologies`` and ``rejected`` (redrawn ones).
    """

    def __init__(self, cfg, rng: np.random.Generator):
        self.cfg, self.rng = cfg, rng
        n = cfg.num_envs
        specs = [get_robot(cfg.robot)] if cfg.robot else self._feasible_morphologies()
        self.specs = specs
        self.spec = specs[0]
        self.assignment = np.arange(n) % len(specs)
        self.rng.shuffle(self.assignment)
        k = len(specs)
        if cfg.randomize:
            variant_physics = sample_physics(self.spec, k, self.rng)
            self.variant_friction, self.variant_payload = variant_physics.friction, variant_physics.payload
        else:
            self.variant_friction, self.variant_payload = np.ones(k), np.zeros(k)
        self.variants = (specs, self.assignment, self.variant_friction, self.variant_payload) if k > 1 or cfg.randomize else None
        masses = np.array([ground_truth.group_masses(s) for s in specs])
        masses[:, 0] += self.variant_payload  # the payload sits on the base
        self.env_masses = masses[self.assignment]
        self.env_friction = self.variant_friction[self.assignment]
        self.env_payload = self.variant_payload[self.assignment]
        self.nominal_height = np.array([s.nominal_height for s in specs])[self.assignment]
        self.humanoid = self.spec.kind == "humanoid"
        #: The humanoid's head points (`step_reward.HeadPoints`); None for quadrupeds.
        self.head = HeadPoints(specs, self.assignment) if self.humanoid else None

    @classmethod
    def drawn(cls, cfg, rng: np.random.Generator) -> "TrainingRobots":
        """The robots of ``cfg``: from ``rng`` (the env's generator), or from their own generator when
        ``cfg.population_seed`` is set."""
        return cls(cfg, rng if cfg.population_seed is None else np.random.default_rng(cfg.population_seed))

    def _feasible_morphologies(self) -> list:
        """``num_morphologies`` sampled robots (CoM shift applied when randomising) that can stand at the lowest
        training gains (`feasibility.can_stand`); the others are redrawn and counted in ``self.rejected``.
        Their parameters are kept in ``self.morphologies``."""
        cfg = self.cfg
        kp, kd = cfg.gain_ranges.get("kp", CONTROL_RANGES["kp"])[0], cfg.gain_ranges.get("kd", CONTROL_RANGES["kd"])[0]
        specs, self.morphologies, self.rejected = [], [], 0
        while len(specs) < cfg.num_morphologies:
            morphology = sample_morphologies(1, self.rng, ranges=dict(cfg.morphology_ranges))[0]
            if cfg.randomize:  # the paper's CoM shift, baked into the morphology's trunk inertial
                shift = self.rng.uniform(*CONTROL_RANGES["com_shift"], size=3)
                morphology = dataclasses.replace(morphology, trunk_com_shift=tuple(map(float, shift)))
            spec = morphology_spec(morphology, f"morph{len(specs):04d}")
            if can_stand(spec, kp, kd):
                specs.append(spec)
                self.morphologies.append(morphology)
            else:
                self.rejected += 1
            if self.rejected > 20 * cfg.num_morphologies:
                raise ValueError(f"{self.rejected} sampled morphologies could not stand at Kp {kp}, Kd {kd}; "
                                 "raise the gain range")
        return specs

    def sample_physics(self, n: int) -> PhysicsParams:
        """Gains, motor strength, friction and payload for ``n`` episodes. Sampled morphologies draw one Kp and
        Kd for all joints from the training's absolute range (they have no gains of their own); a named robot
        (``cfg.robot``) keeps its own per-joint gains, scaled by one factor per episode from
        `NAMED_ROBOT_GAIN_FACTORS` — one Kp of 50-80 N·m/rad would replace the G1's 40-200 per joint."""
        cfg = self.cfg
        ranges = {**CONTROL_RANGES, **cfg.gain_ranges}
        if not cfg.robot:
            return sample_physics(self.spec, n, self.rng, ranges=ranges)
        params = sample_physics(self.spec, n, self.rng, ranges={k: v for k, v in ranges.items() if k not in ("kp", "kd")})
        params.kp = params.kp * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        params.kd = params.kd * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        return params

    def episode_params(self) -> PhysicsParams:
        """The physics of the next episode of every environment: randomised (`sample_physics`, the variants'
        friction and payload, a motor friction) or the spec's nominal values."""
        n = self.cfg.num_envs
        if not self.cfg.randomize:
            return PhysicsParams.nominal(self.spec, n)
        params = self.sample_physics(n)
        params.friction, params.payload = self.env_friction.copy(), self.env_payload.copy()
        params.motor_friction = self.rng.uniform(*CONTROL_RANGES["motor_friction"], size=(n, self.spec.n_joints))
        return params

    @staticmethod
    def com_xy(state: RobotState, com_world: np.ndarray) -> np.ndarray:
        """Whole-body CoM ``com_world`` (N, 3) [m] (the backend's vectorised `whole_body_com`, payload included)
        minus the base position, in the base yaw frame, (N, 2) [m]."""
        s = state
        delta = com_world[:, :2] - s.base_pos[:, :2]
        yaw = yaw_of(s.base_quat)
        c, si = np.cos(yaw), np.sin(yaw)
        return np.stack([c * delta[:, 0] + si * delta[:, 1], -si * delta[:, 0] + c * delta[:, 1]], axis=1)
