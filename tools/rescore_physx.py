"""Add PhysX cells to every main-board record (protocol 1.3): one resumable job.

Protocol 1.3 adds PhysX to the standard and unseen grids (docs/protocol.md, "Protocol 1.3"). A record's MuJoCo
and PyBullet episodes are deterministic and their cells are the same under 1.3, so they are reused; only the
PhysX cells run: for each record of the main board, the cells of its standard and unseen grids (the humanoid set
too where its policy drives humanoids) in PhysX, one chunk (record x robot x terrain: 8-12 cells of 3 episodes)
at a time, one cell after the other in this process (the machine is shared), each written atomically to::

    OUT/<record name>/chunks/<grid>-<robot>-physx-<terrain>.json

A killed job resumes where it stopped: a chunk whose file exists is not run again. Records run one after the
other in board order (``scripted`` and ``frnet-30m`` first), each with all its grids, so that records finish one
by one. When a record's chunks are complete, ``--assemble`` writes its protocol 1.3 results (`Physx13Job`),
``--submit`` submits them::

    nice -n 10 nohup .venv/bin/python tools/rescore_physx.py >> runs/rescore-1.3/nohup.out 2>&1 &
    .venv/bin/python tools/rescore_physx.py --status
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from rescore import (  # noqa: E402
    MAX_CHUNKS_HELP,
    ROOT,
    Job,
    chunk_path,
    job_arguments,
    log,
    run_logged_chunk,
    single_threaded,
)

DEFAULT_OUT = ROOT / "runs" / "rescore-1.3"
#: The protocol the re-scored records are for, and the simulator it adds to the grids.
TARGET_PROTOCOL = "1.3"
SIMULATOR = "physx"
GRIDS = ("standard", "unseen")


def main_board(board: Path) -> list[dict]:
    """The records the board ranks on its main board now (`frbench.leaderboard.sections`), best first, without the
    ones that already hold PhysX cells."""
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.leaderboard.sections import section_of, superseded

    records = load_records(board)
    replaced = superseded(records)
    chosen = [r for r in records if section_of(r, replaced) == "main"
              and not any(c["backend"] == SIMULATOR for c in r["results"]["cells"])]
    return sorted(chosen, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"]))


class PhysxJob(Job):
    """One record's PhysX cells: each MuJoCo chunk of its grids (`rescore.chunks_of`) run in PhysX."""

    def __init__(self, record: dict, board: Path, out: Path):
        super().__init__(record, board, out)
        self.chunks = {grid: [(robot, SIMULATOR, terrain, [_in_physx(cell) for cell in cells])
                              for robot, backend, terrain, cells in self.chunks[grid] if backend == "mujoco"]
                       for grid in GRIDS}

    @property
    def protocol_version(self) -> str:
        return TARGET_PROTOCOL

    def done(self) -> tuple[int, int]:
        """(chunks written, chunks in all)."""
        total = sum(len(self.chunks[grid]) for grid in GRIDS)
        return total - sum(len(self.pending(grid)) for grid in GRIDS), total


def _in_physx(cell):
    import dataclasses

    return dataclasses.replace(cell, backend=SIMULATOR)


def episodes_of(job: PhysxJob) -> list[dict]:
    """The PhysX episodes of a record whose chunks are all written, in chunk order."""
    episodes = []
    for grid in GRIDS:
        for chunk in job.chunks[grid]:
            episodes += json.loads(chunk_path(job.out, job.name, grid, *chunk[:3]).read_text())["episodes"]
    return episodes


def main(argv: list[str] | None = None) -> int:
    parser = job_arguments(__doc__, DEFAULT_OUT, "the whole main board")
    parser.add_argument("--max-chunks", type=int, default=0, help=MAX_CHUNKS_HELP)
    args = parser.parse_args(argv)
    single_threaded(args.out)
    only = {n for n in args.only.split(",") if n}
    jobs = [PhysxJob(r, args.board, args.out) for r in main_board(args.board)
            if not only or r["submission"]["name"] in only]
    if args.status:
        for job in jobs:
            done, total = job.done()
            print(f"{job.name:<28} {done}/{total} chunks")
        return 0
    log(args.out, f"start: {len(jobs)} records, PhysX cells for protocol {TARGET_PROTOCOL}, pid {os.getpid()}")
    ran = 0
    for job in jobs:
        job.meta()
        for grid in GRIDS:
            for chunk in job.pending(grid):
                if args.max_chunks and ran >= args.max_chunks:
                    log(args.out, f"stop after {ran} chunks (--max-chunks)")
                    return 0
                run_logged_chunk(job, grid, chunk)
                ran += 1
        log(args.out, f"{job.name}: every PhysX chunk written")
    log(args.out, "finished: every chunk is done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
