"""Learning curves of training runs: a run folder's curve as CSV, and several runs' success against env steps in
one PNG (``frbench plot-training``).

A run folder (`frbench.training.run.TrainingRun`) logs one row per checkpoint in ``progress.json``: ``env_steps``,
``wall_s`` [s], the *training* success rates (``success_all``, ``success_<family>``: episodes from fallen starts
that ended in the logging window, actions sampled with the policy's exploration noise) and the mean losses of the
PPO updates since the previous row (``loss_<name>``), the policy's mean action std and learning rate over those
updates (``policy_std``, ``policy_learning_rate``) and each reward term's mean per env step (``reward_<term>``). `write_curve_csv` writes the same rows as ``curve.csv``
(one column per key, empty where a row lacks one).
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from frbench.errors import FrbenchError
from frbench.io import atomic_write_text

PROGRESS_FILE, CURVE_CSV = "progress.json", "curve.csv"
#: Columns that come first, in this order; the others follow sorted.
LEADING_COLUMNS = ("iteration", "env_steps", "wall_s", "success_all", "success_flat")


class LossLog:
    """Dicts of numbers added since the last `means` call, averaged: the losses of the PPO updates (an algorithm's
    ``update`` adds each), the policy's std and learning rate per update, or the reward terms per env step. A value
    may be a 0-d array on a device (the reward terms of a training env on a device): it is summed where it lives and read once,
    by `means`."""

    def __init__(self, prefix: str = "loss_"):
        self.prefix = prefix
        self._sums: dict = {}
        self._count = 0

    def add(self, losses: dict) -> None:
        for key, value in losses.items():
            if value is not None:
                self._sums[key] = self._sums.get(key, 0.0) + (float(value) if _on_host(value) else value)
        self._count += 1

    def means(self) -> dict[str, float]:
        """``<prefix><name>`` → mean over the dicts added since the last call (then forgotten); {} if none."""
        out = ({f"{self.prefix}{k}": round(float(v) / self._count, 6) for k, v in self._sums.items()}
               if self._count else {})
        self._sums, self._count = {}, 0
        return out


def _on_host(value) -> bool:
    """Whether ``value`` is a host number (a Python or numpy scalar, a numpy array), not a device array."""
    import numpy as np

    return isinstance(value, (int, float, np.generic, np.ndarray))


class TensorBoardCurve:
    """The learning curve's rows as TensorBoard scalars in the run folder (``tensorboard --logdir RUN``), one point
    per row at its env step; the writer opens on the first row (rank 0 only writes)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self._writer = None

    def add(self, row: dict) -> None:
        if self._writer is None:
            from torch.utils.tensorboard import SummaryWriter

            self._writer = SummaryWriter(log_dir=str(self.folder))
        for key, value in row.items():
            if key not in ("iteration", "env_steps") and isinstance(value, (int, float)):
                group = next((g for g in ("loss", "reward", "policy") if key.startswith(g + "_")), "train")
                self._writer.add_scalar(f"{group}/{key}", value, global_step=int(row["env_steps"]))
        self._writer.flush()

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None


def curve_columns(rows: list[dict]) -> list[str]:
    """Every key of the rows: `LEADING_COLUMNS` first, then success rates, then the rest, each sorted."""
    keys = {k for row in rows for k in row}
    lead = [k for k in LEADING_COLUMNS if k in keys]
    rest = sorted(keys - set(lead), key=lambda k: (not k.startswith("success"), k))
    return lead + rest


def curve_csv_text(rows: list[dict]) -> str:
    """The rows as CSV text (header, then one line per row)."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=curve_columns(rows), restval="", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue()


def write_curve_csv(rows: list[dict], folder: Path) -> Path:
    """Write ``folder/curve.csv`` atomically; returns its path."""
    path = Path(folder) / CURVE_CSV
    atomic_write_text(path, curve_csv_text(rows))
    return path


def read_progress(run: Path) -> list[dict]:
    """A run folder's logged rows (`FrbenchError` naming the folder when it has none or they are unreadable)."""
    path = Path(run) / PROGRESS_FILE
    if not path.is_file():
        raise FrbenchError(f"{run}: no {PROGRESS_FILE}; expected a training run folder (frbench train --out)")
    try:
        rows = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise FrbenchError(f"{path}: unreadable ({exc})") from None
    if not isinstance(rows, list) or not all(isinstance(r, dict) and "env_steps" in r for r in rows):
        raise FrbenchError(f"{path}: expected a list of rows with env_steps")
    return rows


def run_labels(runs: list[Path]) -> list[str]:
    """Each run's folder name, or ``parent/name`` when two runs share a name (seeds of several recipes)."""
    names = [Path(run).name for run in runs]
    if len(set(names)) == len(names):
        return names
    return [f"{Path(run).resolve().parent.name}/{Path(run).name}" for run in runs]


def plot_training(runs: list[Path], out: Path, metrics=("success_flat", "success_all"), labels=None) -> Path:
    """One PNG: each metric in its own panel, one line per run, against env steps [M]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = [read_progress(run) for run in runs]
    labels = list(labels) if labels else run_labels(runs)
    fig, axes = plt.subplots(1, len(metrics), figsize=(5 * len(metrics), 3.6), dpi=120, squeeze=False)
    for ax, metric in zip(axes[0], metrics):
        for rows, label in zip(curves, labels):
            points = [(r["env_steps"] / 1e6, r[metric]) for r in rows if r.get(metric) is not None]
            if points:
                ax.plot(*zip(*points), label=label)
        ax.set_xlabel("env steps [M]")
        ax.set_ylabel(metric.replace("_", " "))
        if metric.startswith("success"):
            ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
    if axes[0][0].get_legend_handles_labels()[0]:  # a run without rows yet draws no line
        axes[0][0].legend(loc="upper left", fontsize="small")
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, out)
    return out
