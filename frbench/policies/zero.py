"""``zero``: hold the default standing pose, whatever happens (a floor for the benchmark)."""

from __future__ import annotations

import numpy as np

from frbench.robots.spec import RobotSpec


class ZeroPolicy:
    """Always returns the default pose: a fallen robot almost never gets up."""

    name = "zero"
    checkpoint = None

    def supports(self, spec: RobotSpec) -> bool:
        """Every robot."""
        return True

    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Remember the pose and batch size."""
        self._targets = np.tile(np.asarray(spec.default_pose, dtype=float), (num_envs, 1))

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The default pose for every environment."""
        return self._targets.copy()
