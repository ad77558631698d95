"""What the backends that step N simulations one after another and compute the protocol's PD in numpy at every
physics step share (PyBullet, PhysX): the per-simulation bookkeeping, the base force, the cached state read and
the divergence check after a control period. Each backend reads its simulator in ``_read_state``."""

from __future__ import annotations

import numpy as np

from frbench.backends.base import PhysicsParams, RobotState, check_base_force, divergence_mask, torque_limit_rows
from frbench.robots.spec import RobotSpec


class ExplicitPdBatch:
    """Bookkeeping of N simulations whose PD torques the backend computes (`frbench.backends.base.actuator_torque`).

    Attributes set by `_init_batch`: ``diverged`` (N,) bool; ``_tau`` (N, n_joints) the torques of the last
    physics step [N·m]; ``_base_force`` (N, 3) [N]; ``_limits`` (n_joints,) torque limits [N·m] ((N, n_joints) when the morphology variants'
    differ, `torque_limit_rows`); ``_state`` the
    state read after the last step (None: read it again); ``_masses`` (N, n_links) link masses [kg] (None: read
    them again); ``params`` the physics, nominal at first.
    """

    def _init_batch(self, spec: RobotSpec, num_envs: int, variants=None) -> None:
        self.diverged = np.zeros(num_envs, dtype=bool)
        self._tau = np.zeros((num_envs, spec.n_joints))
        self._base_force = np.zeros((num_envs, 3))
        self._limits = torque_limit_rows(spec, num_envs, variants)
        self._state: RobotState | None = None
        self._masses: np.ndarray | None = None
        self.params = PhysicsParams.nominal(spec, num_envs)

    def _read_state(self) -> RobotState:
        """Every simulation's state in frbench's conventions, torques ``_tau`` included (fresh arrays)."""
        raise NotImplementedError

    def _finish_step(self) -> None:
        """After a control period: read the state and flag the simulations that diverged."""
        self._state = self._read_state()
        self.diverged |= divergence_mask(self._state)

    def set_base_force(self, force: np.ndarray) -> None:
        """A force [N] (N, 3), world frame, on each root link's centre of mass during every later physics step."""
        self._base_force = check_base_force(force, len(self.diverged))

    def state(self) -> RobotState:
        """State of every simulation in frbench's conventions (a copy)."""
        if self._state is None:
            self._state = self._read_state()
        return self._state.copy()
