"""Record where the G1 key frames reach the crouch, as starts for ``keyframe_search --stage rise``.

Runs `KeyframeHumanoidPolicy` (``--params``, default the shipped file) on g1 / flat / level-1 starts of
``--seeds`` in one backend, for the task's whole episode, and saves every environment's state at the
control step its residual gate first opened (the controller entered ``CROUCH``), with the controller's
targets then and the seed and step, to an ``.npz``. States with the pelvis below ``--min-height`` (the
crouch entered while still lying: the squat ended on the ground) are left out. Example (the rise search's
training states; seeds 0-3 are the evaluation grid's and 16-23 the held-out check's)::

    python -m tools.keyframe_states --backend mujoco --seeds 4-15,24-63 --out crouch_train.npz
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import numpy as np

#: `RobotState` fields stored per recorded state.
STATE_FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")
#: Pelvis heights [m] above flat ground below this at the crouch are not rise starts (still lying).
MIN_CROUCH_HEIGHT = 0.3


def parse_seeds(text: str) -> list[int]:
    """``"4-15,24"`` → [4, 5, …, 15, 24]."""
    seeds: list[int] = []
    for item in filter(None, text.split(",")):
        low, _, high = item.partition("-")
        seeds += range(int(low), int(high or low) + 1)
    return seeds


def record_crouch_states(backend: str, seeds, params: str | None = None, episodes: int = 8,
                         min_height: float = MIN_CROUCH_HEIGHT) -> dict[str, np.ndarray]:
    """Crouch-entry states of the key frames from g1/flat/level-1 ``seeds`` × ``episodes``: arrays by field,
    one row per state (`STATE_FIELDS` plus ``targets`` (J,) [rad], ``seed``, ``step`` [control steps])."""
    from frbench.evaluation.episodes import run_episodes
    from frbench.policies.keyframe_humanoid import (
        KeyframeHumanoidPolicy,
        load_parameters,
    )
    from frbench.robots import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.terrains import make_terrain

    spec = get_robot("g1")
    rows: dict[str, list] = {k: [] for k in (*STATE_FIELDS, "targets", "seed", "step")}
    for seed in seeds:
        terrain = make_terrain("flat", 1, seed)
        policy = KeyframeHumanoidPolicy(None if params is None else load_parameters(params))
        opened = np.zeros(episodes, dtype=bool)

        def record(task, _targets):
            nonlocal opened
            step = task.t - 1
            new = (policy.residual_gate() > 0) & ~opened & task.alive
            for i in np.flatnonzero(new & (task.state.base_pos[:, 2] >= min_height)):
                for field in STATE_FIELDS:
                    rows[field].append(getattr(task.state, field)[i].copy())
                rows["targets"].append(policy.target[i].copy())
                rows["seed"].append(seed)
                rows["step"].append(step)
            opened |= new

        run_episodes(spec, backend, terrain, draw_starts(spec, terrain, "flat", 1, seed, range(episodes)), policy,
                     seed=seed, on_step=record, check=False)
    if not rows["q"]:
        raise ValueError(f"no key-frame episode of seeds {list(seeds)} ({backend}) reached the crouch")
    return {k: np.array(v) for k, v in rows.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", default="mujoco", choices=("mujoco", "pybullet"))
    parser.add_argument("--seeds", required=True, help="g1/flat/level-1 seeds, e.g. 4-15,24-63")
    parser.add_argument("--params", default=None, help="keyframe-humanoid parameter JSON (default: shipped)")
    parser.add_argument("--min-height", type=float, default=MIN_CROUCH_HEIGHT)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    from frbench.io import atomic_write_bytes

    states = record_crouch_states(args.backend, parse_seeds(args.seeds), args.params, min_height=args.min_height)
    buffer = io.BytesIO()
    np.savez(buffer, **states)
    atomic_write_bytes(Path(args.out), buffer.getvalue())
    print(f"{len(states['q'])} crouch states → {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
