"""Aggregate per-episode records into cells, summaries and sim-to-sim gaps; the results table.

Layout (schema_version 1, JSON Schema in ``frbench/schemas/results-v1.schema.json``):
``cells`` per (robot, backend, terrain, level, seed); ``summary`` per (robot,
backend, terrain, level) with the success rate's mean and std over seeds;
``sim_to_sim`` per (robot, terrain, level) with each backend's mean and the
gap MuJoCo − PyBullet; ``episodes`` keeps every episode.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

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
    """Success rate mean ± std over seeds per (robot, backend, terrain, level)."""
    groups: dict[tuple, list[float]] = defaultdict(list)
    for cell in cells:
        groups[(cell["robot"], cell["backend"], cell["terrain"], cell["level"])].append(cell["success_rate"])
    return [
        {
            "robot": k[0], "backend": k[1], "terrain": k[2], "level": k[3],
            "success_rate_mean": float(np.mean(v)), "success_rate_std": float(np.std(v)), "n_seeds": len(v),
        }
        for k, v in sorted(groups.items())
    ]


def sim_to_sim(summary: list[dict]) -> list[dict]:
    """Per (robot, terrain, level) with both backends: their mean success and the gap MuJoCo − PyBullet."""
    by_key: dict[tuple, dict[str, float]] = defaultdict(dict)
    for row in summary:
        by_key[(row["robot"], row["terrain"], row["level"])][row["backend"]] = row["success_rate_mean"]
    out = []
    for (robot, terrain, level), rates in sorted(by_key.items()):
        if "mujoco" in rates and "pybullet" in rates:
            out.append({"robot": robot, "terrain": terrain, "level": level, "mujoco": rates["mujoco"],
                        "pybullet": rates["pybullet"], "gap": rates["mujoco"] - rates["pybullet"]})
    return out


def results_table(summary: list[dict], gaps: list[dict]) -> str:
    """Plain-text table: success mean ± std per backend and the sim-to-sim gap, one row per (robot, terrain, level)."""
    by_key: dict[tuple, dict[str, dict]] = defaultdict(dict)
    for row in summary:
        by_key[(row["robot"], row["terrain"], row["level"])][row["backend"]] = row
    gap_of = {(g["robot"], g["terrain"], g["level"]): g["gap"] for g in gaps}
    backends = sorted({row["backend"] for row in summary})
    header = f"{'robot':<11} {'terrain':<8} {'level':>5} " + " ".join(f"{b:>15}" for b in backends) + f" {'gap (mj-pb)':>12}"
    lines = [header, "-" * len(header)]
    for key in sorted(by_key):
        rates = by_key[key]
        cols = []
        for backend in backends:
            row = rates.get(backend)
            cols.append(f"{100 * row['success_rate_mean']:6.1f} ± {100 * row['success_rate_std']:4.1f}%" if row else f"{'-':>15}")
        gap = gap_of.get(key)
        lines.append(f"{key[0]:<11} {key[1]:<8} {key[2]:>5} " + " ".join(f"{c:>15}" for c in cols)
                     + f" {('%+.1f pts' % (100 * gap)) if gap is not None else '-':>12}")
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
