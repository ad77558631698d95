"""Add PhysX cells to every main-board record (protocol 1.3): one resumable job.

Protocol 1.3 adds PhysX to the standard and unseen grids (docs/protocol.md, "Protocol 1.3"). A record's MuJoCo
and PyBullet episodes are deterministic and their cells are the same under 1.3, so they are reused; only the
PhysX cells run: for each record of the main board, the cells of its standard and unseen grids (the humanoid set
too where its policy drives humanoids) in PhysX, one chunk (record x robot x terrain: 8-12 cells of 3 episodes)
at a time, one cell after the other in this process (the machine is shared), each written atomically to::

    OUT/<record name>/chunks/<grid>-<robot>-physx-<terrain>.json

A killed job resumes where it stopped: a chunk whose file exists is not run again. Records run one after the
other in board order (``scripted`` and ``frnet-30m`` first), each with all its grids, so that records finish one
by one. When a record's chunks are complete its protocol 1.3 results are written to
``OUT/<record name>/results.json`` (`PhysxJob.assemble_physx`): the record's MuJoCo and PyBullet episodes unchanged,
its new PhysX episodes beside them, and the ``reused`` field that names the source record and the sha256 of the
episodes taken from it (`frbench.leaderboard.reuse`), validated like a submission. ``--submit`` submits the
finished ones; the board ranks them once 1.3 is the current protocol, and the 1.2 records go to its archive::

    nice -n 10 nohup .venv/bin/python tools/rescore_physx.py >> runs/rescore-1.3/nohup.out 2>&1 &
    .venv/bin/python tools/rescore_physx.py --status
    .venv/bin/python tools/rescore_physx.py --assemble     # write results.json of every finished record
    .venv/bin/python tools/rescore_physx.py --submit       # submit them
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
    print_status,
    run_logged_chunk,
    single_threaded,
    submit_finished,
    write_reusing_results,
)

DEFAULT_OUT = ROOT / "runs" / "rescore-1.3"
#: The protocol the re-scored records are for, and the simulator it adds to the grids.
TARGET_PROTOCOL = "1.3"
#: The protocol of the records it re-scores.
SOURCE_PROTOCOL = "1.2"
SIMULATOR = "physx"
GRIDS = ("standard", "unseen")
#: The simulators whose episodes a 1.3 record takes unchanged from its 1.2 record.
REUSED = ("mujoco", "pybullet")


def description_suffix(record: str) -> str:
    """What the 1.3 record's description says of its origin."""
    return f"; protocol 1.3: record {record[:12]}'s MuJoCo and PyBullet episodes with its PhysX cells"


def main_board(board: Path) -> list[dict]:
    """The records of protocol 1.2's main board (`SOURCE_PROTOCOL`: main track, not superseded by a canonical-frame
    re-score), best first, without the ones that already hold PhysX cells."""
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.leaderboard.sections import superseded

    records = load_records(board)
    replaced = superseded(records)
    chosen = [r for r in records if r["results"]["protocol_version"] == SOURCE_PROTOCOL and r["track"] == "main"
              and r["id"] not in replaced and not any(c["backend"] == SIMULATOR for c in r["results"]["cells"])]
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

    def assemble_physx(self) -> Path | None:
        """Write ``results.json`` (protocol 1.3) once every chunk is there; None while some are missing. Its
        MuJoCo and PyBullet episodes are the source record's, checked by their checksum (``reused``)."""
        from frbench.evaluation.grid import EvaluationRequest

        target = self.folder / "results.json"
        if target.is_file() or any(self.pending(grid) for grid in GRIDS):
            return target if target.is_file() else None
        request = EvaluationRequest(policy=self.reference, grid=list(GRIDS), jobs=1,
                                    protocol_version=TARGET_PROTOCOL)
        return write_reusing_results(self, target, request, episodes_of(self), REUSED)


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
    parser.add_argument("--assemble", action="store_true", help="write results.json of every finished record and exit")
    args = parser.parse_args(argv)
    single_threaded(args.out)
    if args.submit:
        return submit_finished(args.out, args.board, description_suffix)
    only = {n for n in args.only.split(",") if n}
    jobs = [PhysxJob(r, args.board, args.out) for r in main_board(args.board)
            if not only or r["submission"]["name"] in only]
    if args.status:
        return print_status(jobs, lambda job: "{}/{} chunks".format(*job.done()))
    if args.assemble:
        for job in jobs:
            if job.assemble_physx() is not None:
                print(f"{job.name}: {job.folder / 'results.json'}")
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
                if run_logged_chunk(job, grid, chunk) is not None:
                    ran += 1
        log(args.out, f"{job.name}: every PhysX chunk written")
        if job.assemble_physx() is not None:
            log(args.out, f"{job.name}: results.json complete")
    log(args.out, "finished: every chunk is done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
