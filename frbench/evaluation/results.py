"""Aggregate per-episode records into cells, summaries and sim-to-sim gaps; the results table.

Layout (schema_version 1, JSON Schema in ``frbench/schemas/results-v1.schema.json``):
``cells`` per (robot, backend, terrain, level, seed); ``summary`` per (robot,
backend, terrain, level) with the success rate's mean over seeds, the pooled
successes / episodes and their 95 % Wilson interval (``ci95``; the std over
seeds is kept for the schema but never shown: with one seed it is 0);
``sim_to_sim`` per (robot, terrain, level) with each grid simulator's mean and
the gap of each pair (MuJoCo − PyBullet, MuJoCo − PhysX, PyBullet − PhysX); ``episodes`` keeps every episode. Aggregates over many
cells get stratified-bootstrap intervals (`frbench.evaluation.intervals`).
"""

from __future__ import annotations

import itertools
from collections import defaultdict

import numpy as np

from frbench.evaluation.intervals import bootstrap_rates, percentile_interval, sim_to_sim_gaps, sorted_cells, wilson_interval
from frbench.tasks.protocol import GRID_SIMULATORS

CELL_KEYS = ("robot", "backend", "terrain", "level", "seed")
_MEANS = {
    "mean_final_displacement": "final_displacement",
    "mean_max_displacement": "max_displacement",
    "mean_energy": "energy",
    "mean_smoothness": "smoothness",
    "mean_peak_contact_force": "peak_contact_force",
}


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def aggregate_cells(episodes: list[dict]) -> list[dict]:
    """One aggregate per (robot, backend, terrain, level, seed), sorted."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for record in episodes:
        groups[tuple(record[k] for k in CELL_KEYS)].append(record)
    cells = []
    for key in sorted(groups):
        records = groups[key]
        successes = sum(r["success"] for r in records)
        cell = dict(zip(CELL_KEYS, key))
        cell.update(
            episodes=len(records),
            successes=successes,
            success_rate=successes / len(records),
            mean_time_to_recover=_mean(r["time_to_recover"] for r in records if r["success"]),
            **{name: _mean(r[field] for r in records) for name, field in _MEANS.items()},
            rollover_rate=sum(r["rolled_over"] for r in records) / len(records),
            diverged=sum(r["diverged"] for r in records),
        )
        cells.append(cell)
    return cells


def summarize(cells: list[dict]) -> list[dict]:
    """Per (robot, backend, terrain, level): mean success over seeds, pooled successes / episodes, Wilson 95 %."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for cell in cells:
        groups[(cell["robot"], cell["backend"], cell["terrain"], cell["level"])].append(cell)
    rows = []
    for k, group in sorted(groups.items()):
        rates = [c["success_rate"] for c in group]
        successes, episodes = sum(c["successes"] for c in group), sum(c["episodes"] for c in group)
        rows.append({
            "robot": k[0], "backend": k[1], "terrain": k[2], "level": k[3],
            "success_rate_mean": float(np.mean(rates)), "success_rate_std": float(np.std(rates)), "n_seeds": len(rates),
            "successes": successes, "episodes": episodes, "ci95": list(wilson_interval(successes, episodes)),
        })
    return rows


#: The pairs of simulators whose gaps results and the board report, in order (`frbench.tasks.protocol`'s grid
#: simulators two by two).
SIM_TO_SIM_PAIRS = tuple(itertools.combinations(GRID_SIMULATORS, 2))


def gap_field(first: str, second: str) -> str:
    """A ``sim_to_sim`` entry's field for the gap ``first`` − ``second``: ``gap`` for MuJoCo − PyBullet (the field
    results had before PhysX), ``gap_<first>_<second>`` for the others."""
    return "gap" if (first, second) == SIM_TO_SIM_PAIRS[0] else f"gap_{first}_{second}"


def sim_to_sim(summary: list[dict]) -> list[dict]:
    """Per (robot, terrain, level) that at least two grid simulators ran: each one's mean success and the gap of
    each pair that ran (`SIM_TO_SIM_PAIRS`, `gap_field`), first − second. Results of MuJoCo and PyBullet alone
    keep the entries they had (robot, terrain, level, mujoco, pybullet, gap)."""
    by_key: dict[tuple, dict[str, float]] = defaultdict(dict)
    for row in summary:
        by_key[(row["robot"], row["terrain"], row["level"])][row["backend"]] = row["success_rate_mean"]
    out = []
    for (robot, terrain, level), rates in sorted(by_key.items()):
        pairs = [(a, b) for a, b in SIM_TO_SIM_PAIRS if a in rates and b in rates]
        if pairs:
            out.append({"robot": robot, "terrain": terrain, "level": level,
                        **{name: rates[name] for name in GRID_SIMULATORS if name in rates},
                        **{gap_field(a, b): rates[a] - rates[b] for a, b in pairs}})
    return out


def fmt_count(row: dict) -> str:
    """``k/n rate% [low-high]`` of a summary row (Wilson 95 %)."""
    low, high = row["ci95"]
    return f"{row['successes']}/{row['episodes']} {100 * row['successes'] / row['episodes']:5.1f}% [{100 * low:3.0f}-{100 * high:3.0f}]"


#: Short names of the grid simulators in the printed table's gap columns.
SHORT_NAMES = {"mujoco": "mj", "pybullet": "pb", "physx": "px"}


def results_table(summary: list[dict], gaps: list[dict]) -> str:
    """Plain-text table: successes / episodes, rate and 95 % Wilson interval per backend, and the sim-to-sim gap of
    each pair of grid simulators that ran (``gap (mj-pb)``, ``gap (mj-px)``, ``gap (pb-px)``, points), one row per
    (robot, terrain, level)."""
    by_key: dict[tuple, dict[str, dict]] = defaultdict(dict)
    for row in summary:
        by_key[(row["robot"], row["terrain"], row["level"])][row["backend"]] = row
    pairs = [pair for pair in SIM_TO_SIM_PAIRS if any(gap_field(*pair) in g for g in gaps)]
    gap_of = {(g["robot"], g["terrain"], g["level"]): g for g in gaps}
    backends = sorted({row["backend"] for row in summary})
    header = f"{'robot':<11} {'terrain':<8} {'level':>5} " + " ".join(f"{b:>24}" for b in backends) + "".join(
        f" {'gap (%s-%s)' % (SHORT_NAMES[a], SHORT_NAMES[b]):>12}" for a, b in pairs)
    lines = [header, "-" * len(header)]
    for key in sorted(by_key):
        rates = by_key[key]
        cols = [fmt_count(rates[backend]) if backend in rates else "-" for backend in backends]
        entry = gap_of.get(key, {})
        gap_cols = [entry.get(gap_field(*pair)) for pair in pairs]
        lines.append(f"{key[0]:<11} {key[1]:<8} {key[2]:>5} " + " ".join(f"{c:>24}" for c in cols)
                     + "".join(f" {('%+.1f pts' % (100 * gap)) if gap is not None else '-':>12}" for gap in gap_cols))
    return "\n".join(lines)


def aggregate_intervals(cells: list[dict]) -> dict[str, tuple[float, float, float]]:
    """Name -> (mean cell success, bootstrap 95 % low, high): overall, per family, per backend, per robot, and the
    signed sim-to-sim gap MuJoCo − PyBullet when both backends ran (``frbench.evaluation.intervals``)."""
    ordered = sorted_cells(cells)
    rates = bootstrap_rates(ordered)
    point = np.array([c["success_rate"] for c in ordered])
    k = np.array([c["successes"] for c in ordered])
    n = np.array([c["episodes"] for c in ordered])
    out = {"overall": (float(point.mean()), *percentile_interval(rates.mean(axis=1), k.sum(), n.sum()))}
    for field in ("terrain", "backend", "robot"):
        values = sorted({c[field] for c in ordered})
        if len(values) < 2:
            continue
        for value in values:
            mask = np.array([c[field] == value for c in ordered])
            out[f"{field} {value}"] = (float(point[mask].mean()),
                                       *percentile_interval(rates[:, mask].mean(axis=1), k[mask].sum(), n[mask].sum()))
    gaps = sim_to_sim_gaps(ordered, rates)
    if gaps is not None:
        out["gap MuJoCo - PyBullet"] = (float(sim_to_sim_gaps(ordered, point[None, :])[0]), *percentile_interval(gaps))
    return out


def aggregate_table(cells: list[dict]) -> str:
    """Plain-text lines of `aggregate_intervals`."""
    lines = []
    for name, (mean, low, high) in aggregate_intervals(cells).items():
        lines.append(f"{name:<24} {100 * mean:5.1f}%  [{100 * low:5.1f}, {100 * high:5.1f}]")
    return "\n".join(lines)


def initial_pose_table(episodes: list[dict]) -> str:
    """Plain-text table: successes / episodes per (robot, initial pose) and backend — from which starts a policy
    fails. ``episodes``: per-episode records with ``robot``, ``backend``, ``initial_pose`` and ``success``."""
    counts: dict[tuple, dict[str, list[int]]] = defaultdict(lambda: defaultdict(lambda: [0, 0]))
    for e in episodes:
        count = counts[(e["robot"], e["initial_pose"])][e["backend"]]
        count[0] += bool(e["success"])
        count[1] += 1
    backends = sorted({e["backend"] for e in episodes})
    header = f"{'robot':<11} {'initial pose':<12} " + " ".join(f"{b:>17}" for b in backends)
    lines = [header, "-" * len(header)]
    for key in sorted(counts):
        cols = []
        for backend in backends:
            won, n = counts[key].get(backend, (0, 0))
            cols.append(f"{won}/{n} ({100 * won / n:5.1f}%)" if n else "-")
        lines.append(f"{key[0]:<11} {key[1]:<12} " + " ".join(f"{c:>17}" for c in cols))
    return "\n".join(lines)
