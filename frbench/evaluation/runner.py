"""Run one cell of the evaluation grid: one robot, backend, terrain, level and seed.

All episodes of a cell run side by side in one batched backend. The policy is
loaded once per worker process. Each episode becomes a plain dict (the
per-episode records of the results JSON).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from frbench.backends.simulators import DEVICE_SIMULATORS
from frbench.evaluation.episodes import run_episodes
from frbench.policies.registry import load_policy
from frbench.robot_checks.lookup import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.tasks.protocol import PROTOCOL_VERSION
from frbench.terrains import make_terrain


@dataclass(frozen=True)
class Cell:
    """One unit of work: ``episodes`` episodes of (robot, backend, terrain, level, seed)."""

    robot: str
    backend: str
    terrain: str
    level: int
    seed: int
    episodes: int

    def key(self) -> tuple:
        """Sort key and identity."""
        return (self.robot, self.backend, self.terrain, self.level, self.seed)


@lru_cache(maxsize=4)
def _policy(reference: str):
    return load_policy(reference)


def _none_if_nan(value: float) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def _one_torch_thread() -> None:
    """Cells run in parallel processes: a torch policy gets one thread each. With torch's default (all
    cores) a 256-128-128 MLP on 8 rows took 10 ms per layer under load instead of tens of µs."""
    import sys

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def run_cell(cell: Cell, policy_reference: str, noise: bool = False, joint_frame: str | None = None,
             device: str | None = None, protocol_version: str = PROTOCOL_VERSION) -> list[dict]:
    """Run the cell's episodes with the policy (`run_episodes`); one record per episode. ``joint_frame``
    (``robot`` / ``canonical``) overrides the frame the policy declares: `frbench verify` re-runs a record in
    the frame its results name (absent: ``robot``). ``device``: where a device simulator runs (None: ``cpu``).
    ``protocol_version``: the protocol whose starts the cell draws (its joint-redraw rule, `draw_starts`)."""
    spec = get_robot(cell.robot)
    policy = _policy(policy_reference)
    _one_torch_thread()
    terrain = make_terrain(cell.terrain, cell.level, cell.seed)
    starts = draw_starts(spec, terrain, cell.terrain, cell.level, cell.seed, range(cell.episodes),
                         rule=protocol_version)
    noise_rng = np.random.default_rng([cell.seed, cell.level, 7]) if noise else None
    task = run_episodes(spec, cell.backend, terrain, starts, policy, seed=cell.seed, noise_rng=noise_rng,
                        joint_frame=joint_frame, device=device if cell.backend in DEVICE_SIMULATORS else None)
    success, metrics = task.success, task.metrics
    diverged = metrics.diverged | task.settle_diverged
    base = {k: v for k, v in asdict(cell).items() if k != "episodes"}
    records = []
    for i in range(cell.episodes):
        records.append(
            {
                **base,
                "episode": i,
                "initial_pose": starts.kinds[i],
                "start_redraws": int(starts.attempts[i]),
                "success": bool(success.success[i] and not diverged[i]),
                "time_to_recover": _none_if_nan(success.time_to_recover[i]) if success.success[i] else None,
                "final_displacement": float(metrics.final_displacement[i]),
                "max_displacement": float(metrics.max_displacement[i]),
                "energy": float(metrics.energy[i]),
                "smoothness": float(metrics.smoothness[i]),
                "peak_contact_force": float(metrics.peak_contact_force[i]),
                "rolled_over": bool(metrics.rolled_over[i]),
                "diverged": bool(diverged[i]),
            }
        )
    return records
