"""Success against difficulty level, one figure per terrain family, from ``frbench evaluate`` results files.

Each figure has one panel per backend; each line is one *series* — a robot
(for one policy's results) or a policy (for a comparison of methods, pooled
over the robots) — with the success rate over the pooled episodes of the
evaluation seeds and its 95 % Wilson interval as a band (a standard deviation
over 2-4 seeds of a few episodes says little, and nothing with one seed). The
same numbers go into a Markdown table (`markdown_table`) for docs/results.md.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from frbench.errors import FrbenchError
from frbench.evaluation.intervals import wilson_interval
from frbench.leaderboard.board import read_results

SERIES_KEYS = ("robot", "policy")


def load_results(paths: list[Path]) -> list[dict]:
    """The results JSON of each path, read and checked as ``frbench submit`` does (`frbench.leaderboard.board.read_results`:
    schema, self-consistency, known protocol); an error is one line naming the file and the field."""

    return [read_results(path) for path in paths]


def success_table(results: list[dict], series: str = "robot") -> dict:
    """{(series value, backend, terrain, level): (rate, low, high, episodes)}: the success rate over the pooled
    episodes of the seeds (and, for ``series="policy"``, of the robots) with its 95 % Wilson interval."""
    if series not in SERIES_KEYS:
        raise FrbenchError(f"series {series!r}: expected one of {', '.join(SERIES_KEYS)}")
    counts: dict[tuple, list[int]] = defaultdict(lambda: [0, 0])
    for data in results:
        name = data["policy"]["name"]
        for cell in data["cells"]:
            key = (cell["robot"] if series == "robot" else name, cell["backend"], cell["terrain"], cell["level"])
            counts[key][0] += cell["successes"]
            counts[key][1] += cell["episodes"]
    return {key: (k / n, *wilson_interval(k, n), n) for key, (k, n) in counts.items()}


def plot_families(table: dict, out_dir: Path, title: str = "") -> list[Path]:
    """One PNG per terrain family (``success_<family>.png``) in ``out_dir``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    labels = sorted({k[0] for k in table})
    backends = sorted({k[1] for k in table})
    paths = []
    for terrain in sorted({k[2] for k in table}):
        fig, axes = plt.subplots(1, len(backends), figsize=(4.2 * len(backends), 3.2), dpi=110, sharey=True,
                                 squeeze=False)
        for ax, backend in zip(axes[0], backends):
            for label in labels:
                points = sorted((k[3], v) for k, v in table.items() if k[:3] == (label, backend, terrain))
                if not points:
                    continue
                levels = np.array([p[0] for p in points])
                rate = np.array([p[1][0] for p in points]) * 100
                low = np.array([p[1][1] for p in points]) * 100
                high = np.array([p[1][2] for p in points]) * 100
                ax.plot(levels, rate, marker="o", label=label)
                ax.fill_between(levels, low, high, alpha=0.15)
            ax.set_title(f"{terrain} — {backend}")
            ax.set_xlabel("level")
            ax.set_ylim(-2, 102)
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("success [%] (95 % Wilson interval)")
        axes[0][-1].legend(fontsize=7, loc="best")
        if title:
            fig.suptitle(title, fontsize=9)
        fig.tight_layout()
        path = out_dir / f"success_{terrain}.png"
        tmp = path.with_name(f".{path.name}.tmp.png")
        fig.savefig(tmp)
        plt.close(fig)
        tmp.replace(path)
        paths.append(path)
    return paths


def markdown_table(table: dict) -> str:
    """Rows series × terrain, columns level × backend: "rate (low–high)" in percent, 95 % Wilson."""
    labels = sorted({k[0] for k in table})
    backends = sorted({k[1] for k in table})
    terrains = sorted({k[2] for k in table})
    levels = sorted({k[3] for k in table})
    header = "| | terrain | " + " | ".join(f"L{lv} {b}" for lv in levels for b in backends) + " |"
    lines = [header, "|" + "---|" * (2 + len(levels) * len(backends))]
    for label in labels:
        for terrain in terrains:
            cells = []
            for level in levels:
                for backend in backends:
                    value = table.get((label, backend, terrain, level))
                    cells.append("" if value is None else f"{100 * value[0]:.1f} ({100 * value[1]:.0f}–{100 * value[2]:.0f})")
            if any(cells):
                lines.append(f"| {label} | {terrain} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
