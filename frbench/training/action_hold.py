"""Held actions: the policy decides every K control steps and its action is held in between.

With K = 1 (the default) every control step is a decision. With K > 1 the
exploration noise moves the joint targets for K × 0.02 s at a time instead of
averaging out from one step to the next (time-coherent exploration for a
residual over key frames). The rewards that read the previous actions
(smoothing a_t − a_{t−1}, jerk a_t − 2a_{t−1} + a_{t−2}) see, within a
decision, the held action as its own predecessor.

Shapes: (N, J) actions in policy units (numpy or torch).
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from frbench.arrays import copy_of


class HeldAction:
    """The current action a_t and its predecessor a_{t−1}, held for ``hold`` control steps per decision."""

    def __init__(self, hold: int):
        if hold < 1:
            raise ValueError(f"action_hold {hold}: expected at least 1 control step per decision")
        self.hold = int(hold)
        self.current: np.ndarray | None = None
        self.previous: np.ndarray | None = None
        self.held = 0

    def decisions_per_episode(self, episode_steps: int) -> int:
        """Decisions in an episode of ``episode_steps`` control steps (the last one may be held shorter)."""
        return -(-int(episode_steps) // self.hold)

    def begin(self, action: np.ndarray) -> None:
        """A new episode whose first action (and its predecessor) is ``action`` (N, J)."""
        self.current = action
        self.previous = copy_of(action)

    def decide(self, action: np.ndarray, steps_left: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Make ``action`` (N, J) the current one; yield (a_{t−1}, a_{t−2}) for each control step it is held:
        ``hold`` steps, fewer when the episode has only ``steps_left``. ``held`` counts them."""
        action_prev2, action_prev = self.previous, self.current
        self.previous = action_prev
        self.current = action
        self.held = 0
        while True:
            yield action_prev, action_prev2
            self.held += 1
            action_prev2, action_prev = action_prev, self.current  # within a decision the action does not change
            if self.held >= self.hold or self.held >= steps_left:
                break
        if self.held > 1:  # the next decision's a_{t-2}: the control step before the last one held this action too
            self.previous = self.current
