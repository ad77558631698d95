"""The evaluation grid: validate the request, run its cells in parallel processes, build the results.

Cells run in a local process pool (``executor="local"``: one MuJoCo thread per
worker, so two workers use two cores) or as Ray tasks on this machine or a
cluster (``executor="ray"``, `frbench.evaluation.ray_executor`); a progress bar
counts cells. Results are deterministic: the same policy, grid and protocol
give the same numbers whatever the executor and worker count.
"""

from __future__ import annotations

import datetime as _dt
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

from frbench.backends import BACKENDS, simulator_refusal
from frbench.backends.simulators import DEVICE_SIMULATORS
from frbench.errors import FrbenchError, unknown_name
from frbench.evaluation.provenance import frbench_info, library_versions, processor_info
from frbench.evaluation.results import aggregate_cells, sim_to_sim, summarize
from frbench.evaluation.runner import Cell, run_cell
from frbench.interrupts import children_ignore_sigint, terminate_pool
from frbench.io import sha256_file
from frbench.policies.registry import load_policy
from frbench.robots import get_robot
from frbench.robots.sim_urdf import sim_robot_file
from frbench.tasks.protocol import KNOWN_PROTOCOL_VERSIONS, PROTOCOL_VERSION, RESULTS_SCHEMA_VERSION, STANDARD_BACKENDS
from frbench.terrains import FAMILIES


#: Where the cells run: a local process pool, or Ray tasks (`frbench.evaluation.ray_executor`).
EXECUTORS = ("local", "ray")


@dataclass
class EvaluationRequest:
    """What ``frbench evaluate`` was asked to run (the resolved config of the results)."""

    policy: str = "scripted"
    robots: list[str] = field(default_factory=lambda: ["go2"])
    #: The simulators: by default the current protocol's grid simulators (MuJoCo, PyBullet and PhysX from 1.3 on).
    backends: list[str] = field(default_factory=lambda: list(STANDARD_BACKENDS))
    terrains: list[str] = field(default_factory=lambda: ["flat", "rough", "slopes", "stairs", "stones", "gaps", "beams"])
    levels: list[int] = field(default_factory=lambda: [1, 5, 10])
    seeds: list[int] = field(default_factory=lambda: [0, 1])
    episodes: int = 8
    noise: bool = False
    jobs: int = 0
    executor: str = "local"
    address: str | None = None
    #: Named grids (`frbench.evaluation.grids`: ``standard``, ``unseen``); empty: the product of the fields above.
    grid: list[str] = field(default_factory=list)
    #: Robots of the named grids the policy cannot drive: name -> why (scored "n/a"); set by `apply_grids`.
    not_scored: dict[str, str] = field(default_factory=dict)
    #: The named grids' cell keys (robot, backend, terrain, level, seed); set by `apply_grids`.
    cell_keys: list[tuple] | None = None
    #: Robots a simulator cannot take: backend -> robot -> why (their cells do not run); set by `validate`.
    refused: dict[str, dict[str, str]] = field(default_factory=dict)
    #: Where a device simulator (``mujoco-warp``) runs (`frbench.backends.devices.parse_device`'s value); the CPU
    #: simulators run on ``cpu``. Recorded in the results' config when it is not ``cpu``.
    device: str = "cpu"
    #: The protocol whose named grids `grid` means and whose number the results carry: the current one (a re-score
    #: tool makes another known version's records, e.g. tools/rescore_physx.py protocol 1.3's).
    protocol_version: str = PROTOCOL_VERSION

    def cells(self) -> list[Cell]:
        """Every cell of the grid that runs (none of `refused`), in a fixed order."""
        if self.cell_keys is not None:
            cells = [Cell(*key, self.episodes) for key in self.cell_keys]
        else:
            cells = [
                Cell(robot, backend, terrain, level, seed, self.episodes)
                for robot in self.robots for backend in self.backends for terrain in self.terrains
                for level in self.levels for seed in self.seeds
            ]
        return [cell for cell in cells if cell.robot not in self.refused.get(cell.backend, {})]


def apply_grids(request: EvaluationRequest, policy) -> None:
    """Set the request's robots, axes, episodes and cells from its named grids for ``policy`` (the robots it
    cannot drive go to ``not_scored``); nothing when it names none."""
    if not request.grid:
        return
    from frbench.evaluation.grids import resolve_grids

    resolved = resolve_grids(request.grid, lambda name: policy.supports(get_robot(name)), request.protocol_version)
    axes = resolved.axes
    request.robots, request.backends, request.terrains = list(axes.robots), list(axes.backends), list(axes.terrains)
    request.levels, request.seeds, request.episodes = list(axes.levels), list(axes.seeds), axes.episodes
    request.not_scored, request.cell_keys = dict(resolved.not_scored), list(resolved.keys)


def validate(request: EvaluationRequest):
    """Resolve and check every name and number before anything runs; returns the policy."""
    if request.executor not in EXECUTORS:
        raise unknown_name("executor", request.executor, EXECUTORS)
    if request.protocol_version not in KNOWN_PROTOCOL_VERSIONS:
        raise unknown_name("protocol version", request.protocol_version, KNOWN_PROTOCOL_VERSIONS)

    for backend in request.backends:
        if backend not in BACKENDS:
            raise unknown_name("backend", backend, BACKENDS)
    if request.device != "cpu" and not set(request.backends) & set(DEVICE_SIMULATORS):
        raise FrbenchError(f"--device {request.device}: none of the backends ({', '.join(request.backends)}) runs on "
                           f"a device; that is {', '.join(DEVICE_SIMULATORS)}")
    for terrain in request.terrains:
        if terrain not in FAMILIES:
            raise unknown_name("terrain", terrain, FAMILIES)
    for level in request.levels:
        if not 1 <= level <= 10:
            raise FrbenchError(f"level {level} is out of range: levels are 1 to 10")
    if request.episodes < 1:
        raise FrbenchError(f"--episodes {request.episodes}: expected at least 1")
    if not request.seeds:
        raise FrbenchError("--seeds is empty: expected at least one seed")
    policy = load_policy(request.policy)
    apply_grids(request, policy)
    for robot in request.robots:
        spec = get_robot(robot)
        if not policy.supports(spec):
            raise FrbenchError(f"policy {policy.name!r} does not support robot {spec.name!r} ({spec.kind})")
        for backend in request.backends:
            reason = simulator_refusal(backend, spec)
            if reason:
                request.refused.setdefault(backend, {})[robot] = reason
    if request.refused and not request.cells():
        raise FrbenchError("no cell of the grid can run: " + "; ".join(
            f"{backend}: {reason}" for backend, robots in request.refused.items() for reason in robots.values()))
    return policy


#: Request fields that say how the grid ran, not what it measured: left out of the results' config
#: (``protocol_version`` is the results' own field).
RUN_ONLY_FIELDS = ("jobs", "executor", "address", "cell_keys", "protocol_version")
#: Fields recorded only when the request names grids (a custom grid's config stays as before 1.2).
GRID_FIELDS = ("grid", "not_scored")


def _worker_init() -> None:
    os.environ["FRBENCH_MUJOCO_THREADS"] = "1"
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


def run_grid(request: EvaluationRequest, progress=None) -> list[dict]:
    """Run every cell; returns the episode records sorted by cell and episode."""
    cells = request.cells()
    jobs = request.jobs or min(len(cells), os.cpu_count() or 1)
    records: list[dict] = []
    if request.executor == "ray":
        from frbench.evaluation.ray_executor import run_cells_on_ray

        records = run_cells_on_ray(cells, request.policy, request.noise, progress, request.address, request.jobs,
                                   request.device, request.protocol_version)
    elif jobs <= 1:
        for cell in cells:
            records += run_cell(cell, request.policy, request.noise, device=request.device,
                                protocol_version=request.protocol_version)
            if progress:
                progress(cell)
    else:
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_worker_init) as pool:
            try:
                with children_ignore_sigint():  # the workers start (at submit) ignoring Ctrl-C
                    futures = {pool.submit(run_cell, cell, request.policy, request.noise, device=request.device,
                                           protocol_version=request.protocol_version): cell
                               for cell in cells}
                for future in as_completed(futures):
                    records += future.result()
                    if progress:
                        progress(futures[future])
            except KeyboardInterrupt:
                terminate_pool(pool)
                raise
    records.sort(key=lambda r: (r["robot"], r["backend"], r["terrain"], r["level"], r["seed"], r["episode"]))
    return records


def build_results(request: EvaluationRequest, policy, episodes: list[dict], code: dict | None = None) -> dict:
    """The results document (see `frbench.evaluation.results`).

    ``code``: `frbench_info()` taken when the episodes started (None: now); a long evaluation records the
    commit it ran, not one made while it ran.
    """
    robots = {}
    for name in request.robots:
        spec = get_robot(name)
        sim = sim_robot_file(spec)
        robots[spec.name] = {"urdf_sha256": sim.source_sha256, "sim_urdf_sha256": sim.sha256, "source": spec.source}
    checkpoint = getattr(policy, "checkpoint", None)
    cells = aggregate_cells(episodes)
    summary = summarize(cells)
    config = {k: v for k, v in request.__dict__.items()
              if k not in RUN_ONLY_FIELDS and (request.grid or k not in GRID_FIELDS) and (v or k != "refused")
              and (k != "device" or v != "cpu")}
    return {
        "schema_version": RESULTS_SCHEMA_VERSION,
        "protocol_version": request.protocol_version,
        "frbench": code or frbench_info(),
        "versions": library_versions(),
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "processor": processor_info(),
        "policy": {
            "name": policy.name,
            "checkpoint": str(checkpoint) if checkpoint else None,
            "sha256": sha256_file(checkpoint) if checkpoint else None,
            **({"inputs": policy.inputs} if getattr(policy, "inputs", None) else {}),
            **({"joint_frame": "canonical"} if getattr(policy, "joint_frame", "robot") == "canonical" else {}),
        },
        "config": config,
        "robots": robots,
        "cells": cells,
        "episodes": episodes,
        "summary": summary,
        "sim_to_sim": sim_to_sim(summary),
    }
