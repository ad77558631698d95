"""Re-score the learned main-board records in the canonical joint frame: one resumable job.

frbench's learned policies observe and act in the canonical joint frame (`frbench.robots.joint_frame`). A record
made before the frame existed ran them in each robot's own convention. Every training robot's frame is the
identity, so on the standard grid, and on the unseen robots whose frame is the identity (A1, B1, Laikago), the
two are the same computation and the recorded episodes stand (`frbench verify` re-runs them bit for bit in the
canonical frame: ``tests/test_learned_joint_frame.py``). Only the unseen robots with another frame (Solo12,
Mini Cheetah, Spirit40, Vision60, ANYmal B and C) are re-run, one chunk (record x robot x backend x terrain: 8
cells of 3 episodes) at a time, written atomically to::

    OUT/<record name>/chunks/unseen-<robot>-<backend>-<terrain>.json

and a killed job resumes where it stopped. When a record's chunks are complete its results (the recorded
episodes where the frame is the identity, the new ones elsewhere; ``policy.joint_frame: canonical``) are written
to ``OUT/<record name>/results.json`` and validated like a submission. The new record has a new id (its results
differ); the board lists the record it re-scores as superseded (docs/protocol.md, "The joint frame")::

    nice -n 10 nohup .venv/bin/python tools/rescore_frame.py >> runs/rescore-frame/nohup.out 2>&1 &
    .venv/bin/python tools/rescore_frame.py --status
    .venv/bin/python tools/rescore_frame.py --submit
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from rescore import (  # noqa: E402
    ROOT,
    Job,
    chunk_path,
    job_arguments,
    log,
    policy_reference,
    run_logged_chunk,
    single_threaded,
    submit_finished,
)

DEFAULT_OUT = ROOT / "runs" / "rescore-frame"
GRID = "unseen"


def description_suffix(record: str) -> str:
    """What the re-scored record's description says of its origin."""
    return f"; unseen grid re-scored in the canonical joint frame from record {record[:12]}"


def frame_records(board: Path) -> list[dict]:
    """The current protocol's main-board records whose policy is a canonical-frame learned policy and whose results
    ran it in the robot's frame, best first."""
    from frbench.evaluation.runner import _policy
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key
    from frbench.tasks.protocol import PROTOCOL_VERSION

    chosen = []
    for record in load_records(board):
        results = record["results"]
        if record["track"] != "main" or results["protocol_version"] != PROTOCOL_VERSION:
            continue
        if results["policy"].get("joint_frame", "robot") == "canonical":
            continue
        if getattr(_policy(policy_reference(record, board)), "joint_frame", "robot") == "canonical":
            chosen.append(record)
    return sorted(chosen, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"]))


def moved_robots() -> set[str]:
    """The unseen grid's robots whose canonical frame is not the identity: the cells the frame changes."""
    from frbench.evaluation.grids import unseen_part
    from frbench.robots import get_robot
    from frbench.robots.joint_frame import joint_frame

    return {name for name in unseen_part().robots if not joint_frame(get_robot(name)).is_identity}


class FrameJob(Job):
    """One record's re-score in the canonical frame: the unseen chunks of `moved_robots` only."""

    def __init__(self, record: dict, board: Path, out: Path, robots: set[str]):
        super().__init__(record, board, out)
        self.chunks = {GRID: [c for c in self.chunks[GRID] if c[0] in robots], "standard": []}
        self.robots = robots

    def assemble_frame(self) -> Path | None:
        """Write ``results.json`` once every chunk is there (None while some are missing)."""
        from frbench.evaluation.grid import EvaluationRequest, build_results, validate
        from frbench.io import atomic_write_text
        from frbench.leaderboard.results import check_results

        target = self.folder / "results.json"
        if target.is_file() or self.pending(GRID):
            return target if target.is_file() else None
        recorded = self.record["results"]
        request = EvaluationRequest(policy=self.reference, grid=list(recorded["config"]["grid"]), jobs=1)
        policy = validate(request)
        episodes = [e for e in recorded["episodes"] if e["robot"] not in self.robots]
        for chunk in self.chunks[GRID]:
            episodes += json.loads(chunk_path(self.out, self.name, GRID, *chunk[:3]).read_text())["episodes"]
        episodes.sort(key=lambda r: (r["robot"], r["backend"], r["terrain"], r["level"], r["seed"], r["episode"]))
        results = build_results(request, policy, episodes, code=self.meta()["frbench"])
        if results["policy"].get("joint_frame") != "canonical":
            raise SystemExit(f"{self.name}: the policy does not declare the canonical frame")
        check_results(results)
        atomic_write_text(target, json.dumps(results, indent=1) + "\n")
        return target


def main(argv: list[str] | None = None) -> int:
    args = job_arguments(__doc__, DEFAULT_OUT, "every such record").parse_args(argv)
    single_threaded(args.out)
    if args.submit:
        return submit_finished(args.out, args.board, description_suffix)
    only = {n for n in args.only.split(",") if n}
    robots = moved_robots()
    jobs = [FrameJob(r, args.board, args.out, robots) for r in frame_records(args.board)
            if not only or r["submission"]["name"] in only]
    if args.status:
        for job in jobs:
            total = len(job.chunks[GRID])
            print(f"{job.name:<28} {total - len(job.pending(GRID))}/{total} chunks"
                  + (", results.json" if (job.folder / "results.json").is_file() else ""))
        return 0
    log(args.out, f"start: {len(jobs)} records, robots {', '.join(sorted(robots))}, pid {os.getpid()}")
    for job in jobs:
        job.meta()
        for chunk in job.pending(GRID):
            run_logged_chunk(job, GRID, chunk)
        if job.assemble_frame() is not None:
            log(args.out, f"{job.name}: results.json complete")
    log(args.out, "finished")
    return 0


if __name__ == "__main__":
    sys.exit(main())
