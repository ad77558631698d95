"""Starting states drawn along a getting-up motion (a reverse curriculum for PPO).

Rolling a quadruped from its back onto its belly is a rare event for a
Gaussian policy that starts by flailing; on 2 CPU cores PPO sees too few of
them to learn it (without these starts: 0 % from supine after 9 M steps). This module
records, on the training batch itself, the states that the model-based
``scripted`` controller passes through while it gets up — every morphology on
its own curriculum tile — and lets a fraction of the following training
episodes start from one of those states instead of a fresh fallen pose.
The learner then meets "half rolled", "on the belly" and "standing" states
early, the value function learns what they are worth, and the fraction
anneals to zero so that the end of training (and every evaluation) starts
from fallen poses only. The policy never sees the controller's actions:
this is start-state selection, not imitation.

Shapes: T snapshots per episode, N environments, J joints. Units as in
`frbench.backends.base`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.arrays import to_host
from frbench.backends.base import RobotState
from frbench.policies.registry import load_policy
from frbench.tasks.observations import projected_gravity

#: The model-based controller whose getting-up motion is recorded, per robot kind (policy names).
DEMO_CONTROLLERS = {"quadruped": "scripted", "humanoid": "scripted-humanoid"}


@dataclass
class DemoStartBank:
    """Snapshots of one scripted episode on every environment.

    Attributes:
        states: per snapshot time, the full `RobotState` of all N environments (length T).
        targets: (T, N, J) the controller's joint targets at each snapshot [rad].
        tile_row: (N,) the terrain tile each environment was recorded on.
        valid: (N,) environments whose recording did not diverge.
    """

    states: list[RobotState]
    targets: np.ndarray
    tile_row: np.ndarray
    valid: np.ndarray

    def sample(self, ids: np.ndarray, rng: np.random.Generator) -> tuple[RobotState, np.ndarray, np.ndarray]:
        """A uniformly drawn snapshot time per environment in ``ids`` (M,).

        Returns ``(state, targets (M, J), tile_row (M,))`` for those environments.
        """
        ids = np.asarray(ids, dtype=int)
        times = rng.integers(0, len(self.states), size=len(ids))
        fields = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")
        picked = {f: np.stack([getattr(self.states[t], f)[i] for t, i in zip(times, ids)]) for f in fields}
        return RobotState(**picked), self.targets[times, ids], self.tile_row[ids]


def record_demo_starts(env, specs, assignment: np.ndarray, tile_row: np.ndarray, steps: int,
                       stride: int) -> DemoStartBank:
    """Run ``scripted`` (``scripted-humanoid`` for humanoids) on every environment of ``env`` from its current
    state for ``steps`` control steps.

    Args:
        env: the core environment (`frbench.tasks.core_env.CoreEnv`) whose N environments hold fresh fallen
            starts; driven with `CoreEnv.drive` (physics only, no episode step).
        specs: the robot specs; environment i is robot ``specs[assignment[i]]``.
        assignment: (N,) index into ``specs`` per environment.
        tile_row: (N,) the tile each environment lies on (kept with the snapshots).
        steps: control steps to run; ``stride``: a snapshot every ``stride`` steps.
    """
    groups = [np.flatnonzero(assignment == k) for k in range(len(specs))]
    controllers = []
    for k, ids in enumerate(groups):
        controller = load_policy(DEMO_CONTROLLERS[specs[k].kind])
        controller.reset(specs[k], len(ids))
        controllers.append(controller)
    n, n_joints = len(assignment), specs[0].n_joints
    states, targets = [], []
    target = np.zeros((n, n_joints))
    state = env.state.on_host()  # the controllers run on the host
    for step in range(steps):
        gravity = projected_gravity(state.base_quat)
        for controller, ids in zip(controllers, groups):
            if len(ids):
                target[ids] = controller.act({"projected_gravity": gravity[ids], "joint_pos": state.q[ids]})
        state = env.drive(target).on_host()
        if step % stride == stride - 1:
            states.append(state.copy())
            targets.append(target.copy())
    return DemoStartBank(states=states, targets=np.stack(targets), tile_row=np.asarray(tile_row).copy(),
                         valid=~np.asarray(to_host(env.physics_diverged), dtype=bool).copy())


def assist_probability(initial: float, until_steps: float, env_steps: float) -> float:
    """The fraction of episodes started from the bank: ``initial`` falling linearly to 0 at ``until_steps``."""
    if initial <= 0.0 or until_steps <= 0.0:
        return 0.0
    return float(initial * max(0.0, 1.0 - env_steps / until_steps))
