"""Valid synthetic ``frbench evaluate`` results files for the leaderboard tests.

:func:`make_results` builds a results object (schema_version 1) whose cells,
episodes, summary and sim_to_sim agree with each other, for any grid. Success
of each episode comes from ``success(robot, backend, terrain, level, seed,
episode)``; by default a deterministic pseudo-random draw whose probability
falls with the level, so different ``skill`` values give different records.
"""

from __future__ import annotations

import json
import random
import statistics
from pathlib import Path
from typing import Callable, Sequence

from frbench.evaluation.results import sim_to_sim
from frbench.tasks.protocol import (
    PROTOCOL_VERSION,
    STANDARD_LEVELS,
    STANDARD_ROBOTS,
    STANDARD_SEEDS,
    STANDARD_TERRAINS,
    grid_backends,
)

SuccessFn = Callable[[str, str, str, int, int, int], bool]
POSES = ("supine", "side_left", "side_right", "prone")


def _default_success(skill: float, salt: int) -> SuccessFn:
    def success(robot: str, backend: str, terrain: str, level: int, seed: int, episode: int) -> bool:
        rng = random.Random(f"{salt}/{robot}/{backend}/{terrain}/{level}/{seed}/{episode}")
        p = skill * (1.0 - 0.06 * level) - (0.05 if backend == "pybullet" else 0.0)
        return rng.random() < p

    return success


def make_results(
    *,
    robots: Sequence[str] = STANDARD_ROBOTS,
    backends: Sequence[str] | None = None,
    terrains: Sequence[str] = STANDARD_TERRAINS,
    levels: Sequence[int] = STANDARD_LEVELS,
    seeds: Sequence[int] = STANDARD_SEEDS,
    episodes: int = 3,
    policy: str = "scripted",
    skill: float = 0.8,
    salt: int = 0,
    success: SuccessFn | None = None,
    checkpoint: str | None = None,
    unseen: bool | None = None,
    protocol_version: str = PROTOCOL_VERSION,
) -> dict:
    """A complete, self-consistent results object. ``unseen`` (default: when the axes are the standard grid's) adds
    protocol 1.2's unseen grid (`frbench.evaluation.grids`): the results then hold both grids' cells, as
    ``frbench evaluate --grid standard,unseen`` writes them. ``backends`` default to the grid simulators of
    ``protocol_version`` (the current protocol's), which the results carry."""
    grid_simulators = grid_backends(protocol_version)
    backends = grid_simulators if backends is None else backends
    standard = (tuple(robots), tuple(backends), tuple(terrains), tuple(levels), tuple(seeds)) == (
        STANDARD_ROBOTS, grid_simulators, STANDARD_TERRAINS, STANDARD_LEVELS, STANDARD_SEEDS)
    if unseen if unseen is not None else standard:
        return _with_unseen_grid(make_results(robots=robots, backends=backends, terrains=terrains, levels=levels,
                                              seeds=seeds, episodes=episodes, policy=policy, skill=skill, salt=salt,
                                              success=success, checkpoint=checkpoint, unseen=False,
                                              protocol_version=protocol_version), standard, skill)
    success = success or _default_success(skill, salt)
    cells, records = [], []
    for robot in robots:
        for backend in backends:
            for terrain in terrains:
                for level in levels:
                    for seed in seeds:
                        eps = []
                        for episode in range(episodes):
                            rng = random.Random(f"metrics/{salt}/{robot}/{backend}/{terrain}/{level}/{seed}/{episode}")
                            ok = bool(success(robot, backend, terrain, level, seed, episode))
                            eps.append({
                                "robot": robot, "backend": backend, "terrain": terrain, "level": level, "seed": seed,
                                "episode": episode, "initial_pose": POSES[episode % len(POSES)], "success": ok,
                                "time_to_recover": round(rng.uniform(0.8, 4.0), 3) if ok else None,
                                "final_displacement": round(rng.uniform(0.0, 0.6), 4),
                                "max_displacement": round(rng.uniform(0.6, 1.2), 4),
                                "energy": round(rng.uniform(50.0, 400.0), 2),
                                "smoothness": round(rng.uniform(0.0, 0.05), 5),
                                "peak_contact_force": round(rng.uniform(100.0, 900.0), 1),
                                "rolled_over": rng.random() < 0.2,
                                "diverged": False,
                            })
                        successes = sum(e["success"] for e in eps)
                        times = [e["time_to_recover"] for e in eps if e["time_to_recover"] is not None]
                        cells.append({
                            "robot": robot, "backend": backend, "terrain": terrain, "level": level, "seed": seed,
                            "episodes": episodes, "successes": successes, "success_rate": successes / episodes,
                            "mean_time_to_recover": sum(times) / len(times) if times else None,
                            "mean_final_displacement": sum(e["final_displacement"] for e in eps) / episodes,
                            "mean_max_displacement": sum(e["max_displacement"] for e in eps) / episodes,
                            "mean_energy": sum(e["energy"] for e in eps) / episodes,
                            "mean_smoothness": sum(e["smoothness"] for e in eps) / episodes,
                            "mean_peak_contact_force": sum(e["peak_contact_force"] for e in eps) / episodes,
                            "rollover_rate": sum(e["rolled_over"] for e in eps) / episodes,
                            "diverged": 0,
                        })
                        records.extend(eps)
    summary = []
    for robot in robots:
        for backend in backends:
            for terrain in terrains:
                for level in levels:
                    rates = [c["success_rate"] for c in cells
                             if (c["robot"], c["backend"], c["terrain"], c["level"]) == (robot, backend, terrain, level)]
                    summary.append({
                        "robot": robot, "backend": backend, "terrain": terrain, "level": level,
                        "success_rate_mean": sum(rates) / len(rates),
                        "success_rate_std": statistics.pstdev(rates),
                        "n_seeds": len(rates),
                    })
    return {
        "schema_version": 1,
        "protocol_version": protocol_version,
        "frbench": {"version": "0.1.0", "git_commit": "0123456789abcdef0123456789abcdef01234567", "git_dirty": False},
        "versions": {"python": "3.11.7", "mujoco": "4.0.0", "pybullet": "3.2.7", "pinocchio": "4.1.0",
                     "numpy": "2.4.6", "torch": "2.13.0+cpu"},
        "created": "2026-11-22T01:23:45Z",
        "policy": {"name": policy, "checkpoint": checkpoint,
                   "sha256": None if checkpoint is None else "ab" * 32},
        "config": {"policy": policy, "robots": list(robots), "backends": list(backends), "terrains": list(terrains),
                   "levels": list(levels), "seeds": list(seeds), "episodes": episodes, "noise": False},
        "robots": {r: {"urdf_sha256": f"{i:02x}" * 32, "sim_urdf_sha256": f"{i + 16:02x}" * 32, "source": "example-robot-data 6.0.0"}
                   for i, r in enumerate(robots)},
        "cells": cells,
        "episodes": records,
        "summary": summary,
        "sim_to_sim": sim_to_sim(summary),  # each grid simulator's mean and each pair's gap
    }


def _with_unseen_grid(results: dict, named: bool = True, skill: float = 0.8) -> dict:
    """``results`` extended by the unseen grid's quadruped cells (same policy); ``named``: ``results`` are the
    standard grid's, so the config names both grids (else it only lists the robots, as a custom grid would)."""
    from frbench.evaluation.grids import unseen_part

    version = results["protocol_version"]
    part = unseen_part(version=version)
    config = results["config"]
    extra = make_results(robots=part.robots, backends=part.backends, terrains=part.terrains, levels=part.levels,
                         seeds=part.seeds, episodes=config["episodes"], policy=config["policy"],
                         skill=skill, salt=hash_salt(results), unseen=False, protocol_version=version)
    merged = dict(results)
    for key in ("cells", "episodes", "summary", "sim_to_sim"):
        merged[key] = results[key] + extra[key]
    offset = len(results["robots"])
    merged["robots"] = {**results["robots"], **{r: {**v, "urdf_sha256": f"{i + offset:02x}" * 32,
                                                    "sim_urdf_sha256": f"{i + offset + 64:02x}" * 32}
                                                for i, (r, v) in enumerate(extra["robots"].items())}}
    merged["config"] = {**config, "robots": config["robots"] + list(part.robots),
                        "terrains": config["terrains"], "levels": config["levels"]}
    if named:
        merged["config"]["grid"] = ["standard", "unseen"]
        merged["config"]["not_scored"] = {r: "the policy does not drive this robot (unseen grid: scored n/a, not 0)"
                                          for r in ("icub", "talos")}
    return merged


def hash_salt(results: dict) -> int:
    """A salt for the unseen cells that differs between records made with different salts."""
    return sum(c["successes"] * (i + 1) for i, c in enumerate(results["cells"][:50]))


#: Episodes succeeding out of 4 per (backend, terrain, level) in :func:`small_results` (seed-independent).
SMALL_SUCCESSES = {
    ("mujoco", "flat", 1): 4, ("mujoco", "flat", 5): 3, ("mujoco", "stairs", 1): 2, ("mujoco", "stairs", 5): 1,
    ("pybullet", "flat", 1): 3, ("pybullet", "flat", 5): 3, ("pybullet", "stairs", 1): 2, ("pybullet", "stairs", 5): 0,
}


def small_results(**overrides) -> dict:
    """A partial-track results object with hand-checkable scores.

    go2 on flat and stairs, levels 1 and 5, seeds 0 and 1, 4 episodes per cell,
    both backends. Success rates per (backend, terrain, level): mujoco 1, .75,
    .5, .25; pybullet .75, .75, .5, 0. Hence overall 0.5625, flat 0.8125,
    stairs 0.3125, mujoco 0.625, pybullet 0.5, sim-to-sim gap 0.125.
    """
    args = dict(
        robots=("go2",), backends=("mujoco", "pybullet"), terrains=("flat", "stairs"), levels=(1, 5), seeds=(0, 1),
        episodes=4,
        success=lambda robot, backend, terrain, level, seed, episode: episode < SMALL_SUCCESSES[(backend, terrain, level)],
    )
    args.update(overrides)
    return make_results(**args)


def write_results(path: Path, results: dict) -> Path:
    """Write ``results`` as JSON (NaN allowed, so tests can write bad files too)."""
    path = Path(path)
    path.write_text(json.dumps(results, indent=1), encoding="utf-8")
    return path


def empty_board_copy(source, dest):
    """A copy of the leaderboard folder ``source`` at ``dest`` with no records (nor their policy files), its pages
    regenerated."""
    import shutil

    from frbench.leaderboard import regenerate

    shutil.copytree(source, dest, ignore=shutil.ignore_patterns("policies"))
    for record in (dest / "records").glob("*.json*"):
        record.unlink()
    regenerate(dest)
    return dest
