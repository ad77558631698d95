"""The planner's compute parameters and cost weights (frozen, typed)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

from frbench.errors import FrbenchError
from frbench.tasks.protocol import CONTROL_DT


@dataclass(frozen=True)
class CostWeights:
    """Weights of the cost terms (`frbench.planning.cost`); each term is dimensionless before weighting."""

    height: float = 10.0  # height deficit of the root (and the upper body) over its standing height
    upright: float = 5.0  # 1 − cos(tilt) of the root (and a humanoid's torso)
    balance: float = 20.0  # squared CoM–feet-centre distance in the plane [m²], once up
    body_contact: float = 1.0  # non-foot links touching anything, once up
    com_velocity: float = 0.5  # squared CoM speed [m²/s²], once up
    posture: float = 1.0  # squared distance to the default pose [rad²] per joint, once up
    effort: float = 0.05  # squared PD torque over the torque limit, per joint
    joint_limits: float = 10.0  # squared excursion past the limit margin [rad²]
    displacement: float = 0.0  # squared distance from the episode's start beyond 0.3 m [m²]


@dataclass(frozen=True)
class PlannerConfig:
    """Compute parameters of the sampling planner.

    Attributes:
        samples: candidate plans rolled out per replanning (the warm-started plan is one of them).
        horizon: planning horizon [s] (a multiple of the 0.02 s control period).
        knots: spline knots of joint targets over the horizon (linear interpolation between them).
        replan_steps: control steps (0.02 s each) between two replannings.
        planning_dt: physics step of the planning model [s] (a divisor of 0.02 s).
        noise: standard deviation of a knot perturbation, as a fraction of each joint's range.
        standing_prior: whether a plan that holds the default (standing) pose is a candidate at every replanning.
        noise_levels: groups of perturbed candidates, each with a third of the previous group's noise.
        iterations: sampling rounds per replanning: 1 is predictive sampling; more is the cross-entropy method
            (each round samples around the mean and spread of the previous round's elites).
        elites: plans kept per cross-entropy round (at most ``samples``).
        seed: base seed of the planner's generators (each episode's generator also takes the cell's seed and
            the episode index).
        threads: threads of `mujoco.rollout`.
        weights: the cost weights.
    """

    samples: int = 32
    horizon: float = 0.5
    knots: int = 3
    replan_steps: int = 2
    planning_dt: float = 0.005
    noise: float = 0.15
    noise_levels: int = 3
    standing_prior: bool = True
    iterations: int = 1
    elites: int = 4
    seed: int = 0
    threads: int = 1
    weights: CostWeights = CostWeights()

    def __post_init__(self):
        checks = {"samples": self.samples >= 3, "knots": self.knots >= 2, "replan_steps": self.replan_steps >= 1,
                  "horizon": self.horizon >= 0.04, "planning_dt": self.planning_dt > 0, "noise": self.noise >= 0,
                  "noise_levels": self.noise_levels >= 1, "iterations": self.iterations >= 1, "elites": self.elites >= 1,
                  "threads": self.threads >= 1}
        for name, ok in checks.items():
            if not ok:
                raise FrbenchError(f"planner config: {name}={getattr(self, name)!r} is out of range")

    @property
    def horizon_steps(self) -> int:
        """Control steps in the horizon."""
        return max(2, int(round(self.horizon / CONTROL_DT)))

    def as_dict(self) -> dict:
        """Plain dict (weights nested)."""
        return asdict(self)

    def with_overrides(self, overrides: dict) -> "PlannerConfig":
        """A copy with the fields of ``overrides`` (name → value; ``weights.<term>`` for a weight) set.

        Raises:
            FrbenchError: an unknown field.
        """
        top = {f.name: f.type for f in fields(self)}
        plain, weights = {}, {}
        for key, value in overrides.items():
            if key.startswith("weights."):
                term = key.split(".", 1)[1]
                if term not in {f.name for f in fields(CostWeights)}:
                    raise FrbenchError(f"planner config: unknown cost weight {term!r}")
                weights[term] = float(value)
            elif key in top and key != "weights":
                plain[key] = _parse(key, type(getattr(self, key)), value)
            else:
                raise FrbenchError(f"planner config: unknown field {key!r} (expected one of {', '.join(top)})")
        return replace(self, **plain, weights=replace(self.weights, **weights))


def _parse(key: str, kind: type, value):
    """``value`` (a string or a number) as ``kind``; a FrbenchError naming ``key`` if it is not one."""
    if kind is bool and isinstance(value, str):
        if value.lower() not in ("true", "false", "1", "0"):
            raise FrbenchError(f"planner config: {key}={value!r} is not true or false")
        return value.lower() in ("true", "1")
    try:
        return kind(value)
    except (TypeError, ValueError):
        raise FrbenchError(f"planner config: {key}={value!r} is not a {kind.__name__}") from None
