"""FR-Net's terrain curriculum: seven families × ten levels, driven by recovery success.

The paper trains "using curriculum learning" over its terrain families and ten
difficulty levels without stating the rule. frbench uses legged_gym's terrain
curriculum with the promotion signal replaced: an environment moves by its
recovery **success** (the benchmark's success test), not by distance walked.

Rules
-----
* **Families are fixed per environment.** At construction every environment is
  given a family, balanced (N // F or N // F + 1 environments each) and in a
  random order, and keeps it for the whole run, as legged_gym keeps each
  environment on its terrain column. Every family thus gets a stable share of
  the experience, and its mean level is a meaningful learning curve.
* **Levels** start at ``start_level`` and move after blocks of ``window``
  finished episodes at the current level. With r the success rate of the block:
  one level up if r ≥ ``promote_threshold``, else one level down if
  r < ``demote_threshold``, else stay. The block then starts afresh. The default
  (window 1, both thresholds 0.5) is: up after every success, down after every
  failure, so each environment settles around the level where it succeeds half
  of the time.
* **Clamping and resampling.** Levels stay in [1, ``max_level``]. An
  environment promoted beyond ``max_level`` is sent to a level drawn uniformly
  from [1, ``max_level``] (legged_gym does the same), so that once the policy
  masters the hardest level the curriculum keeps covering every level.
* **Randomness** comes from a generator seeded once from the ``rng`` passed in
  (one draw), so the curriculum is deterministic given that rng and its state
  travels in :meth:`TerrainCurriculum.state_dict`.
"""

from __future__ import annotations

import numpy as np

from frbench.terrains import FAMILIES

__all__ = ["TerrainCurriculum", "moved_levels"]

_STATE_VERSION = 1
_BIT_GENERATORS = ("PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937")


def moved_levels(level, successes, episodes, redraw, *, promote: float, demote: float, max_level: int):
    """The rule's one implementation: the levels of environments whose block just ended, for numpy arrays (the
    curriculum, `TerrainCurriculum`, on the host) and torch tensors on a device alike.

    Args:
        level: (M,) int, the environments' current levels.
        successes, episodes: (M,) int, the block's successful and finished episodes (``episodes`` ≥ 1 where it
            matters; 0 entries count as 1).
        redraw: ``redraw(over)`` → (M,) int of ``level``'s kind, a uniform draw from [1, ``max_level``] at every
            entry where the bool mask ``over`` holds (the caller's generator; other entries are not read).
        promote, demote: the block success rates at or above which a level goes up, below which it goes down.
        max_level: the hardest level.

    Returns:
        (M,) int: one level up, down or the same; a promotion beyond ``max_level`` takes the redrawn level;
        clamped to [1, ``max_level``].
    """
    from frbench.arrays import namespace

    xp = namespace(level)
    rate = successes / xp.clip(episodes, 1, None)
    up = rate >= promote
    down = ~up & (rate < demote)
    new = level + xp.astype(up, level.dtype) - xp.astype(down, level.dtype)
    over = new > max_level
    return xp.clip(xp.where(over, redraw(over), new), 1, max_level)


class TerrainCurriculum:
    """Per-environment terrain family and level for N environments (see the module docstring).

    Attributes:
        families: the family names; ``family`` indexes into them.
        family: (N,) int, each environment's family index (fixed).
        level: (N,) int in [1, max_level], each environment's current level.
        max_level: the hardest level.
    """

    def __init__(
        self,
        num_envs: int,
        rng: np.random.Generator,
        families: tuple[str, ...] = FAMILIES,
        max_level: int = 10,
        start_level: int = 1,
        promote_threshold: float = 0.5,
        demote_threshold: float = 0.5,
        window: int = 1,
    ):
        """
        Args:
            num_envs: N ≥ 1.
            rng: parent generator; one value is drawn from it to seed the curriculum's own.
            families: family names (default: all of ``frbench.terrains.FAMILIES``).
            max_level: hardest level (levels are 1..max_level).
            start_level: every environment's first level.
            promote_threshold: block success rate at or above which an environment moves up.
            demote_threshold: block success rate below which it moves down (≤ promote_threshold).
            window: episodes per block.
        """
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if not families:
            raise ValueError("families must not be empty")
        if max_level < 1 or not 1 <= start_level <= max_level:
            raise ValueError(f"need 1 <= start_level ({start_level}) <= max_level ({max_level})")
        if not 0.0 <= demote_threshold <= promote_threshold <= 1.0:
            raise ValueError(
                f"need 0 <= demote_threshold ({demote_threshold}) <= promote_threshold ({promote_threshold}) <= 1"
            )
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window}")
        self.families = tuple(families)
        self.num_envs = int(num_envs)
        self.max_level = int(max_level)
        self.start_level = int(start_level)
        self.promote_threshold = float(promote_threshold)
        self.demote_threshold = float(demote_threshold)
        self.window = int(window)
        self._rng = np.random.default_rng(int(rng.integers(0, 2**63)))
        self.family = np.empty(self.num_envs, dtype=np.int64)
        self.family[self._rng.permutation(self.num_envs)] = np.arange(self.num_envs) % len(self.families)
        self.level = np.full(self.num_envs, self.start_level, dtype=np.int64)
        self._successes = np.zeros(self.num_envs, dtype=np.int64)
        self._episodes = np.zeros(self.num_envs, dtype=np.int64)

    # ------------------------------------------------------------------ updates

    def update(self, env_ids, success) -> None:
        """Record the outcome of the episodes that environments ``env_ids`` just finished.

        Args:
            env_ids: (M,) distinct environment indices.
            success: (M,) bool, whether each of those episodes met the success test (numpy, or an array on a
                device: it comes to the host, where the curriculum lives).
        """
        from frbench.arrays import to_host

        ids = np.asarray(to_host(env_ids), dtype=np.int64).reshape(-1)
        ok = np.asarray(to_host(success), dtype=bool).reshape(-1)
        if ids.shape != ok.shape:
            raise ValueError(f"env_ids has {ids.size} entries, success {ok.size}")
        if ids.size == 0:
            return
        if ids.min() < 0 or ids.max() >= self.num_envs:
            raise ValueError(f"env_ids must lie in [0, {self.num_envs}), got {ids.min()}..{ids.max()}")
        if np.unique(ids).size != ids.size:
            raise ValueError("env_ids must be distinct")
        self._episodes[ids] += 1
        self._successes[ids] += ok
        ready = ids[self._episodes[ids] >= self.window]
        if ready.size == 0:
            return
        def redraw(over: np.ndarray) -> np.ndarray:
            drawn = np.zeros(over.shape, dtype=np.int64)
            if over.any():
                drawn[over] = self._rng.integers(1, self.max_level + 1, size=int(over.sum()))
            return drawn

        self.level[ready] = moved_levels(self.level[ready], self._successes[ready], self._episodes[ready], redraw,
                                         promote=self.promote_threshold, demote=self.demote_threshold,
                                         max_level=self.max_level)
        self._successes[ready] = 0
        self._episodes[ready] = 0

    # ------------------------------------------------------------------ queries

    def family_name(self, env_id: int) -> str:
        """Name of environment ``env_id``'s family."""
        return self.families[int(self.family[env_id])]

    def cells(self) -> dict[tuple[str, int], np.ndarray]:
        """(family name, level) → sorted environment indices, for every occupied cell."""
        key = self.family * (self.max_level + 1) + self.level
        order = np.argsort(key, kind="stable")
        uniq, starts = np.unique(key[order], return_index=True)
        groups = np.split(order, starts[1:])
        return {
            (self.families[int(k) // (self.max_level + 1)], int(k) % (self.max_level + 1)): np.sort(g)
            for k, g in zip(uniq, groups)
        }

    def stats(self) -> dict[str, float]:
        """For logging: ``level/<family>`` mean level of each family's environments,
        ``level/all`` the mean over all, ``level/at_max`` the fraction at ``max_level``."""
        out = {"level/all": float(self.level.mean()), "level/at_max": float(np.mean(self.level == self.max_level))}
        for i, name in enumerate(self.families):
            mask = self.family == i
            if mask.any():
                out[f"level/{name}"] = float(self.level[mask].mean())
        return out

    # ------------------------------------------------------------------ checkpointing

    def state_dict(self) -> dict:
        """Plain Python state (lists, ints, floats, str), loadable by ``torch.load(weights_only=True)``."""
        return {
            "version": _STATE_VERSION,
            "families": list(self.families),
            "max_level": self.max_level,
            "family": self.family.tolist(),
            "level": self.level.tolist(),
            "successes": self._successes.tolist(),
            "episodes": self._episodes.tolist(),
            "rng": self._rng.bit_generator.state,
        }

    def load_state_dict(self, state: dict) -> None:
        """Restore :meth:`state_dict` output. The environment count, families and max level must match;
        the thresholds and window are this object's (they may change on resume)."""
        if state.get("version") != _STATE_VERSION:
            raise ValueError(f"curriculum state version {state.get('version')!r}, expected {_STATE_VERSION}")
        if tuple(state["families"]) != self.families:
            raise ValueError(f"curriculum state has families {state['families']}, this run {list(self.families)}")
        if int(state["max_level"]) != self.max_level:
            raise ValueError(f"curriculum state has max_level {state['max_level']}, this run {self.max_level}")
        if len(state["level"]) != self.num_envs:
            raise ValueError(f"curriculum state has {len(state['level'])} environments, this run {self.num_envs}")
        family = np.asarray(state["family"], dtype=np.int64)
        level = np.asarray(state["level"], dtype=np.int64)
        if family.min() < 0 or family.max() >= len(self.families) or level.min() < 1 or level.max() > self.max_level:
            raise ValueError("curriculum state has family or level indices out of range")
        kind = state["rng"].get("bit_generator")
        if kind not in _BIT_GENERATORS:
            raise ValueError(f"curriculum state has bit generator {kind!r}, expected one of {_BIT_GENERATORS}")
        rng = np.random.Generator(getattr(np.random, kind)())
        rng.bit_generator.state = state["rng"]
        self.family, self.level = family, level
        self._successes = np.asarray(state["successes"], dtype=np.int64)
        self._episodes = np.asarray(state["episodes"], dtype=np.int64)
        self._rng = rng
