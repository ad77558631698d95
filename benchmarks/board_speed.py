"""How long reading the leaderboard and submitting to it take, against two light commands in the same run.

Times whole ``frbench`` processes (start-up and imports included), the commands run in turn so that a drift in
the machine's speed hits each alike, and prints each command's median wall time and the ratios:

* ``frbench leaderboard`` (the table) and ``frbench submit`` of a 2-cell results file, on a copy of the
  repository's leaderboard (its records and policy files) with a cache folder of its own;
* ``frbench spec --robot go2`` and ``frbench robots`` as yardsticks.

Before timing, the copy is read once with an empty cache (``cold``: every record checked in full and its
summary stored, `frbench.leaderboard.summaries`); that time is printed too. Each timed submission adds a
distinct small record (the 2-cell results with another ``created`` time), so the board grows by one record per
repeat. The 2-cell results come from ``frbench evaluate`` (scripted, go2, MuJoCo, flat, level 1, seeds 0 and 1,
one episode each), run once before timing.

Goals (issue 56): ``leaderboard`` <= 2 s and ``submit`` <= 5 s with the repository's records on 2 cores, and
``leaderboard`` within 5x of ``spec --robot go2``.

Usage: ``python benchmarks/board_speed.py [--repeats 5] [--board leaderboard]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def frbench(*args: str, env: dict) -> float:
    """Wall seconds of one ``frbench ARGS`` process; exits if it fails."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "frbench", *args], env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"frbench {' '.join(args)} exited {done.returncode}: {done.stderr.strip()[-2000:]}")
    return seconds


def two_cell_results(folder: Path, env: dict) -> dict:
    """A 2-cell results object from `frbench evaluate` (the module docstring)."""
    out = folder / "two-cells.json"
    frbench("evaluate", "--policy", "scripted", "--robots", "go2", "--backends", "mujoco", "--terrains", "flat",
            "--levels", "1", "--seeds", "0,1", "--episodes", "1", "--jobs", "1", "--out", str(out), env=env)
    return json.loads(out.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of each command (default 5)")
    parser.add_argument("--board", type=Path, default=REPO / "leaderboard", help="the leaderboard folder to copy")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="frbench-board-speed-") as name:
        folder = Path(name)
        root = Path(shutil.copytree(args.board, folder / "leaderboard"))
        env = {**os.environ, "FRBENCH_CACHE": str(folder / "cache"), "FRBENCH_LEADERBOARD_DIR": str(root)}
        results = two_cell_results(folder, env)
        records = len(list((root / "records").glob("*.json.gz")))
        cold = frbench("leaderboard", env=env)
        commands = {
            "spec --robot go2": lambda i: frbench("spec", "--robot", "go2", env=env),
            "robots": lambda i: frbench("robots", env=env),
            "leaderboard": lambda i: frbench("leaderboard", env=env),
            "submit (2 cells)": lambda i: frbench("submit", str(_variant(folder, results, i)), "--name", f"speed{i}",
                                                  env=env),
        }
        times: dict[str, list[float]] = {key: [] for key in commands}
        for i in range(args.repeats):
            for key, run in commands.items():
                times[key].append(run(i))
    median = {key: statistics.median(values) for key, values in times.items()}
    print(f"{records} records; {os.cpu_count()} CPUs; {args.repeats} runs each, median wall seconds (min-max)")
    print(f"  leaderboard, cold cache (one run, checks every record): {cold:.2f} s")
    for key, values in times.items():
        print(f"  {key:<18} {median[key]:6.2f} s  ({min(values):.2f}-{max(values):.2f})")
    spec, robots = median["spec --robot go2"], median["robots"]
    board, submit = median["leaderboard"], median["submit (2 cells)"]
    print(f"leaderboard / spec --robot go2: {board / spec:.2f}x (goal <= 5)")
    print(f"leaderboard / robots: {board / robots:.2f}x; submit / robots: {submit / robots:.2f}x")
    print(f"leaderboard {board:.2f} s (goal <= 2 s); submit {submit:.2f} s (goal <= 5 s)")


def _variant(folder: Path, results: dict, index: int) -> Path:
    """The 2-cell results with another ``created`` time (another record id), written to a file."""
    path = folder / f"two-cells-{index}.json"
    path.write_text(json.dumps({**results, "created": f"2026-01-01T00:00:{index:02d}Z"}))
    return path


if __name__ == "__main__":
    main()
