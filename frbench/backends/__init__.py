"""Simulator backends behind one batched protocol (see :mod:`frbench.backends.base`)."""

from __future__ import annotations

from frbench.backends.simulators import BACKENDS, backend_class, make_simulator, simulator_refusal
from frbench.backends.split import SPLIT_NAME, SplitBackend
from frbench.errors import unknown_name

__all__ = ["BACKENDS", "backend_class", "make_backend", "simulator_parts", "simulator_refusal",
           "training_backend_names"]


def training_backend_names() -> tuple[str, ...]:
    """Every name `make_backend` accepts: the simulators and the split batch ``mujoco+pybullet``."""
    return (*BACKENDS, SPLIT_NAME)


def make_backend(name: str, spec, num_envs: int, terrain=None, variants=None):
    """A backend ``name`` running ``num_envs`` simulations of ``spec`` on ``terrain`` (flat if None).

    ``variants`` (specs, assignment, frictions, payloads): per-simulation robots
    of the same structure (morphology randomisation); see `MujocoBackend`.
    ``name`` may also be ``mujoco+pybullet`` (training only): the batch split between the two simulators
    (`frbench.backends.split`).
    """
    if name == SPLIT_NAME:
        return SplitBackend(spec, num_envs, terrain=terrain, variants=variants)
    if name not in BACKENDS:
        raise unknown_name("backend", name, training_backend_names())
    return make_simulator(name, spec, num_envs, terrain=terrain, variants=variants)


def simulator_parts(backend) -> list[tuple[str, slice]]:
    """(simulator name, its simulations' rows) of each simulator ``backend`` runs: the parts of a split
    batch (`frbench.backends.split`), else one part with every row."""
    if isinstance(backend, SplitBackend):
        return backend.part_rows()
    return [(backend.name, slice(0, backend.num_envs))]
