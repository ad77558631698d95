"""Re-score the protocol-1.3 records of the main board and the humanoid track under protocol 1.4: one resumable job.

Protocol 1.4 redraws a start's joint angles until its links are free (docs/protocol.md, "Protocol 1.4"). Only the
starts that exhausted 1.3's 50 redraws change, so a 1.4 record of a policy is its 1.3 record with those episodes
run again. For each 1.3 record (main board in board order, then the humanoid track), an episode is *changed* when
one of the starts it was drawn from (its first draw and each screening redraw it used, ``start_redraws``) differs
under the two rules (`changed_episodes`). Every cell holding a changed episode runs again under 1.4 (the cell's
episodes run side by side, as ``frbench evaluate`` runs them), one cell after the other in this process, each
written atomically to::

    OUT/<record name>/cells/<robot>-<simulator>-<family>-<level>-<seed>.json

The re-run cell's unchanged episodes must come out equal to the 1.3 record's (the job stops otherwise). A killed
job resumes where it stopped: a cell whose file exists is not run again. When a record's cells are written, its
1.4 results go to ``OUT/<record name>/results.json``: the changed episodes from the re-run, every other episode
of the 1.3 record unchanged, and the ``reused`` field naming the 1.3 record, its simulators, the re-run episodes
(``rerun``) and the sha256 of the reused ones (`frbench.leaderboard.reuse`), checked like a submission. A record
without changed episodes (the G1-only humanoid records) is pure reuse. ``--submit`` submits the finished ones::

    nice -n 15 nohup .venv/bin/python tools/rescore_starts.py >> runs/rescore-1.4/nohup.out 2>&1 &
    .venv/bin/python tools/rescore_starts.py --status      # changed episodes, cells written, per record
    .venv/bin/python tools/rescore_starts.py --submit

``--only NAME,...`` limits the job to those records; ``--max-cells N`` stops after N cells (to time a chunk).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rescore  # noqa: E402  (tools/rescore.py: the job machinery)

DEFAULT_OUT = rescore.ROOT / "runs" / "rescore-1.4"
#: The protocol the re-scored records are for, and the protocol of the records it re-scores.
TARGET_PROTOCOL = "1.4"
SOURCE_PROTOCOL = "1.3"
TRACKS = ("main", "humanoid")


def description_suffix(record: str) -> str:
    """What the 1.4 record's description says of its origin."""
    return f"; protocol 1.4: record {record[:12]}'s episodes, those whose start 1.4 redraws run again"


def source_records(board: Path) -> list[dict]:
    """The 1.3 records of the main board and the humanoid track (not superseded), each track in board order."""
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.leaderboard.sections import superseded

    records = load_records(board)
    replaced = superseded(records)
    chosen = [r for r in records if r["results"]["protocol_version"] == SOURCE_PROTOCOL and r["track"] in TRACKS
              and r["id"] not in replaced]
    return sorted(chosen, key=lambda r: (TRACKS.index(r["track"]),
                                         rank_key(r["scores"], r["submission"]["submitted"], r["id"])))


class StartDraws:
    """Whether a start (robot, family, level, seed, episode, attempt) is drawn the same under two protocols' rules
    (cached: the main-board records share their cells)."""

    def __init__(self, old: str = SOURCE_PROTOCOL, new: str = TARGET_PROTOCOL):
        from frbench.tasks.initial_states import joint_redraws

        self.rules = (joint_redraws(old), joint_redraws(new))
        self.same: dict[tuple, bool] = {}

    def unchanged(self, robot: str, family: str, level: int, seed: int, episode: int, attempt: int) -> bool:
        import numpy as np

        from frbench.robots.registry import get_robot
        from frbench.tasks.initial_states import draw_start, episode_rng
        from frbench.terrains import make_terrain

        key = (robot, family, level, seed, episode, attempt)
        if key not in self.same:
            spec, terrain = get_robot(robot), make_terrain(family, level, seed)
            old, new = (draw_start(spec, terrain, episode_rng(robot, family, level, seed, episode, attempt=attempt),
                                   rule) for rule in self.rules)
            self.same[key] = old[3] == new[3] and all(np.array_equal(a, b) for a, b in zip(old[:3], new[:3]))
        return self.same[key]


def changed_episodes(results: dict, draws: StartDraws) -> list[tuple]:
    """The keys (`frbench.leaderboard.reuse.episode_key`) of the episodes of ``results`` one of whose starts
    (attempts 0 … ``start_redraws``) ``draws`` finds changed, in results order."""
    from frbench.leaderboard.reuse import episode_key

    return [episode_key(e) for e in results["episodes"]
            if not all(draws.unchanged(e["robot"], e["terrain"], e["level"], e["seed"], e["episode"], attempt)
                       for attempt in range(e["start_redraws"] + 1))]


class StartsJob(rescore.Job):
    """One 1.3 record's re-score under 1.4: its changed episodes and the cells that hold them."""

    def __init__(self, record: dict, board: Path, out: Path, draws: StartDraws):
        self.record, self.out = record, out
        self.name = record["submission"]["name"]
        self.reference = rescore.policy_reference(record, board)
        self.folder = out / self.name
        results = record["results"]
        self.rerun = changed_episodes(results, draws)
        self.cells = sorted({key[:5] for key in self.rerun})

    @property
    def protocol_version(self) -> str:
        return TARGET_PROTOCOL

    def cell_path(self, key: tuple) -> Path:
        return self.folder / "cells" / ("-".join(map(str, key)) + ".json")

    def pending(self, grid: str | None = None) -> list[tuple]:
        return [key for key in self.cells if not self.cell_path(key).is_file()]

    def done(self) -> tuple[int, int]:
        return len(self.cells) - len(self.pending()), len(self.cells)

    def run_one(self, key: tuple) -> tuple[float, int, int]:
        """Run one cell under 1.4, check that its unchanged episodes are the record's, write it; (seconds, changed
        episodes' successes before, after)."""
        from frbench.evaluation.provenance import frbench_info
        from frbench.evaluation.runner import Cell, run_cell
        from frbench.io import atomic_write_text
        from frbench.leaderboard.reuse import episode_key

        results = self.record["results"]
        started = time.monotonic()
        fresh = run_cell(Cell(*key, results["config"]["episodes"]), self.reference, results["config"]["noise"],
                         joint_frame=results["policy"].get("joint_frame", "robot"), protocol_version=TARGET_PROTOCOL)
        seconds = time.monotonic() - started
        rerun = set(self.rerun)
        recorded = {episode_key(e): e for e in results["episodes"] if episode_key(e)[:5] == key}
        for episode in fresh:
            if episode_key(episode) not in rerun and episode != recorded[episode_key(episode)]:
                raise SystemExit(f"{self.name}: {' '.join(map(str, episode_key(episode)))}: its start is unchanged, "
                                 "yet the episode differs from the 1.3 record's: it cannot be reused")
        document = {"cell": list(key), "protocol_version": TARGET_PROTOCOL, "seconds": round(seconds, 2),
                    "frbench": frbench_info(), "episodes": fresh}
        atomic_write_text(self.cell_path(key), json.dumps(document) + "\n")
        changed = [e for e in fresh if episode_key(e) in rerun]
        return seconds, sum(recorded[episode_key(e)]["success"] for e in changed), sum(e["success"] for e in changed)

    def assemble_starts(self) -> Path | None:
        """Write ``results.json`` (protocol 1.4) once every cell is there; None while some are missing."""
        from frbench.evaluation.grid import EvaluationRequest
        from frbench.leaderboard.reuse import episode_key

        target = self.folder / "results.json"
        if target.is_file() or self.pending():
            return target if target.is_file() else None
        results = self.record["results"]
        rerun = set(self.rerun)
        fresh = [e for key in self.cells for e in json.loads(self.cell_path(key).read_text())["episodes"]
                 if episode_key(e) in rerun]
        config = results["config"]
        request = EvaluationRequest(policy=self.reference, grid=list(config["grid"]), jobs=1,
                                    protocol_version=TARGET_PROTOCOL)
        return rescore.write_reusing_results(self, target, request, fresh, config["backends"], self.rerun)


def main(argv: list[str] | None = None) -> int:
    parser = rescore.job_arguments(__doc__, DEFAULT_OUT, "every 1.3 record of the main board and the humanoid track")
    parser.add_argument("--max-cells", type=int, default=0, help="stop after this many cells (0: run to the end)")
    args = parser.parse_args(argv)
    rescore.single_threaded(args.out)
    if args.submit:
        return rescore.submit_finished(args.out, args.board, description_suffix)
    only = {n for n in args.only.split(",") if n}
    draws = StartDraws()
    records = [r for r in source_records(args.board) if not only or r["submission"]["name"] in only]
    names = [r["submission"]["name"] for r in records]
    if len(set(names)) != len(names):
        raise SystemExit(f"two records share a name among {', '.join(names)}: re-score them with --only")
    jobs = [StartsJob(r, args.board, args.out, draws) for r in records]
    if args.status:
        return rescore.print_status(jobs, lambda job: "{:>4} changed episodes, {}/{} cells".format(
            len(job.rerun), *job.done()))
    rescore.log(args.out, f"start: {len(jobs)} records, changed starts re-run under protocol {TARGET_PROTOCOL}, "
                          f"pid {os.getpid()}")
    ran = 0
    for job in jobs:
        job.meta()
        for key in job.pending():
            if args.max_cells and ran >= args.max_cells:
                rescore.log(args.out, f"stop after {ran} cells (--max-cells)")
                return 0
            seconds, before, after = job.run_one(key)
            rescore.log(args.out, f"{job.name} {' '.join(map(str, key))}: changed episodes' successes {before} -> "
                                  f"{after}, {seconds:.1f} s")
            ran += 1
        if job.assemble_starts() is not None:
            rescore.log(args.out, f"{job.name}: results.json complete ({len(job.rerun)} episodes re-run)")
    rescore.log(args.out, "finished: every cell is done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
