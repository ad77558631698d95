"""The benchmark protocol's version and constants (see docs/protocol.md).

Change ``PROTOCOL_VERSION`` whenever a change can move a number: initial
states, terrain geometry, success thresholds, physics or control settings.
Every results file records it; the leaderboard refuses unknown versions.
"""

from __future__ import annotations

from frbench.control import CONTROL_DT  # noqa: F401  (the control period [s] is part of the protocol)

#: The protocol this code implements.
PROTOCOL_VERSION = "1.2"
#: Every protocol version whose results the leaderboard accepts.
KNOWN_PROTOCOL_VERSIONS = ("1.0", "1.1", "1.2")
#: The version in the starts' random key (`frbench.tasks.initial_states.episode_rng`): 1.2 changed no start, so it
#: draws 1.1's (a policy that does not use torch scores the standard grid as under 1.1, episode for episode).
STARTS_KEY_VERSION = "1.1"
#: Version of the results JSON layout written by ``frbench evaluate``.
RESULTS_SCHEMA_VERSION = 1

#: Evaluation episode length [s].
EPISODE_SECONDS = 5.0

#: The standard grid a leaderboard record must cover to be ranked.
STANDARD_ROBOTS = ("go2", "go1", "aliengo", "spot_like", "lite3_like")
STANDARD_BACKENDS = ("mujoco", "pybullet")
STANDARD_TERRAINS = ("flat", "rough", "slopes", "stairs", "stones", "gaps", "beams")
STANDARD_LEVELS = (1, 5, 10)
STANDARD_SEEDS = (0, 1, 2, 3)
#: Episodes per cell of the standard grid: 840 cells x 3 = 2520 episodes, enough for a 95 % interval of at most
#: +-2 points on the overall score even if every cell were at 50 % (1.96^2 x 0.25 / 0.02^2 = 2401 episodes).
STANDARD_EPISODES = 3

#: Protocol 1.2's unseen grid (docs/protocol.md, `frbench.robots.unseen`): real quadrupeds no policy trains on x both
#: backends x four families x levels 1 and 5 x seeds 0-3 x 3 episodes = 576 cells, 1728 episodes: a 95 % interval of
#: at most +-2.4 points on the overall unseen score even at 50 % in every cell (1.96^2 x 0.25 / 1728 = 0.0236^2).
UNSEEN_TERRAINS = ("flat", "rough", "slopes", "stairs")
UNSEEN_LEVELS = (1, 5)
UNSEEN_SEEDS = STANDARD_SEEDS
UNSEEN_EPISODES = STANDARD_EPISODES


def unseen_quadrupeds() -> tuple[str, ...]:
    """The unseen grid's quadrupeds (`frbench.robots.unseen.UNSEEN_QUADRUPEDS`), lightest first."""
    from frbench.robots.unseen import UNSEEN_QUADRUPEDS

    return tuple(r.name for r in UNSEEN_QUADRUPEDS)


def unseen_humanoids() -> tuple[str, ...]:
    """The unseen humanoid set, scored only for policies that drive humanoids."""
    from frbench.robots.unseen import UNSEEN_HUMANOIDS

    return tuple(r.name for r in UNSEEN_HUMANOIDS)
