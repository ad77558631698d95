"""Which starts of the protocol's grids begin with links inside each other, per robot (no physics stepping).

Every (robot, terrain, level, seed) cell of the current protocol's grids (standard, unseen with its
humanoid set, humanoid; `frbench.evaluation.grids`) is drawn as ``frbench evaluate`` draws it
(`draw_starts`: the starts do not depend on the simulator), every episode, and with ``--attempts K`` also
the screening's redraws 1 … K of every episode (`frbench.tasks.start_screening` redraws a start that
settles upright with attempt 1, 2, …, at most 8: the default covers every start any screening can reach,
without running the settle). For each robot it prints:

* ``starts``: drawn starts (cells x episodes x (attempts + 1));
* ``overlapping``: starts whose kept joint angles overlap (`self_intersects`; `draw_start` tests up to
  `MAX_REDRAWS` draws and, when all overlap, keeps the next draw untested), plus the starts whose draw
  raised a `FrbenchError` (``raised``);
* ``joint draws``: the mean and largest number of joint draws a start tested (1: the first was free; 50 under
  `MAX_REDRAWS` = 50 also counts the starts that exhausted it);
* ``sha256``: a digest of every drawn start of the robot in order (base position, quaternion, joint angles,
  fall kind): equal digests mean bit-identical starts.

``--max-redraws N`` sets `frbench.tasks.initial_states.MAX_REDRAWS` for the run (e.g. 2000, to measure a
larger budget); ``--protocol V`` draws with protocol V's joint-redraw rule instead (`joint_redraws`: 1.4 redraws
until free, at most `MAX_FREE_REDRAWS` times, and a start beyond it is counted in ``raised``); ``--json PATH`` writes the table, ``--compare PATH`` prints,
per robot, whether its digest equals the one in an earlier ``--json``.

Run: ``python tools/start_overlap_audit.py`` (about 30 s on one core);
``--max-redraws 50 --json /tmp/old.json``, then ``--compare /tmp/old.json``; ``--robots icub,talos --attempts 0``;
``--protocol 1.3 --attempts 0 --json /tmp/13.json``, then ``--protocol 1.4 --attempts 0 --compare /tmp/13.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time

import numpy as np

from frbench.backends.self_collision import self_intersects
from frbench.errors import FrbenchError
from frbench.evaluation.grids import GRID_NAMES, grid_parts
from frbench.robots.registry import get_robot
from frbench.tasks import initial_states
from frbench.tasks.initial_states import draw_start, episode_rng, joint_redraws
from frbench.tasks.start_screening import MAX_SCREEN_ROUNDS
from frbench.terrains import make_terrain


def grid_cells() -> dict[str, list[tuple[str, int, int, int]]]:
    """robot -> its (terrain, level, seed, episodes) cells in the current protocol's grids (simulators merged)."""
    cells: dict[str, dict] = {}
    for name in GRID_NAMES:
        for part in grid_parts(name):
            for robot, _backend, terrain, level, seed in part.keys():
                cells.setdefault(robot, {})[(terrain, level, seed)] = part.episodes
    return {robot: [(*key, n) for key, n in by_cell.items()] for robot, by_cell in cells.items()}


def start_digest(pos: np.ndarray, quat: np.ndarray, q: np.ndarray, kind: str) -> bytes:
    """The bytes of one drawn start (float64 arrays and the kind's name)."""
    return b"".join(np.ascontiguousarray(a, dtype=np.float64).tobytes() for a in (pos, quat, q)) + kind.encode()


def audit_robot(robot: str, cells, attempts: int, redraws=None) -> dict:
    """Draw every start of ``robot``'s ``cells`` (attempts 0 … ``attempts``) with the joint-redraw rule
    ``redraws`` (None: `MAX_REDRAWS`, keeping the last draw) and count overlaps and draws."""
    spec = get_robot(robot)
    draws = [0]

    def counting(spec_, q):
        draws[0] += 1
        return self_intersects(spec_, q)

    digest = hashlib.sha256()
    per_start, overlapping, failures = [], [], []
    original = initial_states.self_intersects
    initial_states.self_intersects = counting
    try:
        for terrain_name, level, seed, episodes in cells:
            terrain = make_terrain(terrain_name, level, seed)
            for episode in range(episodes):
                for attempt in range(attempts + 1):
                    draws[0] = 0
                    rng = episode_rng(robot, terrain_name, level, seed, episode, attempt=attempt)
                    where = f"{robot} {terrain_name} level {level} seed {seed} episode {episode} attempt {attempt}"
                    try:
                        pos, quat, q, kind = draw_start(spec, terrain, rng, redraws)
                    except FrbenchError:
                        failures.append(where)
                        continue
                    per_start.append(draws[0])
                    digest.update(start_digest(pos, quat, q, kind))
                    if self_intersects(spec, q):
                        overlapping.append(where)
    finally:
        initial_states.self_intersects = original
    return {"starts": len(per_start) + len(failures), "overlapping": len(overlapping) + len(failures),
            "raised": len(failures), "mean_draws": float(np.mean(per_start)) if per_start else float("nan"),
            "max_draws": int(max(per_start, default=0)), "sha256": digest.hexdigest(),
            "overlapping_starts": overlapping[:5] + failures[:5]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=None, help="comma-separated robots (default: every robot of the grids)")
    parser.add_argument("--attempts", type=int, default=MAX_SCREEN_ROUNDS,
                        help=f"screening redraws per episode to draw as well (default {MAX_SCREEN_ROUNDS})")
    parser.add_argument("--max-redraws", type=int, default=None, help="MAX_REDRAWS for this run")
    parser.add_argument("--protocol", default=None, help="draw with this protocol's joint-redraw rule")
    parser.add_argument("--json", default=None, help="write the per-robot table here")
    parser.add_argument("--compare", default=None, help="a --json of an earlier run: compare digests")
    args = parser.parse_args()
    if args.max_redraws is not None:
        initial_states.MAX_REDRAWS = args.max_redraws
    cells = grid_cells()
    robots = args.robots.split(",") if args.robots else list(cells)
    earlier = json.load(open(args.compare))["robots"] if args.compare else {}
    redraws = joint_redraws(args.protocol) if args.protocol else None
    rule = (f"protocol {args.protocol}: {redraws.limit} redraws" + (", until free" if redraws.free else "")
            if redraws else f"MAX_REDRAWS = {initial_states.MAX_REDRAWS}")
    print(f"{rule}, attempts 0-{args.attempts} per episode")
    print(f"{'robot':<12} {'cells':>5} {'starts':>6} {'overlapping':>11} {'raised':>6} {'joint draws mean/max':>21}"
          f"  sha256[:16]{'  same as --compare' if earlier else ''}")
    table = {}
    began = time.perf_counter()
    for robot in robots:
        row = audit_robot(robot, cells[robot], args.attempts, redraws)
        row["cells"] = len(cells[robot])
        table[robot] = row
        same = ""
        if earlier:
            same = "  " + ("yes" if earlier.get(robot, {}).get("sha256") == row["sha256"] else "NO")
        print(f"{robot:<12} {row['cells']:>5} {row['starts']:>6} {row['overlapping']:>11} {row['raised']:>6} "
              f"{row['mean_draws']:>14.1f} / {row['max_draws']:<4}  {row['sha256'][:16]}{same}", flush=True)
        for where in row["overlapping_starts"]:
            print(f"    overlapping: {where}")
    print(f"({time.perf_counter() - began:.0f} s)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"max_redraws": redraws.limit if redraws else initial_states.MAX_REDRAWS, "attempts": args.attempts, "robots": table}, f,
                      indent=1)


if __name__ == "__main__":
    main()
