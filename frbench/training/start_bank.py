"""Bank starts: each episode begins from a settled fallen start recorded before training, not a fresh settle.

A fresh start (`frbench.training.start_sources.CurriculumStarts`) costs, every episode, the protocol's draw on
the host (one Python call per environment) and a settle of ``settle_steps`` control steps in the simulator; on a
GPU, whose control steps are cheap, that would be a large share of an episode. With ``TrainEnvConfig.start_bank``
= S > 0 the training env records S settled starts of every (terrain tile, robot variant) cell once
(`record_bank`: the protocol's draw moved to the tile, settled for ``settle_steps`` and screened by the episode
engine in MuJoCo C, at most `BANK_BATCH` simulations at a time) and every new episode of environment i begins at
a bank entry of its cell, (tile of its curriculum level, its robot variant), drawn from the env's generator,
without a settle (`frbench.tasks.core_env.CoreEnv.begin_recorded`: the velocities as recorded, the episode's
physics set, t = 0 there). A cell without entries borrows the entries of its tile's other variants.

This is the one piece of orchestration the device needs beyond the training env's own (its reason is the cost
of host work per episode): what the env computes during an episode is the same whatever the start source.
Shapes: N environments, K variants, T tiles, M bank entries, J joints.
"""

from __future__ import annotations

import numpy as np

from frbench.backends.base import RobotState
from frbench.tasks.initial_states import RecordedStarts

#: Largest batch of simultaneous simulations the bank is settled in (MuJoCo C on the CPU).
BANK_BATCH = 128
#: The fields of a recorded state.
STATE_FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")


class StartBank:
    """M settled starts (``states``, a `RobotState` of M rows, numpy) with the raster row of their tile
    (``tile`` (M,)) and their robot variant (``variant`` (M,)), of K variants on T tiles."""

    def __init__(self, states: RobotState, tile: np.ndarray, variant: np.ndarray, num_variants: int, num_tiles: int):
        self.states, self.tile, self.variant = states, np.asarray(tile, dtype=np.int64), np.asarray(variant, np.int64)
        self.num_variants, self.num_tiles = int(num_variants), int(num_tiles)
        k = self.num_variants
        key = self.tile * k + self.variant
        self._order = np.argsort(key, kind="stable")
        counts = np.bincount(key, minlength=self.num_tiles * k)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        sorted_tiles = self.tile[self._order]
        for cell in np.flatnonzero(counts == 0):  # borrow the tile's other variants (all entries of the tile)
            mine = np.flatnonzero(sorted_tiles == cell // k)
            if mine.size:
                starts[cell], counts[cell] = mine[0], mine.size
        self.cell_start, self.cell_count = starts, counts

    def __len__(self) -> int:
        return len(self.tile)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The bank as named arrays (a bundle's ``bank/...``)."""
        return {**{f"state_{name}": getattr(self.states, name) for name in STATE_FIELDS},
                "tile": self.tile, "variant": self.variant, "shape": np.array([self.num_variants, self.num_tiles])}

    @classmethod
    def from_arrays(cls, arrays: dict) -> "StartBank":
        """The bank `to_arrays` gave."""
        states = RobotState(**{name: np.asarray(arrays[f"state_{name}"], dtype=float) for name in STATE_FIELDS})
        k, t = (int(v) for v in arrays["shape"])
        return cls(states, arrays["tile"], arrays["variant"], k, t)

    def entries(self, rng: np.random.Generator, tile_row: np.ndarray, variant: np.ndarray) -> np.ndarray:
        """(N,) bank rows: one uniform draw (``rng.random``) per environment among its cell's entries."""
        cell = np.asarray(tile_row) * self.num_variants + np.asarray(variant)
        count = self.cell_count[cell]
        if (count == 0).any():
            raise ValueError(f"start bank: no settled start on tile row {int(np.asarray(tile_row)[count == 0][0])}")
        pick = np.minimum((rng.random(len(cell)) * count).astype(np.int64), count - 1)
        return self._order[self.cell_start[cell] + pick]

    def begin(self, env, rng: np.random.Generator, tile_row: np.ndarray, variant: np.ndarray, params) -> None:
        """Begin every episode of the core env ``env`` at a bank entry of its cell (`entries`) under ``params``; the
        previous action at t = 0 is each environment's robot's default pose, as after a settle."""
        rows = self.entries(rng, tile_row, variant)
        state = self.states.take(rows)
        default = np.asarray(env.task.default_pose, dtype=float)  # (J,), or (N, J) when the robots' differ
        previous = np.tile(default, (len(rows), 1)) if default.ndim == 1 else default.copy()
        env.begin_recorded(RecordedStarts(state, previous), params)


def record_bank(cfg, grid, raster, robots, per_cell: int, rng: np.random.Generator, log=print) -> StartBank:
    """``per_cell`` settled starts of every robot variant on every tile of ``grid`` (the protocol's draw moved to
    the tile, settled for ``cfg.settle_steps`` under nominal gains and screened, `frbench.tasks.core_env.CoreEnv`
    over MuJoCo C), drawn from ``rng``; starts that diverged while settling are left out."""
    from frbench.tasks.actions import DirectTargets
    from frbench.tasks.core_env import CoreEnv
    from frbench.training.action_hold import HeldAction

    tiles = list(raster.tile_keys)
    k = len(robots.specs)
    log(f"start bank: {len(tiles)} tiles x {k} robot variants x {per_cell} settled starts (MuJoCo C)")
    per_batch = max(1, min(per_cell, BANK_BATCH // k)) if k <= BANK_BATCH else 1
    batch_variants = np.tile(np.arange(k), per_batch)
    b = len(batch_variants)
    variants = None if robots.variants is None else (robots.specs, batch_variants, robots.variant_friction,
                                                     robots.variant_payload)
    core = CoreEnv(robots.spec, "mujoco", grid.world, b, transform=DirectTargets(robots.spec.default_pose, 1.0),
                   hold=HeldAction(1), rng=rng, variants=variants, surface_rules=False, track_metrics=False)
    states, tile_rows, variant_ids = [], [], []
    try:
        for tile in tiles:
            for _ in range(-(-per_cell // per_batch)):
                starts = core.draw_fallen(rng, [grid.tiles[tile]] * b, [grid.offsets[tile]] * b,
                                          [robots.specs[v] for v in batch_variants])
                core.reset(starts, None, cfg.settle_steps)
                ok = ~core.task.settle_diverged
                states.append(core.state.take(ok))
                tile_rows.append(np.full(int(ok.sum()), raster.index[tile]))
                variant_ids.append(batch_variants[ok])
    finally:
        core.close()
    merged = RobotState(**{name: np.concatenate([getattr(s, name) for s in states]) for name in STATE_FIELDS})
    return StartBank(merged, np.concatenate(tile_rows), np.concatenate(variant_ids), k, len(tiles))
