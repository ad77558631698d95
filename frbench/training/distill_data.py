"""The distillation dataset: what the student observes, and the per-episode shards a run folder keeps.

The student observes exactly what a `frbench.policies.learned.LearnedPolicy` with an MLP actor on the
groups ``policy`` and ``history`` does (no simulator state):

* ``policy``: o_t = [ω, g, q − q̊, q̇, a_{t−1}] (6 + 3J) from `frbench.tasks.observations.flatten`, with
  a_{t−1} the previous action (joint targets − q̊ [rad], action scale 1; zeros at t = 0);
* ``history``: the last ``frames`` o_t, the current one included (frames · (6 + 3J)), filled with the
  episode's first o_t at its start.

A shard is one episode: ``<run>/data/round<r>/batch<b>-ep<i>.npz`` with ``obs`` (T, 6 + 3J) the o_t,
``history`` (T, frames·(6 + 3J)), ``actions`` (T, J) the teacher's labels q*_teacher − q̊ [rad] and
``meta`` (a JSON text: round, batch, episode, simulator, start kind, who acted, success, CPU seconds).
Shards are written whole (temporary file, then rename), so a killed run leaves none half-written.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from frbench.io import atomic_write_bytes
from frbench.tasks.observations import flatten


class ObservationHistory:
    """The student's inputs for N episodes, kept as `LearnedPolicy` keeps them (module docstring)."""

    def __init__(self, default_pose: np.ndarray, num_envs: int, frames: int):
        self.default_pose = np.asarray(default_pose, dtype=float)
        self.frames = int(frames)
        self.previous = np.zeros((num_envs, len(self.default_pose)))
        self.history: np.ndarray | None = None

    def observe(self, obs: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(o_t (N, 6 + 3J), history (N, frames·(6 + 3J))) of this step's observation dict."""
        o_t = flatten(obs, self.default_pose)
        o_t[:, -self.previous.shape[1]:] = self.previous
        if self.history is None:
            self.history = np.repeat(o_t[:, None, :], self.frames, axis=1)
        else:
            self.history = np.concatenate([self.history[:, 1:], o_t[:, None, :]], axis=1)
        return o_t, self.history.reshape(len(o_t), -1).copy()

    def acted(self, action: np.ndarray) -> None:
        """Record the action a (N, J) = q* − q̊ [rad] executed at this step (the next o_t's a_{t−1})."""
        self.previous = np.clip(np.asarray(action, dtype=float), -10.0, 10.0)


def shard_path(run: Path, round_index: int, batch: int, episode: int) -> Path:
    """Where one episode's shard lives in the run folder ``run``."""
    return Path(run) / "data" / f"round{round_index}" / f"batch{batch:04d}-ep{episode}.npz"


def write_shard(path: Path, obs: np.ndarray, history: np.ndarray, actions: np.ndarray, meta: dict) -> None:
    """Write one episode's shard atomically (float32 arrays; ``meta`` as JSON)."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, obs=obs.astype(np.float32), history=history.astype(np.float32),
                        actions=actions.astype(np.float32), meta=np.array(json.dumps(meta, sort_keys=True)))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buffer.getvalue())


def read_meta(path: Path) -> dict:
    """The ``meta`` dict of a shard."""
    with np.load(path) as data:
        return json.loads(str(data["meta"]))


def load_rounds(run: Path, last_round: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
    """All shards of rounds 0..``last_round`` in file order: (obs (M, F), history (M, H·F), actions (M, J), metas)."""
    obs, history, actions, metas = [], [], [], []
    for r in range(last_round + 1):
        for path in sorted((Path(run) / "data" / f"round{r}").glob("*.npz")):
            with np.load(path) as data:
                obs.append(data["obs"])
                history.append(data["history"])
                actions.append(data["actions"])
                metas.append(json.loads(str(data["meta"])))
    if not obs:
        raise ValueError(f"{run}: no dataset shards in rounds 0-{last_round}")
    return np.concatenate(obs), np.concatenate(history), np.concatenate(actions), metas
