"""Where training episodes start besides fresh fallen poses: demo starts and rise starts.

Every episode first gets a fresh fallen start on its curriculum tile (the
protocol's draw, settled by the episode engine). A start source then replaces
some of them by recorded states:

* `DemoStarts`: states along the model-based ``scripted`` (``scripted-humanoid``)
  controller's getting-up motion (`demo_starts.record_demo_starts`), a fraction
  of episodes falling linearly to 0 (a reverse curriculum);
* `RiseStarts`: the states where a gated base controller opened its gate (the key
  frames' crouch) in a recorded run from fresh starts, with the controller put
  back in that phase, so that every such episode exercises the rise.

Both re-record their bank every ``refresh_episodes`` episodes, on the training
batch itself, through the core environment's API (`frbench.tasks.core_env.CoreEnv`:
``state``, ``drive`` — physics only, no episode step — and ``physics_diverged``);
the training env then puts the drawn episodes on their states with ``restart``. Every random draw comes from the generator passed in; a source
draws its Bernoulli mask at every reset, even when its fraction is 0, so the
generator's stream does not depend on the schedule.
"""

from __future__ import annotations

import numpy as np

from frbench.backends.base import RobotState
from frbench.tasks.observations import proprioception
from frbench.tasks.recovery import EPISODE_STEPS
from frbench.training.demo_starts import DemoStartBank, assist_probability, record_demo_starts

#: The fields of a recorded state, stacked row by row.
_STATE_FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")


class DemoStarts:
    """A fraction ``initial`` of episodes, falling linearly to 0 at ``until`` env steps, starts from a state of
    the scripted getting-up motion, re-recorded every ``refresh_episodes`` episodes from ``steps`` control steps,
    one snapshot every ``stride``."""

    def __init__(self, initial: float, until: float, refresh_episodes: int, steps: int, stride: int):
        self.initial, self.until = float(initial), float(until)
        self.refresh_episodes, self.steps, self.stride = int(refresh_episodes), int(steps), int(stride)
        self.bank: DemoStartBank | None = None
        self.episodes_since = 0

    def fraction(self, env_steps: int) -> float:
        """The share of episodes started from the bank at ``env_steps``."""
        return assist_probability(self.initial, self.until, env_steps)

    def needs_recording(self, fraction: float) -> bool:
        """Whether the bank must be (re-)recorded before this reset."""
        return fraction > 0.0 and (self.bank is None or self.episodes_since >= self.refresh_episodes)

    def record(self, env, specs, assignment: np.ndarray, tile_row: np.ndarray) -> None:
        """Record the bank from the fresh starts the core env ``env`` holds now (see `record_demo_starts`)."""
        self.bank = record_demo_starts(env, specs, assignment, tile_row, self.steps, self.stride)
        self.episodes_since = 0

    def draw(self, rng: np.random.Generator, num_envs: int, fraction: float) -> np.ndarray:
        """(N,) bool: the episodes that start from the bank (one Bernoulli draw each; valid recordings only).
        Counts one episode towards the refresh."""
        self.episodes_since += 1
        return (rng.random(num_envs) < fraction) & (self.bank.valid if self.bank is not None else False)

    def sample(self, ids: np.ndarray, rng: np.random.Generator) -> tuple[RobotState, np.ndarray, np.ndarray]:
        """(state (M rows), controller targets (M, J) [rad], tile rows (M,)) for environments ``ids``."""
        return self.bank.sample(ids, rng)


class RiseStarts:
    """A fraction ``fraction`` of episodes starts where the base controller's gate opened in a recorded episode,
    re-recorded every ``refresh_episodes`` episodes (`record`)."""

    def __init__(self, fraction: float, refresh_episodes: int):
        self.fraction, self.refresh_episodes = float(fraction), int(refresh_episodes)
        self.bank: list[tuple[RobotState, int, np.ndarray, int]] | None = None
        self.episodes_since = 0

    def needs_recording(self) -> bool:
        """Whether the bank must be (re-)recorded before this reset (counts one episode towards the refresh)."""
        stale = self.bank is None or self.episodes_since >= self.refresh_episodes
        return self.fraction > 0.0 and stale

    def count_episode(self) -> None:
        """One more episode since the bank was recorded."""
        self.episodes_since += 1

    def record(self, env, controller, spec, default_pose: np.ndarray, tile_row: np.ndarray) -> None:
        """Run ``controller`` (a fresh base controller) on the fresh starts the core env ``env`` holds for one evaluation
        episode (`EPISODE_STEPS`, whatever the training episode length: the gate openings an evaluation can see);
        keep the state (one row), tile, controller targets (J,) [rad] and way to the crouch (``gate_paths``) of
        every environment at the step its default gate (the crouch) first opened."""
        n = env.num_envs
        controller.reset(spec, n)
        bank, opened = [], np.zeros(n, dtype=bool)
        state = env.state
        for _ in range(EPISODE_STEPS):
            state = env.drive(np.asarray(controller.act(proprioception(state, default_pose))))
            new = (controller.residual_gate() > 0) & ~opened & ~env.physics_diverged
            paths = controller.gate_paths()
            bank += [(state.take([i]), int(tile_row[i]), controller.target[i].copy(), int(paths[i]))
                     for i in np.flatnonzero(new)]
            opened |= new
        self.bank, self.episodes_since = bank, 0

    def draw(self, rng: np.random.Generator, taken: np.ndarray):
        """The episodes (not already ``taken`` (N,) bool by another source) that start from the bank:
        (ids (M,), state (M rows), tile rows (M,), controller targets (M, J), ways to the crouch (M,)),
        or None when there are none."""
        drawn = (rng.random(len(taken)) < self.fraction) & ~taken
        ids = np.flatnonzero(drawn) if self.bank else np.zeros(0, int)
        if not len(ids):
            return None
        picks = rng.integers(0, len(self.bank), size=len(ids))
        rows = [self.bank[k][0] for k in picks]
        state = RobotState(**{f: np.concatenate([getattr(r, f) for r in rows]) for f in _STATE_FIELDS})
        return (ids, state, [self.bank[k][1] for k in picks], np.stack([self.bank[k][2] for k in picks]),
                np.array([self.bank[k][3] for k in picks]))
