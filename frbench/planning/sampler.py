"""Sampling-based planning over spline knots of joint targets: predictive sampling and the cross-entropy method.

A plan is ``knots`` (n_knots, n_joints) joint targets q* [rad] at equally spaced times over the horizon
(knot 0 now, the last one at the horizon's end); the target held during control step c (0.02 s each) is
the linear interpolation of the knots at c. One replanning (`Sampler.plan`):

1. candidates: the warm-started nominal plan (the previous best, shifted by the steps executed since), the
   standing prior (hold the default pose; ``standing_prior``) and perturbations of the nominal plan up to
   ``samples`` in all, each knot value plus noise·(joint range)·N(0, 1), clipped to the
   joint limits; the perturbations come in ``noise_levels`` groups whose noise shrinks by a third from one
   group to the next (coarse moves to get up, fine ones to balance);
2. all candidates are rolled out from the current state at once on the planning model
   (`mujoco.rollout.rollout`, in C, ``threads`` threads), the targets held over each control period as
   the PD actuators of the acting simulators hold them;
3. each trajectory is scored by `frbench.planning.cost.Cost`; with ``iterations`` = 1 the cheapest
   candidate is the plan (predictive sampling); with more, each round samples around the mean and the
   spread of the previous round's ``elites`` cheapest candidates, keeping the best one found
   (the cross-entropy method).

Every random draw comes from the generator the caller passes in.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from frbench.backends.mujoco_model import CountedWarnings
from frbench.planning.config import PlannerConfig
from frbench.planning.cost import Cost
from frbench.planning.model import PlanningModel
from frbench.robots.spec import RobotSpec

#: Ratio of one noise level to the one before (`PlannerConfig.noise_levels`).
NOISE_LEVEL_RATIO = 1.0 / 3.0
#: Smallest spread of a cross-entropy round, as a fraction of the initial one.
MIN_SPREAD = 0.1


@dataclass
class PlanResult:
    """One replanning's outcome: ``knots`` (n_knots, n_joints) [rad], its ``cost``, and every candidate's
    cost of the first round, ``first_costs`` (samples,) (index 0 is the warm-started nominal plan)."""

    knots: np.ndarray
    cost: float
    first_costs: np.ndarray


class Sampler:
    """Plans for one robot on one planning model (module docstring).

    Args:
        spec: the robot (joint limits, default pose, gains).
        planning: the planning model (`frbench.planning.model.build_planning_model`).
        config: the compute parameters and cost weights.
    """

    def __init__(self, spec: RobotSpec, planning: PlanningModel, config: PlannerConfig):
        self.spec, self.planning, self.config = spec, planning, config
        self.cost = Cost(spec, planning, config.weights)
        self.steps = config.horizon_steps
        self.knot_steps = np.linspace(0.0, self.steps, config.knots)
        self.lower, self.upper = np.asarray(spec.joint_lower, float), np.asarray(spec.joint_upper, float)
        self.sigma = config.noise * (self.upper - self.lower)
        #: each perturbed candidate's noise scale: ``noise_levels`` equal groups, each a third of the one before
        #: the standing prior: a plan that holds the default pose (`PlannerConfig.standing_prior`), or None
        self.prior = self.hold(np.asarray(spec.default_pose, float)) if config.standing_prior else None
        perturbed = config.samples - 1 - (self.prior is not None)
        self.scales = NOISE_LEVEL_RATIO ** (np.arange(perturbed) * config.noise_levels // max(perturbed, 1))
        self.n_joints = spec.n_joints
        model = planning.model
        self.datas = [mujoco.MjData(model) for _ in range(config.threads)]
        self.scratch = mujoco.MjData(model)
        n, t = config.samples, self.steps * planning.substeps
        self._control = np.zeros((n, t, model.nu))
        self._state = np.empty((n, t, planning.n_state))
        self._sensordata = np.empty((n, t, model.nsensordata))
        self._q_columns = 1 + planning.qadr  # a full-physics state starts with the time
        #: MuJoCo warnings of unstable candidate rollouts so far (counted, not printed: such plans cost the most)
        self.unstable_warnings = 0

    def targets(self, knots: np.ndarray) -> np.ndarray:
        """Joint targets (…, C, n_joints) [rad] held during each of the C control steps of the horizon, from
        ``knots`` (…, n_knots, n_joints)."""
        c = np.arange(self.steps, dtype=float)
        index = np.clip(np.searchsorted(self.knot_steps, c, side="right") - 1, 0, len(self.knot_steps) - 2)
        t0, t1 = self.knot_steps[index], self.knot_steps[index + 1]
        alpha = ((c - t0) / (t1 - t0))[:, None]
        return knots[..., index, :] * (1.0 - alpha) + knots[..., index + 1, :] * alpha

    def shifted(self, knots: np.ndarray, steps: int) -> np.ndarray:
        """The plan ``knots`` (n_knots, n_joints) moved ``steps`` control steps on: its values at the knot times
        from then, the last knot held past the end (the warm start)."""
        times = np.minimum(self.knot_steps + steps, self.knot_steps[-1])
        return np.stack([np.interp(times, self.knot_steps, knots[:, j]) for j in range(self.n_joints)], axis=1)

    def hold(self, q: np.ndarray) -> np.ndarray:
        """A plan (n_knots, n_joints) that holds the joint positions ``q`` [rad] (clipped to the limits)."""
        return np.tile(np.clip(q, self.lower, self.upper), (len(self.knot_steps), 1))

    def evaluate(self, initial_state: np.ndarray, candidates: np.ndarray, ground: float,
                 anchor: np.ndarray | None = None) -> np.ndarray:
        """Roll out ``candidates`` (samples, n_knots, n_joints) from ``initial_state`` (n_state,) and return their
        costs (samples,); ``ground`` is the terrain height [m] under the robot, ``anchor`` (2,) the episode's start
        xy [m] (None: no displacement term)."""
        planning, k = self.planning, len(candidates)
        targets = self.targets(candidates)  # (K, C, J)
        control = self._control[:k]
        control[:, :, : self.n_joints] = np.repeat(targets, planning.substeps, axis=1)
        state, sensordata = self._state[:k], self._sensordata[:k]
        with CountedWarnings() as unstable:
            rollout.rollout(planning.model, self.datas, np.broadcast_to(initial_state, (k, planning.n_state)),
                            control, state=state, sensordata=sensordata, skip_checks=False)
        self.unstable_warnings += unstable.count
        ends = slice(planning.substeps - 1, None, planning.substeps)
        return self.cost(sensordata[:, ends], state[:, ends][..., self._q_columns], targets, ground, anchor)

    def plan(self, initial_state: np.ndarray, nominal: np.ndarray, ground: float, rng: np.random.Generator,
             anchor: np.ndarray | None = None) -> PlanResult:
        """One replanning from ``initial_state`` (n_state,) around ``nominal`` (n_knots, n_joints) [rad] (``ground``,
        ``anchor``: see `evaluate`)."""
        cfg = self.config
        fixed = [nominal] if self.prior is None else [nominal, self.prior]
        shape = (cfg.samples - len(fixed), *nominal.shape)
        best, best_cost, first_costs = nominal, np.inf, None
        mean, spread = nominal, self.sigma[None, None] * self.scales[:, None, None]
        for _ in range(cfg.iterations):
            perturbed = np.clip(mean + spread * rng.standard_normal(shape), self.lower, self.upper)
            candidates = np.concatenate([best[None], *(p[None] for p in fixed[1:]), perturbed])
            costs = self.evaluate(initial_state, candidates, ground, anchor)
            if first_costs is None:
                first_costs = costs.copy()
            order = np.argsort(costs, kind="stable")
            if costs[order[0]] < best_cost:
                best, best_cost = candidates[order[0]].copy(), float(costs[order[0]])
            elites = candidates[order[: cfg.elites]]
            mean = elites.mean(axis=0)
            spread = np.maximum(elites.std(axis=0), MIN_SPREAD * self.sigma)[None]
        return PlanResult(best, best_cost, first_costs)
