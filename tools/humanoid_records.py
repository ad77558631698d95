"""The humanoid track's records of the built-in humanoid policies (``--grid humanoid``): one resumable job.

For each policy (default: ``zero``, ``keyframe-humanoid``, ``scripted-humanoid``, ``mpc-distilled-g1`` (a learned
G1 policy), ``mpc``, in that order) it runs
``frbench evaluate --grid humanoid`` of protocol ``--protocol`` (the current one by default; the humanoid grid
exists from 1.3 on, docs/protocol.md, "The humanoid track") one *chunk* (policy x robot x simulator x family: 12
G1 cells or 8 humanoid-set cells, 3 episodes each) at a time, in this process, one cell after the other (the
machine is shared). Every finished chunk is written atomically to::

    OUT/<policy>/chunks/humanoid-<robot>-<simulator>-<family>.json    (its episodes)

and a killed job resumes where it stopped: a chunk whose file exists is not run again. The robots of the
humanoid set a policy cannot drive (a learned G1 policy drives the G1's 29 joints only) have no
chunks: their results name them in ``config.not_scored`` ("n/a" on the board, never 0). When a policy's chunks are
complete, ``OUT/<policy>/results.json`` is assembled (``frbench evaluate``'s document, checked like a
submission); ``--submit`` submits the finished ones. ``mpc`` costs about 25 CPU-s per G1 episode, so it runs
last, or alone with ``--only mpc``::

    nice -n 10 nohup .venv/bin/python tools/humanoid_records.py --protocol 1.3 >> runs/humanoid-1.3/nohup.out 2>&1 &
    .venv/bin/python tools/humanoid_records.py --protocol 1.3 --status
    .venv/bin/python tools/humanoid_records.py --protocol 1.3 --submit

Several processes of one job share its chunks: each claims the chunk it runs (``.<chunk file>.claim`` with its
process id, `rescore.claim_chunk`, as every chunked job of `rescore` does) and passes over those another live process holds, so the same command started
once per free core runs that many chunks at a time; a claim whose process has gone is taken over.

``--adopt EARLIER`` (e.g. ``runs/humanoid-1.3``) takes each pending chunk that a job of an earlier protocol wrote
under ``EARLIER/<policy>/chunks/`` when every start of its episodes (the first draw and each screening redraw an
episode used) is drawn the same under both protocols (`rescore_starts.StartDraws`): nothing else of a cell reads
the protocol, so such a chunk's episodes are this protocol's, bit for bit. Under 1.4 that is every G1 chunk of 1.3
(the G1's starts are unchanged, docs/protocol.md, "Protocol 1.4") and no iCub or Talos chunk with a redrawn start;
the copy names its origin (``adopted_from``) and the log says which chunks were taken::

    .venv/bin/python tools/humanoid_records.py --only mpc --adopt runs/humanoid-1.3 --status   # adopt, then run without --status

OUT is ``--out``, else ``runs/humanoid-<protocol>``. The job machinery (chunk files, the meta file, the log,
single-threaded runs, submission) is tools/rescore.py's.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rescore  # noqa: E402  (tools/rescore.py: the job machinery)

GRID = "humanoid"
#: The built-in policies run by default, in this order (the cheapest first; ``mpc`` plans at every step).
POLICIES = ("zero", "keyframe-humanoid", "scripted-humanoid", "mpc-distilled-g1", "mpc")
#: The board description of each default policy's record (`tools.rescore.rescored_description` adds the origin).
DESCRIPTIONS = {
    "zero": "Holds the default pose: the floor of the humanoid track.",
    "keyframe-humanoid": "The G1 getting-up state machine with tuned key poses (frbench.policies.keyframe_humanoid).",
    "scripted-humanoid": "The G1 getting-up state machine (frbench.policies.scripted_humanoid).",
    "mpc-distilled-g1": "A learned G1 policy: an MLP distilled from mpc by DAgger (frbench distill, 144 episodes); "
                        "proprioception only, the G1's 29 joints.",
    "mpc": "Sampling MPC over the simulator's state (frbench.policies.mpc): not a blind policy.",
}


def default_out(version: str) -> Path:
    """``runs/humanoid-<version>``: where a job of protocol ``version`` writes by default."""
    return rescore.ROOT / "runs" / f"humanoid-{version}"


def description_suffix(_record: str) -> str:
    """What each record's description says of its origin (the records are not re-scores of another)."""
    return "; frbench evaluate --grid humanoid, run by tools/humanoid_records.py"


def humanoid_chunks(request) -> list[tuple[str, str, str, list]]:
    """(robot, simulator, family, cells) of a validated ``--grid humanoid`` request, in its cell order."""
    groups: dict[tuple, list] = {}
    for cell in request.cells():
        groups.setdefault((cell.robot, cell.backend, cell.terrain), []).append(cell)
    return [(*key, cells) for key, cells in groups.items()]


class HumanoidJob(rescore.Job):
    """One built-in policy on the humanoid grid of one protocol version: its request and chunk files."""

    def __init__(self, policy: str, out: Path, version: str):
        from frbench.evaluation.grid import EvaluationRequest, validate

        self.version, self.out, self.name, self.reference = version, out, policy, policy
        self.record = {"id": f"built-in {policy}", "submission": {
            "name": policy, "description": DESCRIPTIONS.get(policy, ""), "submitter": "frbench", "link": None}}
        self.request = EvaluationRequest(policy=policy, grid=[GRID], jobs=1, protocol_version=version)
        self.policy = validate(self.request)
        self.folder = out / policy
        self.chunks = {GRID: humanoid_chunks(self.request)}

    @property
    def protocol_version(self) -> str:
        return self.version

    def done(self) -> tuple[int, int]:
        """(chunks written, chunks in all)."""
        total = len(self.chunks[GRID])
        return total - len(self.pending(GRID)), total

    def assemble_humanoid(self) -> Path | None:
        """Write ``results.json`` once every chunk is there (checked by `check_results`); None while some are
        missing."""
        from frbench.evaluation.grid import build_results
        from frbench.io import atomic_write_text
        from frbench.leaderboard.results import check_results
        from frbench.leaderboard.reuse import EPISODE_ORDER

        target = self.folder / "results.json"
        if target.is_file() or self.pending(GRID):
            return target if target.is_file() else None
        files = [rescore.chunk_path(self.out, self.name, GRID, *chunk[:3]) for chunk in self.chunks[GRID]]
        episodes = [episode for path in files for episode in json.loads(path.read_text())["episodes"]]
        episodes.sort(key=lambda e: tuple(e[k] for k in EPISODE_ORDER))
        results = build_results(self.request, self.policy, episodes, code=self.meta()["frbench"])
        check_results(results)
        atomic_write_text(target, json.dumps(results, indent=1) + "\n")
        return target


    def adopt(self, earlier: Path, draws) -> list[Path]:
        """Copy each pending chunk an earlier protocol's job wrote under ``earlier`` whose cells are this chunk's and
        whose episodes' starts ``draws`` (a `rescore_starts.StartDraws` of the two protocols) finds unchanged;
        returns the chunk files written."""
        from frbench.io import atomic_write_text
        from frbench.tasks.protocol import version_key

        meta_path = earlier / self.name / "meta.json"
        if not meta_path.is_file():
            return []
        version = json.loads(meta_path.read_text())["protocol_version"]
        if version_key(version) >= version_key(self.version):
            raise SystemExit(f"--adopt {earlier}: its chunks are of protocol {version}, not earlier than {self.version}")
        taken = []
        for chunk in self.pending(GRID):
            source = rescore.chunk_path(earlier, self.name, GRID, *chunk[:3])
            if not source.is_file():
                continue
            document = json.loads(source.read_text())
            same_cells = document["cells"] == [list(c.key()) for c in chunk[3]]
            if same_cells and all(draws.unchanged(e["robot"], e["terrain"], e["level"], e["seed"], e["episode"], a)
                                  for e in document["episodes"] for a in range(e["start_redraws"] + 1)):
                target = rescore.chunk_path(self.out, self.name, GRID, *chunk[:3])
                atomic_write_text(target, json.dumps({**document, "adopted_from": version}) + "\n")
                taken.append(target)
        return taken


def run(jobs: list[HumanoidJob], out: Path, max_chunks: int = 0) -> int:
    """Run every pending chunk of ``jobs`` in order (at most ``max_chunks``, 0: all), assembling each policy's
    results when its chunks are complete."""
    rescore.log(out, f"start: {', '.join(j.name for j in jobs)} on the humanoid grid of protocol "
             f"{jobs[0].version if jobs else '-'}, pid {os.getpid()}")
    ran = elsewhere = 0
    for job in jobs:
        job.meta()
        for chunk in job.pending(GRID):
            if max_chunks and ran >= max_chunks:
                rescore.log(out, f"stop after {ran} chunks (--max-chunks)")
                return 0
            if rescore.run_logged_chunk(job, GRID, chunk) is None:  # another process of the job runs it
                elsewhere += 1
                continue
            ran += 1
        if job.assemble_humanoid() is not None:
            rescore.log(out, f"{job.name}: results.json complete")
    rescore.log(out, "finished: every chunk is done" if not elsewhere else
                f"finished here: {elsewhere} chunks were another process' (claimed or written meanwhile)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """The job's command line (the module docstring); a `FrbenchError` for a bad protocol or policy."""
    from frbench.evaluation.grids import grid_parts
    from frbench.tasks.protocol import PROTOCOL_VERSION

    parser = rescore.job_arguments(__doc__, Path("runs/humanoid-<protocol>"), ",".join(POLICIES))
    parser.set_defaults(out=None)
    parser.add_argument("--protocol", default=PROTOCOL_VERSION,
                        help=f"the protocol whose humanoid grid runs (default: the current one, {PROTOCOL_VERSION})")
    parser.add_argument("--max-chunks", type=int, default=0, help=rescore.MAX_CHUNKS_HELP)
    parser.add_argument("--adopt", type=Path, default=None,
                        help="an earlier protocol's OUT: take its chunks whose starts this protocol draws the same")
    args = parser.parse_args(argv)
    grid_parts(GRID, args.protocol)  # a protocol without the humanoid grid: one line, before anything is made
    out = args.out or default_out(args.protocol)
    rescore.single_threaded(out)
    if args.submit:
        return rescore.submit_finished(out, args.board, description_suffix)
    policies = [n for n in args.only.split(",") if n] or list(POLICIES)
    jobs = [HumanoidJob(policy, out, args.protocol) for policy in policies]
    if args.adopt is not None:
        from rescore_starts import StartDraws

        for job in jobs:
            earlier = args.adopt / job.name / "meta.json"
            if earlier.is_file():
                job.meta()
                draws = StartDraws(json.loads(earlier.read_text())["protocol_version"], args.protocol)
                for path in job.adopt(args.adopt, draws):
                    rescore.log(out, f"{job.name}: {path.name} adopted from {args.adopt}")
    if args.status:
        for job in jobs:
            done, total = job.done()
            finished = ", results.json" if (job.folder / "results.json").is_file() else ""
            print(f"{job.name:<20} {done}/{total} chunks{finished}")
        return 0
    return run(jobs, out, args.max_chunks)


if __name__ == "__main__":
    from frbench.errors import FrbenchError

    try:
        sys.exit(main())
    except FrbenchError as exc:  # a bad --protocol or policy: one line, exit 2
        print(f"tools/humanoid_records.py: error: {exc}", file=sys.stderr)
        sys.exit(2)
