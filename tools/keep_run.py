"""Keep an unfinished training run in the tree, small enough to commit, so that it resumes on another machine.

A run folder (``frbench train --out``, or one seed of ``benchmarks/learning_curve.py``: ``OUT/seed<S>``) holds
about 6 MB, most of it optimiser states and policy snapshots. This copies what ``frbench train --resume``
needs into ``DEST``: ``config.json``, ``state.pt``, ``progress.json``, ``curve.csv`` and ``runner.pt`` without its
optimiser states (`frbench.training.run.keep_without_optimisers`: about 1.4 MB instead of 3.9; the run resumes
with fresh Adam moments at its last learning rate; its next checkpoint writes ``policy.pt`` again). A learning
curve's subset results (``subset-*.json``, 0.5 MB each) stay out: write their numbers where the run is described::

    python tools/keep_run.py runs/kickstart/seed0 checkpoints/kickstart-seed0/seed0

To resume, copy ``DEST`` back to where the run lived and run the same ``frbench train --resume`` or
``learning_curve.py`` command.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from frbench.training.run import CONFIG_FILE, RUNNER_FILE, STATE_FILE, keep_without_optimisers
from frbench.training.curves import PROGRESS_FILE

#: Files copied as they are (when present).
COPIED = (CONFIG_FILE, STATE_FILE, PROGRESS_FILE, "curve.csv")


def keep(run: Path, dest: Path) -> list[Path]:
    """Copy the resumable part of ``run`` into ``dest`` (module docstring); the paths written."""
    if not (run / RUNNER_FILE).is_file() or not (run / STATE_FILE).is_file():
        raise SystemExit(f"{run}: not a training run folder (expected {RUNNER_FILE} and {STATE_FILE})")
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for name in COPIED:
        if (run / name).is_file():
            shutil.copy2(run / name, dest / name)
            written.append(dest / name)
    keep_without_optimisers(run / RUNNER_FILE, dest / RUNNER_FILE)
    written.append(dest / RUNNER_FILE)
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="the run folder")
    parser.add_argument("dest", type=Path, help="where to keep it")
    args = parser.parse_args()
    for path in keep(args.run, args.dest):
        print(f"{path}  {path.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
