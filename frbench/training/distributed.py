"""Training across processes: rsl-rl's multi-process PPO on CPUs (gloo) or GPUs (NCCL).

``frbench train --nproc N ...`` starts N copies of the same ``frbench train``
command on this machine, with the environment torchrun would give them
(:func:`launch`); ``torchrun --nnodes M --nproc-per-node N ... -m frbench train
...`` runs it on several machines (docs/scale.md). Each process (rank) reads
``WORLD_SIZE``, ``RANK`` and ``LOCAL_RANK`` and:

* trains its own ``--envs`` environments (the run trains N·envs in all), drawn
  from its own seed stream (:func:`rank_seed`; rank 0 keeps the run's seed, so
  a 1-process run is rank 0 of any N-process run);
* joins one process group: NCCL on ``cuda:LOCAL_RANK`` where CUDA is available,
  else gloo on the CPU (:class:`DistributedRunner`, the one place frbench
  overrides a private method of rsl-rl: see there why);
* averages every gradient over the ranks before each optimiser step: rsl-rl's
  PPO reduces the actor's and critic's, :func:`all_reduce_gradients` those of
  an extra optimiser (the MCP estimator's); rsl-rl's empirical normalisers
  reduce their own statistics; rank 0's weights are broadcast at the start of
  every ``learn`` — so the models stay identical on every rank;
* only rank 0 writes checkpoints, logs and progress; the per-rank state that a
  resume needs (curriculum, random generator) is gathered to rank 0 and saved
  with its own.

Env steps are counted over all ranks. ``--resume`` needs the same N.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils import reduce_gradients_in_buckets

from frbench.errors import FrbenchError

#: Gradient bucket of the extra optimisers' all-reduce [MB] (rsl-rl's PPO default).
GRAD_BUCKET_MB = 25.0


@dataclass(frozen=True)
class Ranks:
    """This process's place among the training processes (torchrun's environment variables)."""

    rank: int = 0
    local_rank: int = 0
    world_size: int = 1

    @property
    def is_main(self) -> bool:
        """Rank 0: the process that writes checkpoints, logs and progress."""
        return self.rank == 0


def ranks() -> Ranks:
    """`Ranks` from ``RANK``, ``LOCAL_RANK`` and ``WORLD_SIZE`` (one process when unset)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    return Ranks(int(os.environ.get("RANK", "0")), int(os.environ.get("LOCAL_RANK", "0")), world)


def rank_seed(seed: int, rank: int) -> int:
    """The seed of rank ``rank``'s environments and torch generator: ``seed`` for rank 0, an independent
    stream drawn from ``SeedSequence([seed, rank])`` for the others."""
    if rank == 0:
        return seed
    return int(np.random.SeedSequence([seed, rank]).generate_state(1)[0])


def training_device() -> str:
    """Where this rank's models live: ``cuda:LOCAL_RANK`` in a multi-process run on a CUDA machine, else
    ``cpu`` (a single process trains on the CPU, as before)."""
    r = ranks()
    if r.world_size > 1 and torch.cuda.is_available():
        return f"cuda:{r.local_rank}"
    return "cpu"


def init_process_group() -> None:
    """Join the process group (NCCL for a CUDA device, gloo otherwise); nothing for one process."""
    r = ranks()
    if r.world_size <= 1 or dist.is_initialized():
        return
    device = training_device()
    if device.startswith("cuda"):
        torch.cuda.set_device(r.local_rank)
    dist.init_process_group(backend="nccl" if device.startswith("cuda") else "gloo", rank=r.rank,
                            world_size=r.world_size)


def barrier() -> None:
    """Wait for every rank (nothing for one process)."""
    if dist.is_initialized():
        dist.barrier()


def gather_objects(obj) -> list:
    """``obj`` of every rank, in rank order (``[obj]`` for one process); every rank must call it."""
    if not dist.is_initialized():
        return [obj]
    out = [None] * dist.get_world_size()
    dist.all_gather_object(out, obj)
    return out


def all_reduce_gradients(parameters) -> None:
    """Average the gradients of ``parameters`` over the ranks (nothing for one process); call it between
    ``backward()`` and the optimiser's ``step()`` of an optimiser that rsl-rl's PPO does not reduce."""
    if not dist.is_initialized():
        return
    reduce_gradients_in_buckets(list(parameters), dist.get_world_size(), GRAD_BUCKET_MB)


class DistributedRunner(OnPolicyRunner):
    """rsl-rl's `OnPolicyRunner` whose multi-process set-up takes gloo on the CPU as well as NCCL on GPUs.

    The one private method of rsl-rl that frbench overrides, because rsl-rl (5.5.1) offers no public way: its
    runner's constructor calls ``_configure_multi_gpu``, which reads ``WORLD_SIZE`` and, for more than one
    process, requires ``device == f"cuda:{LOCAL_RANK}"`` (a ValueError otherwise) and calls
    ``init_process_group(backend="nccl")`` itself (so a gloo group joined before it fails as a second
    initialisation). Its ``cfg["multi_gpu"]`` key is overwritten there, not read. This override sets what the
    original sets (the ranks, ``is_distributed`` and ``cfg["multi_gpu"]``, which the algorithm's
    ``construct_algorithm`` and the logger read) and joins the group with :func:`init_process_group`; everything
    after it (parameter broadcast, gradient and normaliser reduction, rank-0 logging) is rsl-rl's own.
    """

    def _configure_multi_gpu(self) -> None:
        r = ranks()
        self.gpu_world_size, self.is_distributed = r.world_size, r.world_size > 1
        self.gpu_local_rank, self.gpu_global_rank = r.local_rank, r.rank
        if not self.is_distributed:
            self.cfg["multi_gpu"] = None
            return
        self.cfg["multi_gpu"] = {"global_rank": r.rank, "local_rank": r.local_rank, "world_size": r.world_size}
        init_process_group()


def runner_class() -> type[OnPolicyRunner]:
    """`DistributedRunner` in a multi-process run, rsl-rl's own runner otherwise."""
    return DistributedRunner if ranks().world_size > 1 else OnPolicyRunner


def check_resume_processes(run_processes: int, folder, world: int | None = None) -> None:
    """A run resumes on as many processes as it trained on (each rank restores its own state); ``world``:
    the processes it is resumed on (default: this process's ``WORLD_SIZE``)."""
    world = ranks().world_size if world is None else world
    if run_processes != world:
        raise FrbenchError(f"--resume {folder}: the run trained on {run_processes} process(es); resume it with "
                           f"--nproc {run_processes} (got {world})")


def without_nproc(argv: list[str]) -> list[str]:
    """``argv`` without ``--nproc N`` / ``--nproc=N``."""
    out, skip = [], False
    for item in argv:
        if skip:
            skip = False
        elif item == "--nproc":
            skip = True
        elif not item.startswith("--nproc="):
            out.append(item)
    return out


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


#: Seconds the other ranks get to end on their own once one has failed, before they are stopped.
FAILURE_GRACE_S = 10.0


def launch(nproc: int, argv: list[str], resume=None) -> int:
    """Run ``frbench <argv>`` on ``nproc`` processes of this machine (torchrun's environment variables on
    127.0.0.1); the exit status of the first process that fails, else 0.

    Rank 0 writes to this terminal; the other ranks' output goes to a log that is shown only when one of them
    fails alone (a bad input makes every rank print the same one-line error: rank 0's is enough). When one
    rank fails the others get `FAILURE_GRACE_S` to end on their own (a bad input fails each of them a moment
    apart), then are stopped (they would wait for it forever). ``resume``: the run folder of
    ``--resume``, whose process count is checked before anything starts. Each process gets
    ``cores // nproc`` MuJoCo threads (at least 1) unless ``FRBENCH_MUJOCO_THREADS`` is set."""
    if nproc < 1:
        raise FrbenchError(f"--nproc {nproc}: expected at least 1 process")
    if resume is not None and (Path(resume) / "config.json").is_file():
        processes = json.loads((Path(resume) / "config.json").read_text()).get("processes", 1)
        check_resume_processes(processes, resume, nproc)
    env = dict(os.environ, MASTER_ADDR="127.0.0.1", MASTER_PORT=str(_free_port()), WORLD_SIZE=str(nproc),
               LOCAL_WORLD_SIZE=str(nproc))
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("FRBENCH_MUJOCO_THREADS", str(max(1, (os.cpu_count() or 1) // nproc)))
    command = [sys.executable, "-m", "frbench", *without_nproc(argv)]
    with tempfile.TemporaryFile("w+") as others:
        procs = [subprocess.Popen(command, env={**env, "RANK": str(r), "LOCAL_RANK": str(r)},
                                  stdout=None if r == 0 else others, stderr=None if r == 0 else others)
                 for r in range(nproc)]
        try:
            while all(p.poll() is None or p.returncode == 0 for p in procs) and any(p.poll() is None for p in procs):
                time.sleep(0.2)
        except KeyboardInterrupt:  # the terminal's Ctrl-C reached every rank as well
            for p in procs:
                p.wait()
            raise
        deadline = time.time() + FAILURE_GRACE_S  # a bad input fails every rank: let rank 0 say it too
        while any(p.poll() is None for p in procs) and time.time() < deadline:
            time.sleep(0.2)
        failed = [p for p in procs if p.poll() not in (None, 0)]
        for p in procs:
            if p.poll() is None:
                p.terminate()
            p.wait()
        if failed and procs[0] not in failed:
            others.seek(0)
            sys.stderr.write(others.read()[-4000:])
    return failed[0].returncode if failed else 0


def mean_over_ranks(stats: dict) -> dict:
    """Each key's mean over the ranks' values that are numbers (``stats`` itself for one process); every rank
    must call it. E.g. the episode statistics of a progress row."""
    if not dist.is_initialized():
        return stats
    every = gather_objects(stats)
    out = {}
    for key in every[0]:
        values = [s.get(key) for s in every if isinstance(s.get(key), (int, float))]
        out[key] = float(np.mean(values)) if values else every[0][key]
    return out
