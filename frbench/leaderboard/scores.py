"""Leaderboard scores, recomputed from a results object's cells (submitted summaries are never trusted).

Every score is a mean of cell success rates (a cell is one robot x backend x
terrain x level x seed), so each cell weighs the same:

* ``overall``: over all scored cells; ``per_family`` / ``per_backend`` /
  ``per_robot``: over the cells of that terrain family / backend / robot;
* ``sim_to_sim_gap``: for each (robot, terrain, level) and each pair of grid
  simulators that ran it (MuJoCo and PyBullet; with PhysX, protocol 1.3, also
  MuJoCo and PhysX, PyBullet and PhysX), ``|mean over seeds (first) - mean over
  seeds (second)|``, averaged; null when no (robot, terrain, level) has two
  simulators. With more than one pair, ``pairwise_gaps`` holds the same mean per
  pair (``mujoco-pybullet``, ``mujoco-physx``, ``pybullet-physx``); records of
  MuJoCo and PyBullet alone keep exactly the scores they had.

A record whose cells cover the standard grid of its protocol version
(``frbench.tasks.protocol``: its simulators are the version's), each standard
cell with at least ``STANDARD_EPISODES`` episodes, is on the ``main`` track and
is scored on the standard grid's cells only (robots, families, levels and seeds
of the standard grid in any grid simulator), so main records are comparable. From protocol 1.3 on, a record that is not main
and whose cells cover the humanoid grid's G1 part (``frbench.evaluation.grids.humanoid_part``,
each cell with at least ``HUMANOID_EPISODES`` episodes) and the unseen humanoid set
(but the robots ``config.not_scored`` says the policy cannot drive) is on the
``humanoid`` track, scored on the G1 part's cells, its humanoid set apart
(`generalisation`'s ``humanoids``). Any other record is ``partial`` and scored on all its
cells. Ranking: overall success (higher first), then sim-to-sim gap (lower
first, none last), then submission time, then id — only among records of one
protocol version (`check_same_protocol`). Each score has a 95 % stratified-
bootstrap interval (`score_intervals`), shown beside it; neighbours whose
overall intervals overlap are marked on the board.

Means use ``math.fsum`` so they do not depend on the order of the cells.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Iterable, Mapping, Sequence

import numpy as np

from frbench.errors import FrbenchError
from frbench.evaluation.intervals import bootstrap_rates, percentile_interval, sim_to_sim_gaps, sorted_cells
from frbench.evaluation.results import SIM_TO_SIM_PAIRS
from frbench.tasks.protocol import (
    GRID_SIMULATORS,
    HUMANOID_EPISODES,
    HUMANOID_PROTOCOL,
    KNOWN_PROTOCOL_VERSIONS,
    PROTOCOL_VERSION,
    STANDARD_EPISODES,
    has_humanoid_grid,
    version_key,
)

#: (robot, backend, terrain, level) -> (sum of the cells' success rates, number of cells).
Groups = dict[tuple[str, str, str, int], tuple[float, int]]

#: The newest protocol version: its grids hold every grid simulator.
NEWEST = KNOWN_PROTOCOL_VERSIONS[-1]


@lru_cache(maxsize=8)
def standard_grid(version: str = NEWEST) -> frozenset:
    """The standard grid's cells under protocol ``version`` (its simulators, `grid_backends`; the newest by default:
    in every grid simulator, the cells a main record is scored on)."""
    from frbench.evaluation.grids import standard_part

    return frozenset(standard_part(version).keys())


def cell_key(cell: Mapping) -> tuple:
    return (cell["robot"], cell["backend"], cell["terrain"], cell["level"], cell["seed"])


@lru_cache(maxsize=8)
def unseen_grid(version: str = NEWEST) -> frozenset:
    """The unseen grid's quadruped cells (protocol 1.2, `frbench.evaluation.grids`) under protocol ``version`` (the
    newest by default: in every grid simulator, the cells scored as unseen)."""
    from frbench.evaluation.grids import unseen_part

    return frozenset(unseen_part(version=version).keys())


@lru_cache(maxsize=8)
def unseen_humanoid_grid(version: str = NEWEST) -> frozenset:
    """The unseen grid's humanoid cells (scored only for policies that drive humanoids) under ``version``."""
    from frbench.evaluation.grids import unseen_part

    return frozenset(unseen_part(humanoids=True, version=version).keys())


@lru_cache(maxsize=8)
def humanoid_grid(version: str = NEWEST) -> frozenset:
    """The humanoid grid's G1 cells under protocol ``version`` (1.3 on; `frbench.evaluation.grids.humanoid_part`;
    the newest by default: in every grid simulator, the cells a humanoid-track record is scored on)."""
    from frbench.evaluation.grids import humanoid_part

    return frozenset(humanoid_part(version).keys())


def humanoid_set_grid(version: str, not_scored: Iterable[str] = ()) -> frozenset:
    """The unseen humanoid set's cells under protocol ``version`` for the robots not in ``not_scored`` (those the
    policy cannot drive: `frbench.evaluation.grids.resolve_grids`)."""
    skipped = set(not_scored)
    return frozenset(key for key in unseen_humanoid_grid(version) if key[0] not in skipped)


def needs_unseen_grid(protocol_version: str | None) -> bool:
    """Whether a main-track record of this protocol version must hold the unseen grid (1.2 and later)."""
    return protocol_version is not None and version_key(protocol_version) >= (1, 2)


def _grid_shortfall(episodes: Mapping[tuple, int], grid: frozenset, label: str,
                    needed: int = STANDARD_EPISODES) -> str | None:
    """Why ``episodes`` (cell key -> episodes) do not cover ``grid`` with ``needed`` episodes per cell (None when
    they do)."""
    missing = len(grid - episodes.keys())
    if missing:
        return f"{missing} of the {label} grid's {len(grid)} cells are missing"
    short = sum(1 for key in grid if episodes[key] < needed)
    if short:
        return f"{short} {label} cells have fewer than {needed} episodes"
    return None


def main_track_shortfall(cells: Sequence[Mapping], protocol_version: str | None = None) -> str | None:
    """Why the cells are not a main-track record (``None`` when they are).

    Main means: every cell of the standard grid present, each with at least
    ``STANDARD_EPISODES`` episodes (the count that bounds the overall score's
    95 % interval at +-2 points; ``frbench.tasks.protocol``); from protocol 1.2
    on, the unseen grid's quadruped cells likewise (a 1.2 record without them is
    partial). The grids' simulators are those of ``protocol_version`` (the current
    protocol's when None): from 1.3 on, PhysX's cells too.
    """
    version = protocol_version or PROTOCOL_VERSION
    episodes = {cell_key(c): c["episodes"] for c in cells}
    shortfall = _grid_shortfall(episodes, standard_grid(version), "standard")
    if shortfall is None and needs_unseen_grid(protocol_version):
        shortfall = _grid_shortfall(episodes, unseen_grid(version), "unseen")
    return shortfall


def humanoid_track_shortfall(cells: Sequence[Mapping], protocol_version: str | None = None,
                             not_scored: Iterable[str] = ()) -> str | None:
    """Why the cells are not a humanoid-track record (``None`` when they are): from protocol 1.3 on, every cell of
    the humanoid grid's G1 part with at least ``HUMANOID_EPISODES`` episodes, then the unseen humanoid set's cells
    likewise for every robot of the set but those in ``not_scored`` (the results' ``config.not_scored``: robots
    the policy cannot drive, scored n/a). Whether the record is main is `main_track_shortfall`'s question."""
    version = protocol_version or PROTOCOL_VERSION
    if not has_humanoid_grid(version):
        return f"the humanoid grid is defined from protocol {HUMANOID_PROTOCOL} on, not under {version}"
    episodes = {cell_key(c): c["episodes"] for c in cells}
    return (_grid_shortfall(episodes, humanoid_grid(version), "humanoid G1", HUMANOID_EPISODES)
            or _grid_shortfall(episodes, humanoid_set_grid(version, not_scored), "humanoid set", HUMANOID_EPISODES))


def track_of(cells: Sequence[Mapping], protocol_version: str | None = None, not_scored: Iterable[str] = ()) -> str:
    """``main`` when the cells cover the whole standard grid (and, from 1.2 on, the unseen grid) with enough
    episodes per cell; else ``humanoid`` when they cover the humanoid grid (1.3 on; `humanoid_track_shortfall`,
    ``not_scored`` the robots the policy cannot drive); else ``partial``."""
    if main_track_shortfall(cells, protocol_version) is None:
        return "main"
    return "humanoid" if humanoid_track_shortfall(cells, protocol_version, not_scored) is None else "partial"


def results_track(results: Mapping) -> str:
    """`track_of` a checked results object (its cells, protocol version and ``config.not_scored``)."""
    return track_of(results["cells"], results["protocol_version"], results["config"].get("not_scored", {}))


def scored_cells(cells: Sequence[Mapping], track: str) -> list[Mapping]:
    """The cells a record is scored on: the standard grid's for main records, the humanoid grid's G1 part for
    humanoid ones; for partial ones all cells but the unseen grid's (scored apart, `unseen_cells`), or all if it
    has no others."""
    if track == "main":
        return [c for c in cells if cell_key(c) in standard_grid()]
    if track == "humanoid":
        return [c for c in cells if cell_key(c) in humanoid_grid()]
    unseen = unseen_grid() | unseen_humanoid_grid()
    others = [c for c in cells if cell_key(c) not in unseen]
    return others or list(cells)


def matched_standard_cells(cells: Sequence[Mapping]) -> list[Mapping]:
    """The standard grid's cells on the unseen grid's families and levels (flat, rough, slopes, stairs at levels 1
    and 5: 320 cells): the same terrains on the training-distribution robots, so that standard − unseen measures
    the bodies, not the terrain difficulty."""
    from frbench.tasks.protocol import UNSEEN_LEVELS, UNSEEN_TERRAINS

    return [c for c in cells if cell_key(c) in standard_grid() and c["terrain"] in UNSEEN_TERRAINS
            and c["level"] in UNSEEN_LEVELS]


def unseen_cells(cells: Sequence[Mapping], humanoids: bool = False) -> list[Mapping]:
    """The record's cells of the unseen grid (its quadrupeds, or its humanoid set)."""
    grid = unseen_humanoid_grid() if humanoids else unseen_grid()
    return [c for c in cells if cell_key(c) in grid]


def groups_of(cells: Iterable[Mapping]) -> Groups:
    """Aggregate cells per (robot, backend, terrain, level)."""
    rates: dict[tuple, list[float]] = {}
    for cell in cells:
        rates.setdefault((cell["robot"], cell["backend"], cell["terrain"], cell["level"]), []).append(cell["success_rate"])
    return {key: (math.fsum(values), len(values)) for key, values in sorted(rates.items(), key=lambda kv: _sort_key(kv[0]))}


def _sort_key(key: tuple) -> tuple:
    return tuple((0, v, "") if isinstance(v, int) else (1, 0, v) for v in key)


def _mean(parts: Iterable[tuple[float, int]]) -> float | None:
    parts = list(parts)
    count = sum(n for _, n in parts)
    return math.fsum(s for s, _ in parts) / count if count else None


def aggregate(groups: Groups, *, robot: str | None = None, backend: str | None = None, terrain: str | None = None) -> dict | None:
    """Scores over the groups matching the filters; ``None`` if none match."""
    chosen = {
        k: v for k, v in groups.items()
        if (robot is None or k[0] == robot) and (backend is None or k[1] == backend) and (terrain is None or k[2] == terrain)
    }
    if not chosen:
        return None

    def by(position: int) -> dict:
        names = sorted({k[position] for k in chosen}, key=str)
        return {name: _mean(v for k, v in chosen.items() if k[position] == name) for name in names}

    per_family_level: dict[str, dict[str, float]] = {}
    for family in sorted({k[2] for k in chosen}):
        levels = sorted({k[3] for k in chosen if k[2] == family})
        per_family_level[family] = {
            str(level): _mean(v for k, v in chosen.items() if k[2] == family and k[3] == level) for level in levels
        }
    gaps: dict[tuple[str, str], list[float]] = {}
    for robot_, terrain_, level in sorted({(k[0], k[2], k[3]) for k in chosen}, key=str):
        means = {b: chosen[(robot_, b, terrain_, level)] for b in GRID_SIMULATORS if (robot_, b, terrain_, level) in chosen}
        for first, second in SIM_TO_SIM_PAIRS:
            if first in means and second in means:
                gaps.setdefault((first, second), []).append(
                    abs(means[first][0] / means[first][1] - means[second][0] / means[second][1]))
    every = [gap for pair in gaps.values() for gap in pair]
    return {
        "overall": _mean(chosen.values()),
        "per_family": by(2),
        "per_backend": by(1),
        "per_robot": by(0),
        "per_family_level": per_family_level,
        "sim_to_sim_gap": math.fsum(every) / len(every) if every else None,
        **({"pairwise_gaps": {pair_name(*pair): math.fsum(values) / len(values) for pair, values in gaps.items()}}
           if len(gaps) > 1 else {}),
        "cells": sum(n for _, n in chosen.values()),
    }


def pair_name(first: str, second: str) -> str:
    """``mujoco-physx``: a pair of simulators in `pairwise_gaps` and `score_intervals`' ``signed_gaps``."""
    return f"{first}-{second}"


def _scores_of(cells: Sequence[Mapping]) -> dict:
    full = aggregate(groups_of(cells))
    assert full is not None  # results always have cells
    return {
        "overall": full["overall"],
        "per_family": full["per_family"],
        "per_backend": full["per_backend"],
        "per_robot": full["per_robot"],
        "sim_to_sim_gap": full["sim_to_sim_gap"],
        **({"pairwise_gaps": full["pairwise_gaps"]} if "pairwise_gaps" in full else {}),
        "cells": full["cells"],
        "episodes": sum(c["episodes"] for c in cells),
    }


def record_scores(cells: Sequence[Mapping], track: str) -> dict:
    """The ``scores`` stored in a record: the standard (or, partial, the record's own) grid's; with the unseen
    grid's cells also ``unseen`` (its quadrupeds) and ``unseen_humanoids`` (when the policy drives humanoids)
    with the same fields, and ``generalisation_gap`` = the matched standard cells' mean (`matched_standard_cells`)
    − the unseen mean. A humanoid-track record: its G1 part's scores, and ``unseen_humanoids`` when it holds the
    humanoid set. Records without unseen cells
    (every record before protocol 1.2) keep exactly their former scores."""
    scores = _scores_of(scored_cells(cells, track))
    if track == "humanoid":
        humanoids = unseen_cells(cells, humanoids=True)
        if humanoids:
            scores["unseen_humanoids"] = _scores_of(humanoids)
        return scores
    unseen = unseen_cells(cells)
    matched = matched_standard_cells(cells)
    if unseen and matched:
        scores["unseen"] = _scores_of(unseen)
        scores["generalisation_gap"] = _scores_of(matched)["overall"] - scores["unseen"]["overall"]
        humanoids = unseen_cells(cells, humanoids=True)
        if humanoids:
            scores["unseen_humanoids"] = _scores_of(humanoids)
    return scores


def check_same_protocol(versions: Iterable[str]) -> str | None:
    """The one protocol version of records about to be ranked together; ``FrbenchError`` if they differ."""
    found = sorted(set(versions))
    if len(found) > 1:
        raise FrbenchError(f"refusing to rank records of protocol versions {', '.join(found)} together: "
                           "a success rate means something else under each version")
    return found[0] if found else None


def rank_key(scores: Mapping, submitted: str, record_id: str) -> tuple:
    """Sort key: overall success descending, gap ascending (none last), then time, then id."""
    gap = scores.get("sim_to_sim_gap")
    return (-scores["overall"], gap is None, gap if gap is not None else 0.0, submitted, record_id)


# --------------------------------------------------------------------------- intervals


@lru_cache(maxsize=256)
def _replicates(fingerprint: tuple) -> tuple[tuple, np.ndarray]:
    """(sorted cells, bootstrap rates (R, cells)) of a fingerprint ((robot, backend, terrain, level, seed,
    successes, episodes), ...); cached because every rendering of the board asks again."""
    cells = [dict(zip(("robot", "backend", "terrain", "level", "seed", "successes", "episodes"), row)) for row in fingerprint]
    ordered = sorted_cells(cells)
    return tuple(ordered), bootstrap_rates(ordered)


def _fingerprint(cells: Iterable[Mapping]) -> tuple:
    return tuple(sorted((c["robot"], c["backend"], c["terrain"], c["level"], c["seed"], c["successes"], c["episodes"])
                        for c in cells))


def score_intervals(cells: Sequence[Mapping], *, robot: str | None = None, backend: str | None = None,
                    terrain: str | None = None) -> dict | None:
    """95 % stratified-bootstrap intervals [low, high] of the `aggregate` scores of ``cells`` matching the filters
    (``overall``, ``per_family``, ``per_backend``, ``per_robot``) and of the signed gap MuJoCo − PyBullet
    (``signed_gap``: [point, low, high], None without both backends), and with more than one pair of grid
    simulators each pair's signed gap first − second (``signed_gaps``: `pair_name` -> [point, low, high]); None if
    no cell matches.

    The replicates are drawn once over all of ``cells`` (`frbench.evaluation.intervals.bootstrap_rates`,
    seeded), so a filtered score's interval comes from the same resampled cells as the unfiltered one.
    """
    ordered, rates = _replicates(_fingerprint(cells))
    keep = np.array([(robot is None or c["robot"] == robot) and (backend is None or c["backend"] == backend)
                     and (terrain is None or c["terrain"] == terrain) for c in ordered])
    if not keep.any():
        return None
    chosen = [c for c, k in zip(ordered, keep) if k]
    sub = rates[:, keep]
    k = np.array([c["successes"] for c in chosen])
    n = np.array([c["episodes"] for c in chosen])

    def by(field: str) -> dict:
        names = sorted({c[field] for c in chosen}, key=str)
        out = {}
        for name in names:
            mask = np.array([c[field] == name for c in chosen])
            out[name] = list(percentile_interval(sub[:, mask].mean(axis=1), k[mask].sum(), n[mask].sum()))
        return out

    signed = {}
    for first, second in SIM_TO_SIM_PAIRS:
        gaps = sim_to_sim_gaps(chosen, sub, first, second)
        if gaps is not None:
            point = float(sim_to_sim_gaps(chosen, _points(chosen), first, second)[0])
            signed[pair_name(first, second)] = [point, *percentile_interval(gaps)]
    return {
        "overall": list(percentile_interval(sub.mean(axis=1), k.sum(), n.sum())),
        "per_family": by("terrain"),
        "per_backend": by("backend"),
        "per_robot": by("robot"),
        "signed_gap": signed.get(pair_name(*SIM_TO_SIM_PAIRS[0])),
        **({"signed_gaps": signed} if len(signed) > 1 else {}),
    }


def _points(cells: Sequence[Mapping]) -> np.ndarray:
    return np.array([[c["successes"] / c["episodes"] for c in cells]])


def overlaps(a: Sequence[float] | None, b: Sequence[float] | None) -> bool:
    """Whether two intervals [low, high] overlap (None never does)."""
    return a is not None and b is not None and a[0] <= b[1] and b[0] <= a[1]


def generalisation(cells: Sequence[Mapping], track: str) -> dict | None:
    """The unseen grid's scores of a record's cells with 95 % intervals, None without unseen cells:
    ``unseen`` [score, low, high] over its quadruped cells, ``matched`` [score, low, high] over the standard cells
    on the same families and levels (`matched_standard_cells`), ``gap`` [point, low, high] = matched − unseen (per
    bootstrap replicate: both resampled), and ``humanoids`` [score, low, high] over the humanoid set, or None
    ("n/a": the policy does not drive humanoids). A humanoid-track record (``track``) has ``humanoids`` only: its
    humanoid set's [score, low, high], or None."""
    if track == "humanoid":
        return {"humanoids": _humanoid_set_score(cells)}
    unseen = unseen_cells(cells)
    scored = matched_standard_cells(cells)
    if not unseen or not scored:
        return None
    u_point, u_reps, u_k, u_n = _mean_and_replicates(unseen)
    s_point, s_reps, s_k, s_n = _mean_and_replicates(scored)
    return {
        "unseen": [u_point, *percentile_interval(u_reps, u_k, u_n)],
        "matched": [s_point, *percentile_interval(s_reps, s_k, s_n)],
        "gap": [s_point - u_point, *percentile_interval(s_reps - u_reps)],
        "humanoids": _humanoid_set_score(cells),
    }


def _humanoid_set_score(cells: Sequence[Mapping]) -> list[float] | None:
    """[score, low, high] of the record's unseen humanoid set cells (95 % interval), None without them."""
    humanoid = unseen_cells(cells, humanoids=True)
    if not humanoid:
        return None
    point, replicates, successes, episodes = _mean_and_replicates(humanoid)
    return [point, *percentile_interval(replicates, successes, episodes)]


def _mean_and_replicates(chosen: Sequence[Mapping]) -> tuple[float, np.ndarray, int, int]:
    """(mean cell success, its bootstrap replicates (R,), successes, episodes) of ``chosen`` cells."""
    _, rates = _replicates(_fingerprint(chosen))
    point = math.fsum(c["successes"] / c["episodes"] for c in chosen) / len(chosen)
    return point, rates.mean(axis=1), sum(c["successes"] for c in chosen), sum(c["episodes"] for c in chosen)
