"""``mujoco+pybullet``: one batch of N simulations split between two backends, for training in both.

Simulations ``0 … n_a − 1`` run in the first backend, ``n_a … N − 1`` in the
second (n_a = ⌈N / 2⌉). The same robot file, actuator model, control period,
physics step, friction and terrain go to both (every backend builds them from
the same `RobotSpec` and terrain), so a policy trained on the split batch sees
each simulator's contact and integration differences in half of its episodes —
what `frbench evaluate` scores it on. Every method takes or returns arrays with
N rows and routes them to the two parts; nothing else differs from a single
backend, so the training environment needs no change to use it.
"""

from __future__ import annotations

import itertools
from dataclasses import fields

import numpy as np

from frbench.backends.base import Contacts, PhysicsParams, RobotState
from frbench.backends.simulators import make_simulator
from frbench.robots.spec import RobotSpec

#: The name ``frbench train --backend`` accepts for the split batch, and its two parts in order.
SPLIT_NAME = "mujoco+pybullet"
SPLIT_PARTS = ("mujoco", "pybullet")


def split_sizes(num_envs: int, parts: int = 2) -> list[int]:
    """Simulations per part: as equal as possible, the first parts one larger. Raises ValueError for fewer
    simulations than parts (a part would be empty)."""
    if num_envs < parts:
        raise ValueError(f"a split backend needs at least {parts} simulations (one per simulator), got {num_envs}")
    return [num_envs // parts + (1 if k < num_envs % parts else 0) for k in range(parts)]


def _concat(values: list) -> np.ndarray | None:
    return None if any(v is None for v in values) else np.concatenate(values)


def _take_rows(obj, rows: slice):
    """A dataclass of per-simulation arrays cut to ``rows`` (None fields stay None)."""
    return type(obj)(**{f.name: (None if getattr(obj, f.name) is None else getattr(obj, f.name)[rows])
                        for f in fields(obj)})


class SplitBackend:
    """N simulations of one robot, split between backends ``names`` (default `SPLIT_PARTS`); see the module
    docstring. The parts must agree on link names, physics step and substeps (ValueError otherwise)."""

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, variants=None,
                 names: tuple[str, ...] = SPLIT_PARTS):
        self.name = "+".join(names)
        self.spec, self.num_envs = spec, int(num_envs)
        sizes = split_sizes(self.num_envs, len(names))
        bounds = [0, *itertools.accumulate(sizes)]
        self.rows = [slice(a, b) for a, b in itertools.pairwise(bounds)]
        self.parts = []
        for name, rows in zip(names, self.rows):
            part_variants = None
            if variants is not None:
                specs, assignment, frictions, payloads = variants
                part_variants = (specs, np.asarray(assignment)[rows], frictions, payloads)
            self.parts.append(make_simulator(name, spec, rows.stop - rows.start, terrain=terrain, variants=part_variants))
        first = self.parts[0]
        for part in self.parts[1:]:
            for attr in ("link_names", "physics_dt", "substeps"):
                if getattr(part, attr) != getattr(first, attr):
                    raise ValueError(f"split backend {self.name}: {part.name} has {attr}={getattr(part, attr)!r}, "
                                     f"{first.name} {getattr(first, attr)!r}; the parts must simulate the same task")
        self.physics_dt, self.substeps, self.link_names = first.physics_dt, first.substeps, first.link_names

    def part_rows(self) -> list[tuple[str, slice]]:
        """(simulator name, its simulations' rows) of each part, in order."""
        return [(part.name, rows) for part, rows in zip(self.parts, self.rows)]

    @property
    def diverged(self) -> np.ndarray:
        """(N,) bool: simulations whose state left the valid range (each part's flags, in order)."""
        return np.concatenate([part.diverged for part in self.parts])

    def _local(self, ids: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """For each part: (positions in ``ids`` that fall in it, their part-local indices)."""
        ids = np.asarray(ids, dtype=int)
        if ids.size and (ids.min() < 0 or ids.max() >= self.num_envs):
            raise IndexError(f"simulation ids must lie in [0, {self.num_envs}), got {ids.min()}…{ids.max()}")
        out = []
        for rows in self.rows:
            where = np.flatnonzero((ids >= rows.start) & (ids < rows.stop))
            out.append((where, ids[where] - rows.start))
        return out

    def reset(self, ids: np.ndarray, state: RobotState) -> None:
        """Place simulations ``ids`` in ``state`` (rows match ``ids``)."""
        for part, (where, local) in zip(self.parts, self._local(ids)):
            if local.size:
                part.reset(local, state.take(where))

    def step(self, joint_targets: np.ndarray) -> None:
        """Advance every simulation one control period towards ``joint_targets`` (N, n_joints) [rad]."""
        targets = np.asarray(joint_targets, dtype=float)
        if targets.shape[0] != self.num_envs:
            raise ValueError(f"joint_targets must have {self.num_envs} rows (one per simulation), got {targets.shape}")
        for part, rows in zip(self.parts, self.rows):
            part.step(targets[rows])

    def state(self) -> RobotState:
        """Current state of all simulations, parts concatenated in order."""
        states = [part.state() for part in self.parts]
        return RobotState(**{f.name: _concat([getattr(s, f.name) for s in states]) for f in fields(RobotState)})

    def contacts(self) -> Contacts:
        """Contact readings at the last physics step, parts concatenated in order."""
        readings = [part.contacts() for part in self.parts]
        return Contacts(**{f.name: np.concatenate([getattr(c, f.name) for c in readings]) for f in fields(Contacts)})

    def set_params(self, params: PhysicsParams) -> None:
        """Every simulation's physical parameters (arrays with N rows), each part its rows."""
        for part, rows in zip(self.parts, self.rows):
            part.set_params(_take_rows(params, rows))

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total mass [kg] (N,), whole-body CoM [m] (N, 3)) as each part's simulator holds them."""
        masses, coms = zip(*(part.mass_properties() for part in self.parts))
        return np.concatenate(masses), np.concatenate(coms)

    def whole_body_com(self) -> np.ndarray:
        """Whole-body CoM [m] (N, 3), each part's rows from its simulator."""
        return np.concatenate([part.whole_body_com() for part in self.parts])

    def set_base_force(self, force: np.ndarray) -> None:
        """Apply ``force`` [N] (N, 3, world frame) at each root link's CoM in every later physics step."""
        force = np.asarray(force, dtype=float)
        if force.shape != (self.num_envs, 3):
            raise ValueError(f"force must have shape ({self.num_envs}, 3), got {force.shape}")
        for part, rows in zip(self.parts, self.rows):
            part.set_base_force(force[rows])

    def close(self) -> None:
        """Free both simulators."""
        for part in self.parts:
            part.close()
