"""Redraw starts that are already recovered after the settle, so no policy is credited for it (protocol 1.1).

A drawn start is settled for `SETTLE_SECONDS` before t = 0 (`frbench.tasks.recovery`). Now and then a side
or random start tips onto its feet during the settle; under protocol 1.0 the `zero` policy "recovered"
from those. Here, after the settle, every start whose settled state lies within the success test's
upright bound (`SuccessTracker.up_pose`: tilt, height and surface, whatever touches the ground) is
replaced by the next deterministic draw of the same episode (`episode_rng(..., attempt)`), and all
starts are settled again, until none is upright or `MAX_SCREEN_ROUNDS` rounds have passed.

What a start settles into is each simulator's physics, so the screening runs in each backend: the
sequence of candidate starts is identical in MuJoCo and PyBullet, and the rare start that settles
upright in one of them only is replaced in that one. Each episode's number of redraws is recorded.
"""

from __future__ import annotations

import numpy as np

from frbench.tasks.initial_states import FallenStarts, draw_start, episode_rng, start_name

#: Screening rounds before giving up (a start still upright after this many redraws is kept and counted).
MAX_SCREEN_ROUNDS = 8


def redraw(starts: FallenStarts, mask: np.ndarray) -> None:
    """Replace, in place, the rows of ``starts`` where ``mask`` (N,) is True by their episode's next draw
    (``attempts`` counts the redraws of each row), under the starts' joint-redraw rule (``redraws``)."""
    spec, terrain, family, level, seed, episodes = starts.cell
    for i in np.flatnonzero(mask):
        starts.attempts[i] += 1
        attempt = int(starts.attempts[i])
        rng = episode_rng(spec.name, family, level, seed, episodes[i], attempt=attempt)
        starts.base_pos[i], starts.base_quat[i], starts.q[i], starts.kinds[i] = draw_start(
            spec, terrain, rng, starts.redraws, start_name(family, level, seed, episodes[i], attempt))


def screen_starts(task, starts: FallenStarts, settle_steps: int) -> FallenStarts:
    """Redraw and re-settle ``task``'s settled starts while any lies within the upright bound.

    ``task`` is a `RecoveryTask` right after ``settle(starts)`` (redrawn starts are settled again for
    ``settle_steps`` control steps). ``starts`` is updated in place (its
    ``kinds`` and ``attempts`` then describe the starts the episodes run from) and returned; starts without
    ``cell`` (not from `draw_starts`, e.g. training starts) are left unchanged.
    """
    if starts.cell is None:
        return starts
    for _ in range(MAX_SCREEN_ROUNDS):
        upright = task.settled_upright()
        if not upright.any():
            break
        redraw(starts, upright)
        task.settle(starts, settle_steps)
    return starts
