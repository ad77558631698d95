"""The benchmark protocol's version and constants (see docs/protocol.md).

Change ``PROTOCOL_VERSION`` whenever a change can move a number: initial
states, terrain geometry, success thresholds, physics or control settings.
Every results file records it; the leaderboard refuses unknown versions.
"""

from __future__ import annotations

from frbench.control import CONTROL_DT  # noqa: F401  (the control period [s] is part of the protocol)

#: The protocol this code implements: 1.4, 1.3's grids in three simulators with every start free of self-overlap
#: (docs/protocol.md, "Protocol 1.4").
PROTOCOL_VERSION = "1.4"
#: Every protocol version whose results the leaderboard accepts.
KNOWN_PROTOCOL_VERSIONS = ("1.0", "1.1", "1.2", "1.3", "1.4")
#: The earliest protocol whose episodes this code reproduces (`frbench verify`): 1.4 draws a 1.3 or 1.2 record's
#: starts with that version's redraw rule (`joint_redraws`); 1.3 added PhysX cells and the humanoid grid and changed
#: no MuJoCo or PyBullet episode of 1.2; 1.2 changed learned policies' inference.
REPRODUCED_FROM = "1.2"
#: The first protocol whose starts are redrawn until their links are free of each other (docs/protocol.md,
#: "Protocol 1.4"; `frbench.tasks.initial_states.joint_redraws`): earlier protocols kept the last of 50 redraws,
#: overlapping or not.
FREE_STARTS_PROTOCOL = "1.4"
#: The first protocol whose grids hold PhysX cells.
PHYSX_PROTOCOL = "1.3"
#: The version in the starts' random key (`frbench.tasks.initial_states.episode_rng`): 1.2 changed no start, so it
#: draws 1.1's (a policy that does not use torch scores the standard grid as under 1.1, episode for episode).
STARTS_KEY_VERSION = "1.1"
#: Version of the results JSON layout written by ``frbench evaluate``.
RESULTS_SCHEMA_VERSION = 1

#: Evaluation episode length [s].
EPISODE_SECONDS = 5.0

#: The standard grid a leaderboard record must cover to be ranked.
STANDARD_ROBOTS = ("go2", "go1", "aliengo", "spot_like", "lite3_like")
#: The simulators of the standard and unseen grids, in the order results list them: MuJoCo and PyBullet, and PhysX
#: from protocol 1.3 on (`grid_backends`).
GRID_SIMULATORS = ("mujoco", "pybullet", "physx")
STANDARD_TERRAINS = ("flat", "rough", "slopes", "stairs", "stones", "gaps", "beams")
STANDARD_LEVELS = (1, 5, 10)
STANDARD_SEEDS = (0, 1, 2, 3)


def version_key(version: str) -> tuple[int, int]:
    """``"1.2"`` -> (1, 2): protocol versions in order."""
    major, _, minor = version.partition(".")
    return int(major), int(minor or 0)


def grid_backends(version: str = PROTOCOL_VERSION) -> tuple[str, ...]:
    """The simulators of the standard and unseen grids under protocol ``version``: MuJoCo and PyBullet, and PhysX
    from `PHYSX_PROTOCOL` on."""
    return GRID_SIMULATORS if version_key(version) >= version_key(PHYSX_PROTOCOL) else GRID_SIMULATORS[:2]


#: The current protocol's grid simulators.
STANDARD_BACKENDS = grid_backends()
#: Episodes per cell of the standard grid: 840 cells x 3 = 2520 episodes in two simulators (1260 cells in three),
#: enough for a 95 % interval of at most
#: +-2 points on the overall score even if every cell were at 50 % (1.96^2 x 0.25 / 0.02^2 = 2401 episodes).
STANDARD_EPISODES = 3

#: Protocol 1.2's unseen grid (docs/protocol.md, `frbench.robots.unseen`): real quadrupeds no policy trains on x the
#: grid's simulators x four families x levels 1 and 5 x seeds 0-3 x 3 episodes = 576 cells, 1728 episodes in two
#: simulators (864 cells, 2592 episodes in three from 1.3 on): a 95 % interval of at most +-2.4 points on the
#: overall unseen score even at 50 % in every cell (1.96^2 x 0.25 / 1728 = 0.0236^2).
UNSEEN_TERRAINS = ("flat", "rough", "slopes", "stairs")
UNSEEN_LEVELS = (1, 5)
UNSEEN_SEEDS = STANDARD_SEEDS
UNSEEN_EPISODES = STANDARD_EPISODES

#: The first protocol whose named grids hold the humanoid grid (`frbench.evaluation.grids`, ``--grid humanoid``).
HUMANOID_PROTOCOL = "1.3"
#: The humanoid grid's G1 part (docs/protocol.md, "The humanoid track"): the G1 x the grid's three simulators x the
#: four families where a humanoid recovery is defined x levels 1, 5, 10 x seeds 0-3 x 3 episodes = 144 cells, 432
#: episodes: a 95 % interval of at most +-4.7 points on the overall G1 score even at 50 % in every cell
#: (1.96 x sqrt(0.25 / 432) = 0.0471). Its second part is the unseen grid's humanoid set (`unseen_humanoids`).
HUMANOID_ROBOTS = ("g1",)
HUMANOID_TERRAINS = ("flat", "rough", "slopes", "stairs")
HUMANOID_LEVELS = (1, 5, 10)
HUMANOID_SEEDS = (0, 1, 2, 3)
HUMANOID_EPISODES = 3


def has_humanoid_grid(version: str) -> bool:
    """Whether protocol ``version`` defines the humanoid grid (`HUMANOID_PROTOCOL` and later)."""
    return version_key(version) >= version_key(HUMANOID_PROTOCOL)


def unseen_quadrupeds() -> tuple[str, ...]:
    """The unseen grid's quadrupeds (`frbench.robots.unseen.UNSEEN_QUADRUPEDS`), lightest first."""
    from frbench.robots.unseen import UNSEEN_QUADRUPEDS

    return tuple(r.name for r in UNSEEN_QUADRUPEDS)


def unseen_humanoids() -> tuple[str, ...]:
    """The unseen humanoid set, scored only for policies that drive humanoids."""
    from frbench.robots.unseen import UNSEEN_HUMANOIDS

    return tuple(r.name for r in UNSEEN_HUMANOIDS)
