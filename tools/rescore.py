"""Re-score every main-board record under protocol 1.2 on the standard and unseen grids: one resumable job.

For each record on the leaderboard's main board (the current protocol's and, before any 1.2 record exists, the
1.1 main board) it re-runs the record's policy (its attached file, its shipped checkpoint or the built-in policy,
as `frbench verify` resolves it) on the grids of ``frbench evaluate --grid standard,unseen``, one *chunk*
(record x robot x backend x terrain: 8-12 cells) at a time, in this process, one cell after the other
(``--jobs 1``: the machine is shared). Order: the unseen grid of every record first (what 1.2 adds), then the
standard grids. Every finished chunk is written atomically to::

    OUT/<record name>/chunks/<grid>-<robot>-<backend>-<terrain>.json    (its episodes)

and a killed job resumes where it stopped: a chunk whose file exists is not run again (processes of one job share
its chunks: each claims the chunk it runs, `claim_chunk`, so the command started once per free core runs that many
at a time). When a record's grid is complete its results file is assembled (``frbench evaluate``'s document,
validated like a submission)::

    OUT/<record name>/unseen.json       (grid unseen)
    OUT/<record name>/results.json      (grid standard,unseen: what ``frbench submit`` takes)

Progress goes to ``OUT/progress.log`` (one line per chunk with its seconds) and ``OUT/status.json`` (chunks done
per record, seconds so far, the extrapolated remainder). Start it with low priority and leave it::

    nice -n 10 nohup .venv/bin/python tools/rescore.py >> runs/rescore-1.2/nohup.out 2>&1 &

    .venv/bin/python tools/rescore.py --status          # where it stands
    .venv/bin/python tools/rescore.py --submit          # submit every finished results.json not yet on the board

The same command resumes a stopped job (also in another checkout, given the same OUT folder).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "runs" / "rescore-1.2"
GRIDS = ("unseen", "standard")  # the order phases run in
MAX_CHUNKS_HELP = "stop after this many chunks (0: run to the end)"


def log(out: Path, text: str) -> None:
    line = f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} {text}"
    print(line, flush=True)
    with open(out / "progress.log", "a", encoding="utf-8") as handle:
        handle.write(line + "\n")


def board_records(board: Path) -> list[dict]:
    """The records to re-score: the main board of the newest protocol that has one, in board order."""
    from frbench.leaderboard.records import load_records
    from frbench.leaderboard.scores import rank_key

    records = [r for r in load_records(board) if r["track"] == "main"]
    versions = sorted({r["results"]["protocol_version"] for r in records}, key=lambda v: tuple(map(int, v.split("."))))
    for version in reversed(versions):
        if version != "1.2":  # the records to re-score are the last protocol's main board
            chosen = [r for r in records if r["results"]["protocol_version"] == version]
            return sorted(chosen, key=lambda r: rank_key(r["scores"], r["submission"]["submitted"], r["id"]))
    return []


def policy_reference(record: dict, board: Path) -> str:
    """What `frbench verify` would re-run for the record (attached file, shipped checkpoint or built-in name)."""
    from frbench.leaderboard.verify import Verification, resolve_policy

    report = Verification(record["id"], record["results"]["protocol_version"])
    reference = resolve_policy(record, board, report)
    if reference is None:
        raise SystemExit(f"record {record['id'][:12]}: its policy cannot be re-run: {'; '.join(report.failures)}")
    return reference


def chunks_of(grid: str, request) -> list[tuple[str, str, str, list]]:
    """(robot, backend, terrain, cells) of one grid for a validated request (its cell keys)."""
    from frbench.evaluation.grids import grid_parts

    robots = {r for part in grid_parts(grid) for r in part.robots}
    groups: dict[tuple, list] = {}
    for cell in request.cells():
        if cell.robot in robots:
            groups.setdefault((cell.robot, cell.backend, cell.terrain), []).append(cell)
    return [(*key, cells) for key, cells in groups.items()]


def chunk_path(out: Path, name: str, grid: str, robot: str, backend: str, terrain: str) -> Path:
    return out / name / "chunks" / f"{grid}-{robot}-{backend}-{terrain}.json"


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def claim_chunk(path: Path) -> Path | None:
    """Claim the chunk whose file is ``path`` for this process, so that several job processes on one machine
    share the chunks (each runs the chunks nobody else claimed): the claim file ``.<file name>.claim`` beside it,
    holding this process' id from the instant it exists (written aside, then hard-linked into place, which fails
    when the claim exists). Returns the claim to release, or None when the chunk is written or another live
    process holds it. A claim left by a process that no longer runs is taken over."""
    claim = path.with_name(f".{path.name}.claim")
    claim.parent.mkdir(parents=True, exist_ok=True)
    mine = claim.with_name(f"{claim.name}.{os.getpid()}")
    mine.write_text(str(os.getpid()))
    try:
        for _ in range(2):
            if path.is_file():
                return None
            try:
                os.link(mine, claim)
            except FileExistsError:
                try:
                    holder = int(claim.read_text())
                except (OSError, ValueError):
                    holder = 0
                if holder and _alive(holder):
                    return None
                claim.unlink(missing_ok=True)  # stale: its process is gone
                continue
            if path.is_file():  # written between the check and the claim
                claim.unlink(missing_ok=True)
                return None
            return claim
        return None
    finally:
        mine.unlink(missing_ok=True)


class Job:
    """One record's re-score: its request (grid standard,unseen) and the chunk files."""

    def __init__(self, record: dict, board: Path, out: Path):
        from frbench.evaluation.grid import EvaluationRequest, validate

        self.record, self.out = record, out
        self.name = record["submission"]["name"]
        self.reference = policy_reference(record, board)
        self.request = EvaluationRequest(policy=self.reference, grid=["standard", "unseen"], jobs=1)
        self.policy = validate(self.request)
        self.folder = out / self.name
        self.chunks = {grid: chunks_of(grid, self.request) for grid in GRIDS}

    def pending(self, grid: str) -> list[tuple]:
        return [c for c in self.chunks[grid] if not chunk_path(self.out, self.name, grid, *c[:3]).is_file()]

    def meta(self) -> dict:
        """The record's meta file: source record, policy, the protocol its chunks are for (``protocol_version``:
        the current one unless a subclass targets another), the commit its first chunk ran (written once)."""
        from frbench.evaluation.provenance import frbench_info
        from frbench.io import atomic_write_text

        version = self.protocol_version
        path = self.folder / "meta.json"
        if path.is_file():
            meta = json.loads(path.read_text())
            if meta["protocol_version"] != version:
                raise SystemExit(f"{path}: chunks of protocol {meta['protocol_version']}, this job makes protocol "
                                 f"{version}: move {self.folder} away to start over")
            return meta
        meta = {"record": self.record["id"], "name": self.name, "policy": self.reference,
                "protocol_version": version, "frbench": frbench_info(),
                "submission": self.record["submission"]}
        atomic_write_text(path, json.dumps(meta, indent=1) + "\n")
        return meta

    @property
    def protocol_version(self) -> str:
        """The protocol the job's results are for: the current one."""
        from frbench.tasks.protocol import PROTOCOL_VERSION

        return PROTOCOL_VERSION

    def run_chunk(self, grid: str, chunk: tuple) -> float:
        from frbench.evaluation.runner import run_cell
        from frbench.io import atomic_write_text

        robot, backend, terrain, cells = chunk
        started = time.monotonic()
        episodes = []
        for cell in cells:
            episodes += run_cell(cell, self.reference, self.request.noise)
        seconds = time.monotonic() - started
        from frbench.evaluation.provenance import frbench_info

        document = {"cells": [list(c.key()) for c in cells], "seconds": round(seconds, 2), "frbench": frbench_info(),
                    "episodes": episodes}
        atomic_write_text(chunk_path(self.out, self.name, grid, robot, backend, terrain), json.dumps(document) + "\n")
        return seconds

    def assemble(self, grids: list[str], file_name: str) -> Path | None:
        """Build and write the results of ``grids`` once every chunk is there; None while some are missing."""
        from frbench.evaluation.grid import EvaluationRequest, build_results, validate
        from frbench.io import atomic_write_text
        from frbench.leaderboard.results import check_results

        target = self.folder / file_name
        if target.is_file() or any(self.pending(g) for g in grids):
            return target if target.is_file() else None
        request = EvaluationRequest(policy=self.reference, grid=list(grids), jobs=1)
        policy = validate(request)
        wanted = {c.key() for c in request.cells()}
        episodes = []
        for grid in grids:
            for chunk in self.chunks[grid]:
                data = json.loads(chunk_path(self.out, self.name, grid, *chunk[:3]).read_text())
                episodes += [e for e in data["episodes"]
                             if (e["robot"], e["backend"], e["terrain"], e["level"], e["seed"]) in wanted]
        episodes.sort(key=lambda r: (r["robot"], r["backend"], r["terrain"], r["level"], r["seed"], r["episode"]))
        results = build_results(request, policy, episodes, code=self.meta()["frbench"])
        check_results(results)
        atomic_write_text(target, json.dumps(results, indent=1) + "\n")
        return target


def write_reusing_results(job: Job, target: Path, request, fresh: list[dict], backends, rerun=()) -> Path:
    """Write ``target``: the results of ``request`` (an `EvaluationRequest` of the target protocol) holding the
    ``fresh`` episodes and the job's source record's episodes of ``backends`` except ``rerun`` (episode keys)
    unchanged, with the ``reused`` field that names them (`frbench.leaderboard.reuse`); checked like a submission
    and against the source record."""
    from frbench.evaluation.grid import build_results, validate
    from frbench.io import atomic_write_text
    from frbench.leaderboard.results import check_results
    from frbench.leaderboard.reuse import check_against_source, episode_key, reused_episodes, reused_field

    policy = validate(request)
    episodes = sorted(reused_episodes(job.record, backends, rerun) + list(fresh), key=episode_key)
    results = build_results(request, policy, episodes, code=job.meta()["frbench"])
    results["reused"] = reused_field(job.record, backends, rerun)
    check_results(results)
    check_against_source(results, job.record)
    atomic_write_text(target, json.dumps(results, indent=1) + "\n")
    return target


def run_logged_chunk(job: Job, grid: str, chunk: tuple) -> float | None:
    """Run one chunk of ``job`` under its claim (`claim_chunk`) and log it (record, grid, robot, backend, terrain,
    cells, successes, seconds); its seconds, or None when another process of the job holds it or wrote it."""
    path = chunk_path(job.out, job.name, grid, *chunk[:3])
    claim = claim_chunk(path)
    if claim is None:
        return None
    try:
        took = job.run_chunk(grid, chunk)
    finally:
        claim.unlink(missing_ok=True)
    successes = sum(e["success"] for e in json.loads(
        chunk_path(job.out, job.name, grid, *chunk[:3]).read_text())["episodes"])
    log(job.out, f"{job.name} {grid} {chunk[0]} {chunk[1]} {chunk[2]}: {len(chunk[3])} cells, {successes} successes, "
                 f"{took:.1f} s")
    return took


def write_status(out: Path, jobs: list[Job], seconds: dict[str, float]) -> dict:
    from frbench.io import atomic_write_text

    status = {"records": {}, "updated": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    done_total = all_total = 0
    for job in jobs:
        entry = {}
        for grid in GRIDS:
            total = len(job.chunks[grid])
            done = total - len(job.pending(grid))
            entry[grid] = f"{done}/{total}"
            done_total += done
            all_total += total
        entry["seconds"] = round(seconds.get(job.name, 0.0), 1)
        status["records"][job.name] = entry
    measured = [json.loads(p.read_text())["seconds"] for p in out.glob("*/chunks/*.json")]
    status["chunks"] = f"{done_total}/{all_total}"
    if measured:
        mean = sum(measured) / len(measured)
        status["mean_chunk_seconds"] = round(mean, 1)
        status["remaining_hours_at_that_mean"] = round(mean * (all_total - done_total) / 3600, 1)
    atomic_write_text(out / "status.json", json.dumps(status, indent=1) + "\n")
    return status


def protocol_suffix(record: str) -> str:
    """What a record re-scored under protocol 1.2 says of its origin."""
    return f"; re-scored under protocol 1.2 (standard and unseen grids) from record {record[:12]}"


def rescored_description(description: str, record: str, origin=protocol_suffix) -> str:
    """The original description, shortened with an ellipsis where needed, and what re-scored it (``origin(record)``),
    within the board's limit of ``DESCRIPTION_MAX`` characters."""
    from frbench.leaderboard.records import DESCRIPTION_MAX

    suffix = origin(record)
    room = DESCRIPTION_MAX - len(suffix)
    text = description.strip()
    if len(text) > room:
        text = text[:room - 1].rstrip() + "\u2026"
    return text + suffix


def submit_finished(out: Path, board: Path, origin=protocol_suffix) -> int:
    """Submit each finished results.json whose results are not on the board yet, with its policy file; its
    description ends with ``origin(source record id)``."""
    from frbench.leaderboard import board as lb
    from frbench.leaderboard.records import load_records

    on_board = {r["id"] for r in load_records(board)}
    from frbench.leaderboard.records import record_id

    submitted = 0
    for meta_path in sorted(out.glob("*/meta.json")):
        meta = json.loads(meta_path.read_text())
        results_path = meta_path.parent / "results.json"
        if not results_path.is_file():
            continue
        if record_id(json.loads(results_path.read_text())) in on_board:
            continue
        source = meta["submission"]
        policy = meta["policy"]
        policy_file = policy if Path(policy.split(":")[0]).is_file() else None
        description = rescored_description(source["description"], meta["record"], origin)
        done = lb.submit(results_path, board, name=source["name"], description=description,
                         submitter=source["submitter"], link=source.get("link"), policy_file=policy_file)
        print(f"submitted {source['name']}: record {done.record['id'][:12]} ({done.record['track']})")
        submitted += 1
    print(f"{submitted} record(s) submitted")
    return 0


def print_status(jobs, progress) -> int:
    """Print one line per job: its name, ``progress(job)`` (e.g. ``3/12 chunks``) and whether its results.json is
    written; returns 0."""
    for job in jobs:
        print(f"{job.name:<28} {progress(job)}" + (", results.json" if (job.folder / "results.json").is_file() else ""))
    return 0


def job_arguments(doc: str, default_out: Path, records: str) -> argparse.ArgumentParser:
    """The options every re-score tool takes: --out, --board, --only (``records``: which records by default),
    --status, --submit."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--out", type=Path, default=default_out, help=f"results folder (default {default_out})")
    parser.add_argument("--board", type=Path, default=ROOT / "leaderboard", help="leaderboard folder")
    parser.add_argument("--only", default="", help=f"comma-separated record names (default: {records})")
    parser.add_argument("--status", action="store_true", help="print where the job stands and exit")
    parser.add_argument("--submit", action="store_true", help="submit finished results to the board and exit")
    return parser


def single_threaded(out: Path) -> None:
    """One MuJoCo and one torch thread in this process (the machine is shared); ``out`` made."""
    os.environ.setdefault("FRBENCH_MUJOCO_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    out.mkdir(parents=True, exist_ok=True)


def main(argv: list[str] | None = None) -> int:
    parser = job_arguments(__doc__, DEFAULT_OUT, "every main-board record")
    parser.add_argument("--grids", default=",".join(GRIDS), help="phases to run, in order (default unseen,standard)")
    parser.add_argument("--max-chunks", type=int, default=0, help=MAX_CHUNKS_HELP)
    args = parser.parse_args(argv)
    single_threaded(args.out)
    if args.submit:
        return submit_finished(args.out, args.board)
    records = board_records(args.board)
    only = {n for n in args.only.split(",") if n}
    jobs = [Job(r, args.board, args.out) for r in records if not only or r["submission"]["name"] in only]
    seconds: dict[str, float] = {}
    if args.status:
        print(json.dumps(write_status(args.out, jobs, seconds), indent=1))
        return 0
    log(args.out, f"start: {len(jobs)} records, grids {args.grids}, pid {os.getpid()}")
    ran = 0
    for grid in [g for g in args.grids.split(",") if g]:
        for job in jobs:
            job.meta()
            for chunk in job.pending(grid):
                if args.max_chunks and ran >= args.max_chunks:
                    write_status(args.out, jobs, seconds)
                    log(args.out, f"stop after {ran} chunks (--max-chunks)")
                    return 0
                took = run_logged_chunk(job, grid, chunk)
                if took is None:  # another process of the job runs it
                    continue
                ran += 1
                seconds[job.name] = seconds.get(job.name, 0.0) + took
                write_status(args.out, jobs, seconds)
            for files in ((["unseen"], "unseen.json"), (["standard"], "standard.json"),
                          (["standard", "unseen"], "results.json")):
                path = job.assemble(*files)
                if path is not None and not (args.out / job.name / f".{files[1]}.logged").exists():
                    (args.out / job.name / f".{files[1]}.logged").touch()
                    log(args.out, f"{job.name}: {path.relative_to(args.out)} complete")
    write_status(args.out, jobs, seconds)
    log(args.out, "finished: every chunk is done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
