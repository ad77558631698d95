"""Checking a results object (what ``frbench evaluate`` writes) against its schema and itself.

:func:`check_results` raises a :class:`~frbench.errors.ResultsError` whose
message is ``field: problem`` (no file name; callers prefix it). It checks, in
order: ``schema_version``, ``protocol_version``, the JSON Schema
(``frbench/schemas/results-v1.schema.json``), then that the file agrees with
itself:

* every robot in the cells has a URDF checksum in ``robots``; a policy with a
  checkpoint has its sha256;
* the cells cover ``config``'s robots x backends x terrains x levels x seeds
  exactly once each, with ``config.episodes`` episodes each;
* each cell's ``episodes``, ``successes``, ``success_rate`` (= successes /
  episodes within 1e-9), ``diverged``, ``rollover_rate`` and ``mean_*`` agree
  with its per-episode records (means over all its episodes;
  ``mean_time_to_recover`` over the successful episodes' non-null
  ``time_to_recover`` (or over every episode's non-null one), null when none);
* ``summary`` has one entry per (robot, backend, terrain, level) whose
  ``success_rate_mean`` is the mean of its cells' success rates and ``n_seeds``
  their number; ``sim_to_sim`` has one entry per (robot, terrain, level) that
  two or more grid simulators ran, with their means and each pair's gap
  (``gap`` = mujoco - pybullet, or its absolute value; ``gap_mujoco_physx``,
  ``gap_pybullet_physx``).

``frbench evaluate`` can call it on its own output before writing.
"""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any, Iterable

from frbench.errors import FrbenchError, ResultsError
from frbench.evaluation.grids import expected_cell_keys
from frbench.evaluation.intervals import wilson_interval
from frbench.schemas import SchemaViolation, validate
from frbench.evaluation.results import SIM_TO_SIM_PAIRS, gap_field
from frbench.leaderboard.reuse import check_reused
from frbench.tasks.protocol import GRID_SIMULATORS, KNOWN_PROTOCOL_VERSIONS, RESULTS_SCHEMA_VERSION

#: Tolerance on rates recomputed from counts.
RATE_TOLERANCE = 1e-9
#: Relative tolerance on means recomputed from episodes (absorbs float32 and summation order).
MEAN_RTOL = 1e-6
MEAN_ATOL = 1e-9

CELL_KEY = ("robot", "backend", "terrain", "level", "seed")
GROUP_KEY = ("robot", "backend", "terrain", "level")
PAIR_KEY = ("robot", "terrain", "level")

#: Cell field -> the episode field it is the mean of.
MEAN_FIELDS = {
    "mean_final_displacement": "final_displacement",
    "mean_max_displacement": "max_displacement",
    "mean_energy": "energy",
    "mean_smoothness": "smoothness",
    "mean_peak_contact_force": "peak_contact_force",
}


def describe(key: Iterable, names: Iterable[str]) -> str:
    """``robot=go2 backend=mujoco ...`` for a grid key."""
    return " ".join(f"{n}={v}" for n, v in zip(names, key))


def _fmt(x: float) -> str:
    return f"{x:.10g}"


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=MEAN_RTOL, abs_tol=MEAN_ATOL)


def check_schema_version(results: dict) -> None:
    """The first check: is this a results file this frbench reads?"""
    if "schema_version" not in results:
        raise ResultsError(
            f"schema_version: required field is missing; expected {RESULTS_SCHEMA_VERSION} "
            "(is this a results file written by `frbench evaluate`?)"
        )
    version = results["schema_version"]
    if isinstance(version, bool) or version != RESULTS_SCHEMA_VERSION:
        raise ResultsError(
            f"schema_version: {version!r} is not supported; this frbench reads results schema_version {RESULTS_SCHEMA_VERSION}"
        )


def check_protocol_version(results: dict) -> None:
    """Refuse results of a benchmark protocol this frbench does not know."""
    if "protocol_version" not in results:
        raise ResultsError("protocol_version: required field is missing")
    version = results["protocol_version"]
    if not isinstance(version, str) or version not in KNOWN_PROTOCOL_VERSIONS:
        raise ResultsError(
            f"protocol_version: unknown protocol version {version!r}; known: {', '.join(KNOWN_PROTOCOL_VERSIONS)}"
        )


def check_results(results: Any, *, schema_checked: bool = False) -> None:
    """Raise ``ResultsError('field: problem')`` unless ``results`` is a valid, self-consistent results object.

    ``schema_checked``: the caller already validated ``results`` against the results schema.
    """
    if not isinstance(results, dict):
        raise ResultsError("(top level): expected a JSON object")
    check_schema_version(results)
    check_protocol_version(results)
    if not schema_checked:
        validate(results, "results-v1")
    _check_provenance(results)
    cells = _check_cells(results)
    _check_episodes(results, cells)
    _check_summary(results)
    check_reused(results)


def _check_provenance(results: dict) -> None:
    policy = results["policy"]
    if policy["checkpoint"] is not None and policy["sha256"] is None:
        raise ResultsError("policy.sha256: required when policy.checkpoint is set (the checkpoint's checksum)")
    for index, cell in enumerate(results["cells"]):
        if cell["robot"] not in results["robots"]:
            raise SchemaViolation(
                f"robots.{cell['robot']}",
                f"required field is missing: cells[{index}] use robot {cell['robot']!r} but its URDF checksum is not recorded",
            )


def _check_cells(results: dict) -> dict[tuple, int]:
    """Cells cover config's grid exactly once; returns cell key -> index."""
    config = results["config"]
    axes = {"robot": "robots", "backend": "backends", "terrain": "terrains", "level": "levels", "seed": "seeds"}
    index_of: dict[tuple, int] = {}
    for index, cell in enumerate(results["cells"]):
        for field, listing in axes.items():
            if cell[field] not in config[listing]:
                raise ResultsError(f"cells[{index}].{field}: {cell[field]!r} is not in config.{listing}")
        key = tuple(cell[f] for f in CELL_KEY)
        if key in index_of:
            raise ResultsError(f"cells[{index}]: duplicate cell {describe(key, CELL_KEY)} (also cells[{index_of[key]}])")
        index_of[key] = index
        if cell["episodes"] != config["episodes"]:
            raise ResultsError(f"cells[{index}].episodes: {cell['episodes']} but config.episodes is {config['episodes']}")
        if cell["successes"] > cell["episodes"]:
            raise ResultsError(f"cells[{index}].successes: {cell['successes']} successes exceed {cell['episodes']} episodes")
        expected = cell["successes"] / cell["episodes"]
        if abs(cell["success_rate"] - expected) > RATE_TOLERANCE:
            raise ResultsError(
                f"cells[{index}].success_rate: {_fmt(cell['success_rate'])} differs from successes/episodes = "
                f"{cell['successes']}/{cell['episodes']} = {_fmt(expected)}"
            )
        if cell["diverged"] > cell["episodes"]:
            raise ResultsError(f"cells[{index}].diverged: {cell['diverged']} exceeds {cell['episodes']} episodes")
    named = _named_grid_keys(config, results["protocol_version"])
    if named is not None:
        for key in sorted(named - index_of.keys(), key=str)[:1]:
            raise ResultsError(f"cells: no cell for {describe(key, CELL_KEY)}, which config.grid {config['grid']} holds")
        for key in sorted(index_of.keys() - named, key=str)[:1]:
            raise ResultsError(f"cells[{index_of[key]}]: {describe(key, CELL_KEY)} is not a cell of config.grid {config['grid']}")
        return index_of
    expected_cells = len(config["robots"]) * len(config["backends"]) * len(config["terrains"]) * len(config["levels"]) * len(config["seeds"])
    if len(index_of) != expected_cells:
        for robot in config["robots"]:
            for backend in config["backends"]:
                for terrain in config["terrains"]:
                    for level in config["levels"]:
                        for seed in config["seeds"]:
                            key = (robot, backend, terrain, level, seed)
                            if key not in index_of:
                                raise ResultsError(f"cells: no cell for {describe(key, CELL_KEY)}, which config lists")
    return index_of


def _named_grid_keys(config: dict, version: str) -> set[tuple] | None:
    """The cells of ``config.grid`` under protocol ``version`` (None when it names no grid); an unknown grid name is
    a one-line error."""
    if "grid" not in config:
        return None
    try:
        return expected_cell_keys(config, version)
    except FrbenchError as exc:
        raise ResultsError(f"config.grid: {str(exc).removeprefix('--grid ')}") from None


def _check_episodes(results: dict, cells: dict[tuple, int]) -> None:
    grouped: dict[int, list[dict]] = defaultdict(list)
    seen: dict[tuple, int] = {}
    for index, episode in enumerate(results["episodes"]):
        key = tuple(episode[f] for f in CELL_KEY)
        cell_index = cells.get(key)
        if cell_index is None:
            raise ResultsError(f"episodes[{index}]: no cell for {describe(key, CELL_KEY)}")
        full = key + (episode["episode"],)
        if full in seen:
            raise ResultsError(
                f"episodes[{index}].episode: episode {episode['episode']} of {describe(key, CELL_KEY)} "
                f"appears twice (also episodes[{seen[full]}])"
            )
        seen[full] = index
        grouped[cell_index].append(episode)
    for index, cell in enumerate(results["cells"]):
        where = f"cells[{index}]"
        episodes = grouped.get(index, [])
        if cell["episodes"] != len(episodes):
            raise ResultsError(
                f"{where}.episodes: {cell['episodes']} but {len(episodes)} episode records have "
                f"{describe((cell[f] for f in CELL_KEY), CELL_KEY)}"
            )
        successes = sum(1 for e in episodes if e["success"])
        if cell["successes"] != successes:
            raise ResultsError(f"{where}.successes: {cell['successes']} but {successes} of its {len(episodes)} episode records succeed")
        diverged = sum(1 for e in episodes if e["diverged"])
        if cell["diverged"] != diverged:
            raise ResultsError(f"{where}.diverged: {cell['diverged']} but {diverged} of its episode records diverged")
        rollover = sum(1 for e in episodes if e["rolled_over"]) / len(episodes)
        if abs(cell["rollover_rate"] - rollover) > RATE_TOLERANCE:
            raise ResultsError(
                f"{where}.rollover_rate: {_fmt(cell['rollover_rate'])} differs from the fraction of its episodes "
                f"that rolled over, {_fmt(rollover)}"
            )
        for field, source in MEAN_FIELDS.items():
            mean = math.fsum(e[source] for e in episodes) / len(episodes)
            if not _close(cell[field], mean):
                raise ResultsError(f"{where}.{field}: {_fmt(cell[field])} differs from the mean of its episodes' {source}, {_fmt(mean)}")
        # over the successful episodes (what frbench evaluate writes) or over every episode that has a time
        candidates = []
        for chosen in ([e for e in episodes if e["success"]], episodes):
            times = [e["time_to_recover"] for e in chosen if e["time_to_recover"] is not None]
            candidates.append(math.fsum(times) / len(times) if times else None)
        stated = cell["mean_time_to_recover"]
        if not any((stated is None and c is None) or (stated is not None and c is not None and _close(stated, c))
                   for c in candidates):
            shown = "null" if stated is None else _fmt(stated)
            wanted = "null (no episode recovered)" if candidates[0] is None else _fmt(candidates[0])
            raise ResultsError(
                f"{where}.mean_time_to_recover: {shown} differs from the mean time_to_recover of its successful episodes, {wanted}"
            )


def _check_summary_counts(index: int, entry: dict, counts: list[int], where: str) -> None:
    """The optional pooled counts and Wilson interval of a summary entry (protocol 1.1) agree with its cells."""
    for field, value in (("successes", counts[0]), ("episodes", counts[1])):
        if field in entry and entry[field] != value:
            raise ResultsError(f"summary[{index}].{field}: {entry[field]} but the cells of {where} have {value}")
    if "ci95" in entry:
        expected = wilson_interval(*counts)
        if any(abs(a - b) > RATE_TOLERANCE for a, b in zip(entry["ci95"], expected)):
            raise ResultsError(f"summary[{index}].ci95: {entry['ci95']} is not the Wilson interval of {counts[0]}/{counts[1]}")


def _check_summary(results: dict) -> None:
    rates: dict[tuple, list[float]] = defaultdict(list)
    counts: dict[tuple, list[int]] = defaultdict(lambda: [0, 0])
    for cell in results["cells"]:
        rates[tuple(cell[f] for f in GROUP_KEY)].append(cell["success_rate"])
        counts[tuple(cell[f] for f in GROUP_KEY)][0] += cell["successes"]
        counts[tuple(cell[f] for f in GROUP_KEY)][1] += cell["episodes"]
    means = {key: math.fsum(values) / len(values) for key, values in rates.items()}
    seen: dict[tuple, int] = {}
    for index, entry in enumerate(results["summary"]):
        key = tuple(entry[f] for f in GROUP_KEY)
        if key not in means:
            raise ResultsError(f"summary[{index}]: no cells for {describe(key, GROUP_KEY)}")
        if key in seen:
            raise ResultsError(f"summary[{index}]: duplicate entry for {describe(key, GROUP_KEY)} (also summary[{seen[key]}])")
        seen[key] = index
        if abs(entry["success_rate_mean"] - means[key]) > RATE_TOLERANCE:
            raise ResultsError(
                f"summary[{index}].success_rate_mean: {_fmt(entry['success_rate_mean'])} differs from the mean of its "
                f"cells' success_rate, {_fmt(means[key])}"
            )
        if entry["n_seeds"] != len(rates[key]):
            raise ResultsError(f"summary[{index}].n_seeds: {entry['n_seeds']} but {len(rates[key])} cells have {describe(key, GROUP_KEY)}")
        _check_summary_counts(index, entry, counts[key], describe(key, GROUP_KEY))
    for key in sorted(means, key=str):
        if key not in seen:
            raise ResultsError(f"summary: no entry for {describe(key, GROUP_KEY)}")

    _check_sim_to_sim(results["sim_to_sim"], means)


def _check_sim_to_sim(entries: list[dict], means: dict[tuple, float]) -> None:
    """One ``sim_to_sim`` entry per (robot, terrain, level) that a pair of grid simulators ran, holding the summary
    means of the simulators that ran it and each such pair's gap (`frbench.evaluation.results.sim_to_sim`)."""
    rates: dict[tuple, dict[str, float]] = defaultdict(dict)
    for (robot, backend, terrain, level), mean in means.items():
        if backend in GRID_SIMULATORS:
            rates[(robot, terrain, level)][backend] = mean
    ran = {key: value for key, value in rates.items() if any(a in value and b in value for a, b in SIM_TO_SIM_PAIRS)}
    seen = {}
    for index, entry in enumerate(entries):
        key = tuple(entry[f] for f in PAIR_KEY)
        if key not in ran:
            raise ResultsError(f"sim_to_sim[{index}]: no cells of two simulators for {describe(key, PAIR_KEY)}")
        if key in seen:
            raise ResultsError(f"sim_to_sim[{index}]: duplicate entry for {describe(key, PAIR_KEY)} (also sim_to_sim[{seen[key]}])")
        seen[key] = index
        present = ran[key]
        for backend in GRID_SIMULATORS:
            if (backend in entry) != (backend in present):
                raise ResultsError(f"sim_to_sim[{index}].{backend}: " + (
                    "missing, but the summary has it" if backend in present else f"{backend} ran no cell of it"))
            if backend in present and abs(entry[backend] - present[backend]) > RATE_TOLERANCE:
                raise ResultsError(
                    f"sim_to_sim[{index}].{backend}: {_fmt(entry[backend])} differs from the summary's "
                    f"success_rate_mean, {_fmt(present[backend])}"
                )
        for first, second in SIM_TO_SIM_PAIRS:
            name, both = gap_field(first, second), first in present and second in present
            if (name in entry) != both:
                raise ResultsError(f"sim_to_sim[{index}].{name}: " + (
                    "missing" if both else f"{first} and {second} did not both run it"))
            if both:
                gap = present[first] - present[second]
                accepted = (gap, abs(gap)) if name == "gap" else (gap,)  # |mujoco - pybullet| as before PhysX
                if min(abs(entry[name] - value) for value in accepted) > RATE_TOLERANCE:
                    raise ResultsError(f"sim_to_sim[{index}].{name}: {_fmt(entry[name])} differs from {first} - "
                                       f"{second} = {_fmt(gap)}")
    for key in sorted(ran, key=str):
        if key not in seen:
            raise ResultsError(f"sim_to_sim: no entry for {describe(key, PAIR_KEY)}, which two simulators ran")
