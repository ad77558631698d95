"""``mpc``: a sampling-based model-predictive get-up controller that plans with the simulator's state.

Unlike every other policy it is not blind: before each control step it reads the acting simulator's full
state (base pose and velocities, joint positions and velocities: `frbench.backends.base.RobotState`) and
plans on a MuJoCo copy of the episode's robot and terrain (`frbench.planning`). The episode runner gives
it both through two calls that only policies declaring ``uses_simulator_state = True`` receive:
``reset_episode(terrain, seed)`` after ``reset``, and ``observe_state(state)`` before each ``act``.
Its results say so (``inputs = "simulator-state"``) and the leaderboard never ranks it with blind policies.

The same planner drives MuJoCo and PyBullet: frbench's `RobotState` is the root link frame in both, which
is MuJoCo's free-joint convention, so PyBullet's state maps onto the planning model's qpos/qvel as is.

Compute: `frbench.planning.config.PlannerConfig` (defaults fit 2 cores). ``$FRBENCH_MPC`` overrides fields
for one process, e.g. ``FRBENCH_MPC="samples=64,horizon=0.6,iterations=2"``; the policy's name then carries
them (``mpc-samples64-horizon0.6-iterations2``), so its results say which planner ran.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from frbench.errors import FrbenchError, PolicyError
from frbench.planning.config import PlannerConfig
from frbench.planning.model import build_planning_model
from frbench.planning.sampler import Sampler
from frbench.robots.spec import RobotSpec
from frbench.terrains import height_at

#: Environment variable with planner-config overrides (``field=value,...``).
CONFIG_ENV = "FRBENCH_MPC"


def config_from_text(text: str) -> tuple[PlannerConfig, dict]:
    """(config, overrides) from ``field=value,...`` (empty: the defaults).

    Raises:
        FrbenchError: a malformed item or an unknown field.
    """
    overrides = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not value:
            raise FrbenchError(f"${CONFIG_ENV}: expected field=value, got {item!r}")
        overrides[key.strip()] = value.strip()
    try:
        return PlannerConfig().with_overrides(overrides), overrides
    except ValueError as exc:
        raise FrbenchError(f"${CONFIG_ENV}: {exc}") from None


class MpcPolicy:
    """Sampling MPC on a MuJoCo copy of the episode, reading the simulator's state (not blind; docs/planning.md)."""

    checkpoint: Path | None = None
    uses_simulator_state = True
    #: What the policy reads: the simulator's state (the results and the leaderboard carry it).
    inputs = "simulator-state"

    def __init__(self, config: PlannerConfig | None = None):
        if config is None:
            config, overrides = config_from_text(os.environ.get(CONFIG_ENV, ""))
        else:
            overrides = {}
        self.config = config
        suffix = "".join(f"-{key.replace('weights.', '')}{value}" for key, value in overrides.items())
        self.name = f"mpc{suffix}"
        self.spec: RobotSpec | None = None
        self._episodes_ready = False

    def supports(self, spec: RobotSpec) -> bool:
        """Any robot with feet and a simulation URDF (the planner needs nothing else)."""
        return len(spec.foot_links) > 0

    def parameter_dict(self) -> dict:
        """The planner's configuration (plain values)."""
        return self.config.as_dict()

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Start ``num_envs`` episodes of ``spec``; `reset_episode` must follow before the first `act`."""
        self.spec, self.num_envs = spec, int(num_envs)
        self._episodes_ready = False
        self._state = None

    def reset_episode(self, terrain, seed: int) -> None:
        """Build the planning model of the episodes' ``terrain``; the episodes' generators take ``seed``."""
        if self.spec is None:
            raise PolicyError("policy 'mpc': reset_episode before reset")
        self.terrain = terrain
        self.planning = build_planning_model(self.spec, terrain, self.config.planning_dt)
        self.sampler = Sampler(self.spec, self.planning, self.config)
        self.scratch = mujoco.MjData(self.planning.model)
        self.rngs = [np.random.default_rng([self.config.seed, int(seed), i]) for i in range(self.num_envs)]
        self.plans: list[np.ndarray | None] = [None] * self.num_envs
        self.anchors: list[np.ndarray | None] = [None] * self.num_envs
        self.queue = np.zeros((self.num_envs, self.config.replan_steps, self.spec.n_joints))
        self.step_index = 0
        self.last_cost = np.full(self.num_envs, np.nan)
        self._episodes_ready = True

    def observe_state(self, state) -> None:
        """The acting simulator's `RobotState` (N rows) at the coming control step."""
        self._state = state

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, n_joints) [rad]: each episode's plan at this step, replanned every ``replan_steps``."""
        if not self._episodes_ready or self._state is None:
            raise PolicyError("policy 'mpc' plans with the simulator's state: run it through `frbench evaluate` "
                              "(the runner calls reset_episode and observe_state), not as a blind policy")
        k = self.step_index % self.config.replan_steps
        if k == 0:
            for i in range(self.num_envs):
                self._replan(i)
        self.step_index += 1
        return self.queue[:, k].copy()

    def _replan(self, i: int) -> None:
        """Replan episode ``i`` from the observed state and queue the next ``replan_steps`` targets."""
        state, steps = self._state, self.config.replan_steps
        if not (np.isfinite(state.q[i]).all() and np.isfinite(state.base_pos[i]).all()):
            self.queue[i] = self.queue[i, -1]  # a diverged simulation: hold the last target
            return
        x0 = self.planning.initial_state(state, i, self.scratch)
        previous = self.plans[i]
        nominal = self.sampler.hold(state.q[i]) if previous is None else self.sampler.shifted(previous, steps)
        ground = float(height_at(self.terrain, state.base_pos[i, :2]))
        if self.anchors[i] is None:  # the first observed state is the episode's start
            self.anchors[i] = state.base_pos[i, :2].copy()
        result = self.sampler.plan(x0, nominal, ground, self.rngs[i], self.anchors[i])
        self.plans[i], self.last_cost[i] = result.knots, result.cost
        targets = self.sampler.targets(result.knots)
        self.queue[i] = targets[np.minimum(np.arange(steps), len(targets) - 1)]
