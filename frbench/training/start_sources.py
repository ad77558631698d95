"""Where training episodes start besides fresh fallen poses: demo starts and rise starts.

Every episode first gets a fresh fallen start on its curriculum tile (the
protocol's draw, settled by the episode engine). A start source then replaces
some of them by recorded states:

* `DemoStarts`: states along the model-based ``scripted`` (``scripted-humanoid``)
  controller's getting-up motion (`demo_starts.record_demo_starts`), a fraction
  of episodes falling linearly to 0 (a reverse curriculum);
* `RiseStarts`: the states where a gated base controller opened its gate (the key
  frames' crouch) in a recorded run from fresh starts, with the controller put
  back in that phase, so that every such episode exercises the rise.

Both re-record their bank every ``refresh_episodes`` episodes, on the training
batch itself, through the core environment's API (`frbench.tasks.core_env.CoreEnv`:
``state``, ``drive`` — physics only, no episode step — and ``physics_diverged``);
the training env then puts the drawn episodes on their states with ``restart``. Every random draw comes from the generator passed in; a source
draws its Bernoulli mask at every reset, even when its fraction is 0, so the
generator's stream does not depend on the schedule.
"""

from __future__ import annotations

import numpy as np

from frbench.arrays import is_host, like, namespace, to_host
from frbench.backends.base import RobotState
from frbench.tasks.observations import proprioception
from frbench.tasks.recovery import EPISODE_STEPS
from frbench.training.demo_starts import DemoStartBank, assist_probability, record_demo_starts

#: The fields of a recorded state, stacked row by row.
_STATE_FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")


class DemoStarts:
    """A fraction ``initial`` of episodes, falling linearly to 0 at ``until`` env steps, starts from a state of
    the scripted getting-up motion, re-recorded every ``refresh_episodes`` episodes from ``steps`` control steps,
    one snapshot every ``stride``."""

    def __init__(self, initial: float, until: float, refresh_episodes: int, steps: int, stride: int):
        self.initial, self.until = float(initial), float(until)
        self.refresh_episodes, self.steps, self.stride = int(refresh_episodes), int(steps), int(stride)
        self.bank: DemoStartBank | None = None
        self.episodes_since = 0

    def fraction(self, env_steps: int) -> float:
        """The share of episodes started from the bank at ``env_steps``."""
        return assist_probability(self.initial, self.until, env_steps)

    def needs_recording(self, fraction: float) -> bool:
        """Whether the bank must be (re-)recorded before this reset."""
        return fraction > 0.0 and (self.bank is None or self.episodes_since >= self.refresh_episodes)

    def record(self, env, specs, assignment: np.ndarray, tile_row: np.ndarray) -> None:
        """Record the bank from the fresh starts the core env ``env`` holds now (see `record_demo_starts`)."""
        self.bank = record_demo_starts(env, specs, assignment, tile_row, self.steps, self.stride)
        self.episodes_since = 0

    def draw(self, rng: np.random.Generator, num_envs: int, fraction: float) -> np.ndarray:
        """(N,) bool: the episodes that start from the bank (one Bernoulli draw each; valid recordings only).
        Counts one episode towards the refresh."""
        self.episodes_since += 1
        return (rng.random(num_envs) < fraction) & (self.bank.valid if self.bank is not None else False)

    def sample(self, ids: np.ndarray, rng: np.random.Generator) -> tuple[RobotState, np.ndarray, np.ndarray]:
        """(state (M rows), controller targets (M, J) [rad], tile rows (M,)) for environments ``ids``."""
        return self.bank.sample(ids, rng)


class RiseStarts:
    """A fraction ``fraction`` of episodes starts where the base controller's gate opened in a recorded episode,
    re-recorded every ``refresh_episodes`` episodes (`record`)."""

    def __init__(self, fraction: float, refresh_episodes: int):
        self.fraction, self.refresh_episodes = float(fraction), int(refresh_episodes)
        self.bank: list[tuple[RobotState, int, np.ndarray, int]] | None = None
        self.episodes_since = 0

    def needs_recording(self) -> bool:
        """Whether the bank must be (re-)recorded before this reset (counts one episode towards the refresh)."""
        stale = self.bank is None or self.episodes_since >= self.refresh_episodes
        return self.fraction > 0.0 and stale

    def count_episode(self) -> None:
        """One more episode since the bank was recorded."""
        self.episodes_since += 1

    def record(self, env, controller, spec, default_pose: np.ndarray, tile_row: np.ndarray) -> None:
        """Run ``controller`` (a fresh base controller) on the fresh starts the core env ``env`` holds for one evaluation
        episode (`EPISODE_STEPS`, whatever the training episode length: the gate openings an evaluation can see);
        keep the state (one row), tile, controller targets (J,) [rad] and way to the crouch (``gate_paths``) of
        every environment at the step its default gate (the crouch) first opened."""
        n = env.num_envs
        controller.reset(spec, n)
        bank, opened = [], np.zeros(n, dtype=bool)
        state = env.state.on_host()  # the controller runs on the host
        for _ in range(EPISODE_STEPS):
            state = env.drive(np.asarray(controller.act(proprioception(state, default_pose)))).on_host()
            new = (controller.residual_gate() > 0) & ~opened & ~to_host(env.physics_diverged)
            paths = controller.gate_paths()
            bank += [(state.take([i]), int(tile_row[i]), controller.target[i].copy(), int(paths[i]))
                     for i in np.flatnonzero(new)]
            opened |= new
        self.bank, self.episodes_since = bank, 0

    def draw(self, rng: np.random.Generator, taken: np.ndarray):
        """The episodes (not already ``taken`` (N,) bool by another source) that start from the bank:
        (ids (M,), state (M rows), tile rows (M,), controller targets (M, J), ways to the crouch (M,)),
        or None when there are none."""
        drawn = (rng.random(len(taken)) < self.fraction) & ~taken
        ids = np.flatnonzero(drawn) if self.bank else np.zeros(0, int)
        if not len(ids):
            return None
        picks = rng.integers(0, len(self.bank), size=len(ids))
        rows = [self.bank[k][0] for k in picks]
        state = RobotState(**{f: np.concatenate([getattr(r, f) for r in rows]) for f in _STATE_FIELDS})
        return (ids, state, [self.bank[k][1] for k in picks], np.stack([self.bank[k][2] for k in picks]),
                np.array([self.bank[k][3] for k in picks]))


class CurriculumStarts:
    """Training's start distribution, the ``starts`` of its `frbench.tasks.core_env.CoreEnv`: every episode a
    fresh fallen start on the tile its curriculum level says (the protocol's draw, moved to the tile, of the
    environment's robot, settled under the episode's randomised physics), a fraction of them replaced by
    `DemoStarts` and `RiseStarts` states; the curriculum moves on the episodes from fallen starts.

    Args:
        cfg: the `TrainEnvConfig` (start-source schedules, settle steps, action scale, families, curriculum).
        grid: the world of terrain tiles (`terrain_grid.build_grid`); ``raster`` its `HeightRaster`.
        curriculum: the `TerrainCurriculum` (each environment's family and level).
        robots: the batch's `TrainingRobots` (robot per environment, physics per episode).
        bank: a `frbench.training.start_bank.StartBank` of settled starts recorded before training, or None: every
            episode's fallen start is drawn and settled afresh.

    After `new_episodes`: ``tile_row`` (N,) each environment's tile (a row of ``raster``), ``from_demo`` (N,)
    the episodes started from a bank (demo or rise).
    """

    def __init__(self, cfg, grid, raster, curriculum, robots, bank=None):
        self.cfg, self.grid, self.raster, self.curriculum, self.robots = cfg, grid, raster, curriculum, robots
        self.bank = bank
        self.demo = DemoStarts(cfg.demo_start_fraction, cfg.demo_start_until, cfg.demo_refresh_episodes,
                               cfg.demo_steps, cfg.demo_stride)
        self.rise = RiseStarts(cfg.rise_start_fraction, cfg.demo_refresh_episodes) if cfg.rise_start_fraction else None
        self.tile_row: np.ndarray | None = None
        self._tiles: dict = {}  # ``tile_row`` on the devices it was asked for (`tiles`), until new episodes
        self.from_demo = np.zeros(cfg.num_envs, dtype=bool)

    def tiles(self, ref):
        """``tile_row`` (N,) in the namespace and on the device of array ``ref`` (converted once per episode)."""
        if is_host(ref):
            return self.tile_row
        key = str(ref.device)
        if key not in self._tiles:
            self._tiles[key] = like(self.tile_row, ref, namespace(ref).int64)
        return self._tiles[key]

    def new_episodes(self, env, rng: np.random.Generator) -> None:
        """New episodes for every environment of the core env ``env``: fresh fallen starts (re-recording a bank
        first when it is due), a fraction of them replaced by bank states; the episodes' actions begun."""
        self._tiles = {}
        try:
            self._new_episodes(env, rng)
        finally:
            self._tiles = {}

    def _new_episodes(self, env, rng: np.random.Generator) -> None:
        n, spec = env.num_envs, env.spec
        fraction = self.demo.fraction(env.env_steps)
        if self.demo.needs_recording(fraction):
            self._fresh_starts(env, rng)
            self.demo.record(env, self.robots.specs, self.robots.assignment, self.tile_row)
        if self.rise is not None:
            if self.rise.needs_recording():
                self._fresh_starts(env, rng)
                self.rise.record(env, env.transform.fresh_copy(), spec, env.default_pose, self.tile_row)
            self.rise.count_episode()
        self._fresh_starts(env, rng)
        action = np.zeros((n, spec.n_joints))
        self.from_demo = self.demo.draw(rng, n, fraction)
        if self.from_demo.any():
            ids = np.flatnonzero(self.from_demo)
            state, targets, tiles = self.demo.sample(ids, rng)
            self._restart_from(env, ids, state, tiles)
            action[ids] = (targets - env.default_pose) / self.cfg.action_scale
        env.begin(action)  # a_{t-1} = a_t: both zero at a fresh start; the transform reset
        if self.rise is not None:
            drawn = self.rise.draw(rng, self.from_demo)
            if drawn is not None:
                ids, state, tiles, targets, paths = drawn
                self._restart_from(env, ids, state, tiles)
                self.from_demo[ids] = True
                env.transform.enter_gate(ids, targets, to_host(env.state.q), paths)

    def _restart_from(self, env, ids: np.ndarray, state: RobotState, tiles) -> None:
        """Start environments ``ids`` from recorded ``state`` (len(ids) rows) on their recorded ``tiles``."""
        env.restart(ids, state)
        self.tile_row[ids] = tiles

    def _fresh_starts(self, env, rng: np.random.Generator) -> None:
        """Fallen starts on every environment's curriculum tile, settled for ``settle_steps`` by the engine (or
        drawn from the bank of settled starts)."""
        tiles = list(zip(self.curriculum.family.tolist(), self.curriculum.level.tolist()))
        self.tile_row = np.array([self.raster.index[t] for t in tiles])
        if self.bank is not None:
            self.bank.begin(env, rng, self.tile_row, self.robots.assignment, self.robots.episode_params())
            return
        specs = [self.robots.specs[k] for k in self.robots.assignment]
        starts = env.draw_fallen(rng, [self.grid.tiles[t] for t in tiles], [self.grid.offsets[t] for t in tiles], specs)
        env.reset(starts, self.robots.episode_params(), self.cfg.settle_steps)

    def end_episodes(self, env, success, alive) -> dict[str, float]:
        """The episodes' statistics (`episode_stats`), then the curriculum's move on the fallen starts' ``success``
        (N,) bool (when the config has a curriculum). ``success`` and ``alive`` (N,) may live on a device: they
        come to the host here, once per episode."""
        success, alive = to_host(success), to_host(alive)
        stats = self.episode_stats(env, success, alive)
        if self.cfg.curriculum:  # the curriculum judges fallen starts only
            fallen = np.flatnonzero(~self.from_demo)
            self.curriculum.update(fallen, success[fallen])
        return stats

    def episode_stats(self, env, success: np.ndarray, alive: np.ndarray) -> dict[str, float]:
        """Success rate of the episodes from fallen starts, overall, per family (all levels) and, on a split
        backend, per simulator (``success_in_<simulator>``); the diverged fraction; with demo starts, their
        share and their success rate."""
        fallen = ~self.from_demo
        stats = {"success_all": float(success[fallen].mean()) if fallen.any() else 0.0,
                 "diverged": float((~alive).mean()), "mean_level": float(self.curriculum.level.mean())}
        if self.cfg.assist_force > 0.0:
            stats["assist_fraction"] = float(env.assist.fraction)
        if self.from_demo.any():
            stats["demo_start_share"] = float(self.from_demo.mean())
            stats["success_demo_starts"] = float(success[self.from_demo].mean())
        for f, family in enumerate(self.cfg.families):
            mine = (self.curriculum.family == f) & fallen
            if mine.any():
                stats[f"success_{family}"] = float(success[mine].mean())
        parts = env.simulator_parts()
        for simulator, rows in parts if len(parts) > 1 else ():
            mine = np.zeros_like(fallen)
            mine[rows] = fallen[rows]
            if mine.any():
                stats[f"success_in_{simulator}"] = float(success[mine].mean())
        return stats
