"""The protocol's named evaluation grids: ``standard``, ``unseen`` (protocol 1.2) and ``humanoid`` (1.3; docs/protocol.md).

A grid is one or more *parts*, each a product robots x backends x terrains x
levels x seeds with a fixed episode count; its simulators are those of the
protocol version (`frbench.tasks.protocol.grid_backends`: MuJoCo and PyBullet,
PhysX too from 1.3 on), every function here takes the version (the current one
by default):

* ``standard``: the five quadrupeds training samples around x the simulators x the
  seven families x levels 1, 5, 10 x seeds 0-3 x 3 episodes (840 cells in two
  simulators, 1260 in three);
* ``unseen``: the real quadrupeds of `frbench.robots.unseen` x the simulators x
  flat, rough, slopes, stairs x levels 1, 5 x seeds 0-3 x 3 episodes (576
  cells in two simulators, 864 in three), plus the same product over the unseen
  humanoids for a policy that drives humanoids. A policy that does not gets no
  humanoid cells: its humanoid score is "n/a" (`not_scored`), never 0;
* ``humanoid`` (from protocol 1.3 on, `frbench.tasks.protocol.HUMANOID_PROTOCOL`):
  the G1 x the simulators x flat, rough, slopes, stairs x levels 1, 5, 10 x
  seeds 0-3 x 3 episodes (144 cells), plus the unseen grid's humanoid set as
  above (scored for a policy that drives those robots, else "n/a").

``frbench evaluate --grid standard,unseen`` (or ``--grid humanoid``) runs the union of the parts; the
results' ``config.grid`` names the grids, ``config.not_scored`` the robots a
grid has that the policy cannot drive, and `expected_cell_keys` is the set of
cells such results must hold (`frbench.leaderboard.results` checks it).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Mapping, Sequence

from frbench.errors import FrbenchError
from frbench.tasks import protocol


@dataclass(frozen=True)
class GridPart:
    """A product of cells (robots x backends x terrains x levels x seeds), ``episodes`` per cell."""

    robots: tuple[str, ...]
    backends: tuple[str, ...]
    terrains: tuple[str, ...]
    levels: tuple[int, ...]
    seeds: tuple[int, ...]
    episodes: int

    def keys(self, robots: Sequence[str] | None = None) -> list[tuple]:
        """Cell keys (robot, backend, terrain, level, seed), robots limited to ``robots`` if given."""
        chosen = [r for r in self.robots if robots is None or r in robots]
        return list(itertools.product(chosen, self.backends, self.terrains, self.levels, self.seeds))


def standard_part(version: str = protocol.PROTOCOL_VERSION) -> GridPart:
    """The standard grid (`frbench.tasks.protocol` STANDARD_*) under protocol ``version``."""
    p = protocol
    return GridPart(p.STANDARD_ROBOTS, p.grid_backends(version), p.STANDARD_TERRAINS, p.STANDARD_LEVELS,
                    p.STANDARD_SEEDS, p.STANDARD_EPISODES)


def unseen_part(humanoids: bool = False, version: str = protocol.PROTOCOL_VERSION) -> GridPart:
    """The unseen grid's quadrupeds, or (``humanoids``) its humanoid set, under protocol ``version``."""
    p = protocol
    robots = p.unseen_humanoids() if humanoids else p.unseen_quadrupeds()
    return GridPart(robots, p.grid_backends(version), p.UNSEEN_TERRAINS, p.UNSEEN_LEVELS, p.UNSEEN_SEEDS,
                    p.UNSEEN_EPISODES)


def humanoid_part(version: str = protocol.PROTOCOL_VERSION) -> GridPart:
    """The humanoid grid's G1 part (`frbench.tasks.protocol` HUMANOID_*) under protocol ``version``."""
    p = protocol
    return GridPart(p.HUMANOID_ROBOTS, p.grid_backends(version), p.HUMANOID_TERRAINS, p.HUMANOID_LEVELS,
                    p.HUMANOID_SEEDS, p.HUMANOID_EPISODES)


def grid_parts(name: str, version: str = protocol.PROTOCOL_VERSION) -> tuple[GridPart, ...]:
    """The parts of a named grid under protocol ``version`` (the unseen grid's humanoid set is the second part of
    ``unseen`` and of ``humanoid``); ``humanoid`` under a protocol before 1.3 is a one-line error."""
    if name == "standard":
        return (standard_part(version),)
    if name == "unseen":
        return (unseen_part(version=version), unseen_part(humanoids=True, version=version))
    if name == "humanoid":
        if not protocol.has_humanoid_grid(version):
            raise FrbenchError(f"--grid humanoid: the humanoid grid is defined from protocol "
                               f"{protocol.HUMANOID_PROTOCOL} on, not under protocol {version}")
        return (humanoid_part(version), unseen_part(humanoids=True, version=version))
    raise FrbenchError(f"--grid {name!r}: unknown grid; known: {', '.join(GRID_NAMES)}")


#: The named grids, in the order results list them.
GRID_NAMES = ("standard", "unseen", "humanoid")


def parse_grids(text: str, version: str = protocol.PROTOCOL_VERSION) -> list[str]:
    """Comma-separated grid names (``standard,unseen``, ``humanoid``) -> the names in canonical order; a one-line
    error for an empty list, an unknown name or a grid protocol ``version`` does not define."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise FrbenchError(f"--grid is empty: expected one or more of {', '.join(GRID_NAMES)}, comma-separated")
    for name in names:
        grid_parts(name, version)
    return [n for n in GRID_NAMES if n in names]


@dataclass(frozen=True)
class ResolvedGrid:
    """What a set of named grids means for one policy: its robots, axes, cells and the robots it cannot drive."""

    names: tuple[str, ...]
    #: The union of the parts' axes (its product is more than ``keys`` when the parts differ).
    axes: GridPart
    keys: tuple[tuple, ...]
    not_scored: Mapping[str, str]


def _union(values) -> tuple:
    return tuple(dict.fromkeys(values))


def resolve_grids(names: Sequence[str], supports, version: str = protocol.PROTOCOL_VERSION) -> ResolvedGrid:
    """The cells of ``names`` under protocol ``version`` for a policy: ``supports(robot_name) -> bool`` says whether
    it drives a robot. A part's robots the policy cannot drive go to ``not_scored`` (name -> reason); a grid whose
    every quadruped is undrivable is an error."""
    robots, not_scored, keys, parts = [], {}, [], []
    for name in names:
        for index, part in enumerate(grid_parts(name, version)):
            drivable = [r for r in part.robots if supports(r)]
            for robot in part.robots:
                if robot not in drivable:
                    not_scored[robot] = f"the policy does not drive this robot ({name} grid: scored n/a, not 0)"
            if not drivable and index == 0:
                raise FrbenchError(f"--grid {name}: the policy drives none of its robots ({', '.join(part.robots)})")
            if drivable:
                parts.append(part)
                robots += drivable
                keys += part.keys(drivable)
    episodes = {p.episodes for p in parts}
    if len(episodes) != 1:  # pragma: no cover - every named grid has 3 episodes per cell
        raise FrbenchError(f"--grid {','.join(names)}: parts with different episode counts {sorted(episodes)}")
    axes = GridPart(_union(robots), _union(b for p in parts for b in p.backends),
                    _union(t for p in parts for t in p.terrains), tuple(sorted({lv for p in parts for lv in p.levels})),
                    tuple(sorted({s for p in parts for s in p.seeds})), episodes.pop())
    return ResolvedGrid(tuple(names), axes, tuple(dict.fromkeys(keys)), dict(not_scored))


def expected_cell_keys(config: Mapping, version: str = protocol.PROTOCOL_VERSION) -> set[tuple] | None:
    """The cells results of ``config`` under protocol ``version`` must hold when it names grids (None: a plain
    product of its axes). A grid part contributes its cells for the robots ``config.robots`` lists (a humanoid set
    that was not scored contributes none)."""
    names = config.get("grid")
    if not names:
        return None
    keys: set[tuple] = set()
    for name in names:
        for part in grid_parts(name, version):
            keys.update(part.keys(config["robots"]))
    return keys


def grid_of_robot(robot: str) -> str | None:
    """``standard``, ``unseen``, ``humanoid`` (the G1) or ``unseen-humanoid`` for a robot of a named grid, else
    None."""
    if robot in protocol.STANDARD_ROBOTS:
        return "standard"
    if robot in protocol.HUMANOID_ROBOTS:
        return "humanoid"
    if robot in protocol.unseen_quadrupeds():
        return "unseen"
    if robot in protocol.unseen_humanoids():
        return "unseen-humanoid"
    return None
