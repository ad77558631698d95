"""Comparing methods from their ``frbench evaluate`` results files (issue: baselines and ablations).

Three Markdown tables, each row one policy:

* `level10_table`: success at level 10 per terrain family (mean over robots,
  seeds and both backends), with the paper's level-10 numbers beside it;
* `sim_to_sim_table`: per family, MuJoCo and PyBullet success (mean over
  robots, levels and seeds) and their difference, plus the mean |gap| over
  the cells (robot × family × level) — the smaller, the better it transfers;
* `displacement_table`: the base's largest horizontal displacement from its
  start within an episode [m] on the level-10 stairs and slopes (the paper's
  stability study), mean and 90th percentile over episodes, per backend.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from frbench.terrains import FAMILIES

#: Level-10 success [%] that the paper's text states (Sec. "Comparison", the paragraph on its comparison
#: figure); derived entries are FR-Net's number minus the stated difference. "< 45": "alternatives fall
#: below 45 %"; a range: "outperforms DreamRiser by 8-12 %".
PAPER_LEVEL10: dict[str, dict[str, str]] = {
    "frnet": {"rough": "69.5", "beams": "64.1", "stairs": "≥ 58", "slopes": "≥ 58", "gaps": "46.8"},
    "ppo": {"rough": "47.7", "beams": "38.8", "stairs": "< 45", "slopes": "< 45"},
    "dreamriser": {"stairs": "< 45", "slopes": "< 45", "gaps": "34.8-38.8", "beams": "52.1-56.1"},
    "rma": {"stairs": "< 45", "slopes": "< 45"},
    "frnet-no-mass": {"gaps": "35.5"},
    "frnet-no-est": {"beams": "51.4"},
}


def _method_of(name: str) -> str | None:
    """The paper's method a policy name belongs to (longest matching prefix: ``frnet-no-mass-3m`` →
    ``frnet-no-mass``)."""
    matches = [m for m in PAPER_LEVEL10 if name == m or name.startswith(m + "-")]
    return max(matches, key=len) if matches else None


def _families(results: list[dict]) -> list[str]:
    """The families present in ``results``, in frbench's order."""
    seen = {c["terrain"] for data in results for c in data["cells"]}
    return [f for f in FAMILIES if f in seen] + sorted(seen - set(FAMILIES))


def level10_table(results: list[dict], level: int = 10) -> str:
    """Success [%] at ``level`` per family, ours beside the paper's where the paper states one."""
    rates: dict[tuple[str, str], list[float]] = defaultdict(list)
    for data in results:
        for cell in data["cells"]:
            if cell["level"] == level:
                rates[(data["policy"]["name"], cell["terrain"])].append(cell["success_rate"])
    families = _families(results)
    lines = ["| policy | " + " | ".join(f"{f} (ours / paper)" for f in families) + " |",
             "|---|" + "---|" * len(families)]
    for name in sorted({k[0] for k in rates}):
        paper = PAPER_LEVEL10.get(_method_of(name) or "", {})
        cells = [f"{100 * np.mean(rates[(name, f)]):.1f} / {paper.get(f, '–')}" if rates[(name, f)] else ""
                 for f in families]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def sim_to_sim_table(results: list[dict]) -> str:
    """Per policy and family: "MuJoCo / PyBullet (difference)" [%], and the mean |gap| over cells [points]."""
    rates: dict[tuple, list[float]] = defaultdict(list)  # (policy, family, robot, level, backend) -> rates
    for data in results:
        for cell in data["cells"]:
            key = (data["policy"]["name"], cell["terrain"], cell["robot"], cell["level"], cell["backend"])
            rates[key].append(cell["success_rate"])
    paired = defaultdict(list)  # (policy, family) -> [(MuJoCo rate, PyBullet rate) per robot and level]
    for (name, family, robot, level, backend), values in rates.items():
        other = rates.get((name, family, robot, level, "pybullet"))
        if backend == "mujoco" and other:
            paired[(name, family)].append((np.mean(values), np.mean(other)))
    families = _families(results)
    lines = ["| policy | " + " | ".join(families) + " | mean \\|gap\\| |", "|---|" + "---|" * (len(families) + 1)]
    for name in sorted({k[0] for k in paired}):
        cells, gaps = [], []
        for family in families:
            pairs = np.array(paired.get((name, family), []))
            if pairs.size:
                mj, pb = pairs.mean(axis=0)
                cells.append(f"{100 * mj:.1f} / {100 * pb:.1f} ({100 * (mj - pb):+.1f})")
                gaps += list(np.abs(pairs[:, 0] - pairs[:, 1]))
            else:
                cells.append("")
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {100 * np.mean(gaps):.1f} |")
    return "\n".join(lines) + "\n"


def displacement_table(results: list[dict], terrains=("stairs", "slopes"), level: int = 10) -> str:
    """Largest displacement from the start within an episode [m], mean and 90th percentile, per backend."""
    values: dict[tuple, list[float]] = defaultdict(list)
    for data in results:
        for episode in data["episodes"]:
            if episode["terrain"] in terrains and episode["level"] == level:
                values[(data["policy"]["name"], episode["terrain"], episode["backend"])].append(
                    episode["max_displacement"])
    backends = sorted({k[2] for k in values})
    columns = [(t, b) for t in terrains for b in backends]
    lines = ["| policy | " + " | ".join(f"{t} L{level} {b}" for t, b in columns) + " |",
             "|---|" + "---|" * len(columns)]
    for name in sorted({k[0] for k in values}):
        cells = []
        for key in columns:
            v = values.get((name, *key))
            cells.append(f"{np.mean(v):.2f} (p90 {np.percentile(v, 90):.2f}, n {len(v)})" if v else "")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
