"""The DAgger rule frbench's two teachers share: who acts in which episode, what a label is, and, for the
teacher that labels inside the vectorised training env, when the imitation ends.

DAgger (Ross et al. 2011) gathers its data in rounds. Round 0 is behaviour cloning: the teacher acts in every
episode. In each later round r the student acts, except in a fraction ``beta`` of the episodes, drawn from a
generator seeded by (seed, round, batch) (`teacher_acts`); the teacher labels every visited state either way.
A label is the teacher's joint target as the student's action (`teacher_label`): in the student's joint frame,
relative to its default pose, in its action units.

Two collectors apply the rule:

* `frbench.training.distill` (``frbench distill``, the ``mpc`` planner): episodes through the evaluation's
  episode runner, one shard per episode, the student retrained from scratch after each round;
* `frbench.training.teacher` (``TrainEnvConfig.teacher``, the ``scripted`` controller): the teacher labels
  inside the vectorised training env at every control step, and the student, FR-Net's actor, learns online on
  PPO's mini-batches (`frbench.training.imitation.KickstartPPO`); a round is a span of env steps
  (`ImitationSchedule`), a batch is one env episode of all environments.

`ImitationSchedule` is the in-env collector's timetable, in env steps: DAgger for ``dagger_steps`` in
``dagger_rounds`` equal rounds (no reinforcement learning: the PPO surrogate and entropy terms weigh 0 and
the imitation term ``weight``), then PPO with the imitation term's weight falling linearly from ``weight`` to
0 at ``until`` env steps (kickstarting, Schmitt et al. 2018), then PPO alone. During that decay the teacher
may go on acting in a fraction ``kick_beta`` of the episodes; the rows it acted in are imitation rows, not PPO
rows (their PPO weight is 0). With ``teacher_rows_only`` the imitation term weighs only the rows the teacher
acted in, where its label is its own next action; on the learner's rows the stateful ``scripted`` runs beside
it on its own clock and its label need not be what it would do from there (docs/training.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def teacher_acts(seed: int, round_index: int, batch: int, n: int, beta: float) -> np.ndarray:
    """(n,) bool: the episodes of batch ``batch`` of DAgger round ``round_index`` that the teacher acts in: all of
    them in round 0, else each with probability ``beta`` from a generator seeded by (seed, round, batch)."""
    if round_index == 0:
        return np.ones(n, dtype=bool)
    return np.random.default_rng([int(seed), int(round_index), int(batch)]).random(n) < beta


def teacher_label(targets: np.ndarray, policy_default_pose: np.ndarray, frame=None, scale: float = 1.0) -> np.ndarray:
    """The student's action (N, J) [policy units] that asks for the teacher's joint ``targets`` (N, J) [rad, the
    robot's joints]: ``(frame.to_canonical(targets) − q̊) / scale`` with ``q̊`` (J,) the student's default pose in
    its frame (``frame`` None: the robot's own frame)."""
    targets = np.asarray(targets, dtype=np.float64)
    if frame is not None and not frame.is_identity:
        targets = frame.to_canonical(targets)
    return (targets - np.asarray(policy_default_pose, dtype=np.float64)) / float(scale)


@dataclass(frozen=True)
class ImitationSchedule:
    """When the in-env teacher's imitation runs, in env steps (module docstring).

    Attributes:
        dagger_steps: env steps of DAgger (0: none) [env steps].
        dagger_rounds: equal rounds the DAgger steps are cut into; round 0 is behaviour cloning.
        beta: in rounds 1.., the fraction of episodes the teacher acts in.
        weight: the imitation term's weight during DAgger and at the start of the decay.
        until: env steps at which the weight has fallen linearly to 0 (at most ``dagger_steps``: no decay).
        seed: the seed of the rounds' draws (`teacher_acts`).
        kick_beta: after DAgger and before ``until``, the fraction of episodes the teacher acts in (drawn as a
            round numbered ``dagger_rounds``).
        teacher_rows_only: the imitation term weighs only the rows the teacher acted in.
        floor: the weight the decay stops at (0: it falls to 0 at ``until`` and the teacher stops acting; above
            0 the weight stays at ``floor`` from where the decay reaches it, and the teacher goes on acting in a
            fraction ``kick_beta`` of the episodes to the end of training).
    """

    dagger_steps: float = 0.0
    dagger_rounds: int = 1
    beta: float = 0.0
    weight: float = 1.0
    until: float = 0.0
    seed: int = 0
    kick_beta: float = 0.0
    teacher_rows_only: bool = False
    floor: float = 0.0

    def __post_init__(self) -> None:
        if self.dagger_steps < 0 or self.until < 0:
            raise ValueError(f"imitation schedule: dagger_steps {self.dagger_steps!r} and until {self.until!r} must "
                             "be >= 0 env steps")
        if int(self.dagger_rounds) < 1:
            raise ValueError(f"dagger_rounds {self.dagger_rounds!r}: expected at least 1 round")
        if not 0.0 <= self.beta <= 1.0:
            raise ValueError(f"dagger_beta {self.beta!r}: expected a fraction in [0, 1]")
        if not 0.0 <= self.kick_beta <= 1.0:
            raise ValueError(f"kickstart_beta {self.kick_beta!r}: expected a fraction in [0, 1]")
        if self.weight < 0:
            raise ValueError(f"imitation_weight {self.weight!r}: expected a weight >= 0")
        if not 0.0 <= self.floor <= self.weight:
            raise ValueError(f"imitation_floor {self.floor!r}: expected a weight in [0, imitation_weight "
                             f"{self.weight!r}]")

    def round_at(self, env_steps: float) -> int | None:
        """The DAgger round at ``env_steps`` (0-based), None once DAgger is over."""
        if env_steps >= self.dagger_steps:
            return None
        return min(int(env_steps * self.dagger_rounds // self.dagger_steps), self.dagger_rounds - 1)

    def imitation_weight(self, env_steps: float) -> float:
        """The imitation term's weight at ``env_steps``: ``weight`` during DAgger, then falling linearly to 0 at
        ``until``, never below ``floor``."""
        if env_steps < self.dagger_steps:
            return float(self.weight)
        if env_steps >= self.until:
            return float(self.floor)
        return max(float(self.weight * (self.until - env_steps) / (self.until - self.dagger_steps)), float(self.floor))

    def rl_weight(self, env_steps: float) -> float:
        """The PPO surrogate's (and entropy bonus's) weight at ``env_steps``: 0 during DAgger, 1 after."""
        return 0.0 if env_steps < self.dagger_steps else 1.0

    def acts(self, env_steps: float, episode: int, n: int) -> np.ndarray:
        """(n,) bool: the environments whose episode number ``episode`` (a batch) starting at ``env_steps`` the
        teacher acts in (`teacher_acts`; during the decay a fraction ``kick_beta``, none after it unless a
        ``floor`` keeps the term on)."""
        round_index = self.round_at(env_steps)
        if round_index is not None:
            return teacher_acts(self.seed, round_index, episode, n, self.beta)
        if (env_steps < self.until or self.floor > 0) and self.kick_beta > 0:
            return teacher_acts(self.seed, self.dagger_rounds, episode, n, self.kick_beta)
        return np.zeros(n, dtype=bool)

    def row_weights(self, env_steps: float, acting: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The imitation and PPO weights, each (n,), of the rows collected at ``env_steps`` whose episodes the
        teacher acts in where ``acting`` (n,) bool: the teacher's rows are never PPO rows, and with
        ``teacher_rows_only`` the only imitation rows."""
        acting = np.asarray(acting, dtype=bool)
        imitation = np.full(acting.shape, self.imitation_weight(env_steps))
        if self.teacher_rows_only:
            imitation = np.where(acting, imitation, 0.0)
        return imitation, np.where(acting, 0.0, self.rl_weight(env_steps))
