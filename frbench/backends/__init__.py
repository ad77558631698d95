"""Simulator backends behind one batched protocol (see :mod:`frbench.backends.base`)."""

from __future__ import annotations

from frbench.backends.simulators import BACKENDS, backend_class, make_simulator, refuse_device, simulator_refusal
from frbench.backends.split import SPLIT_NAME, SplitBackend
from frbench.errors import unknown_name

__all__ = ["BACKENDS", "backend_class", "make_backend", "simulator_parts", "simulator_refusal",
           "training_backend_names"]


def training_backend_names() -> tuple[str, ...]:
    """Every name `make_backend` accepts: the simulators and the split batch ``mujoco+pybullet``."""
    return (*BACKENDS, SPLIT_NAME)


def make_backend(name: str, spec, num_envs: int, terrain=None, variants=None, device: str | None = None,
                 device_arrays: bool = False, world=None):
    """A backend ``name`` running ``num_envs`` simulations of ``spec`` on ``terrain`` (flat if None).

    ``variants`` (specs, assignment, frictions, payloads): per-simulation robots
    of the same structure (morphology randomisation); see `MujocoBackend`.
    ``name`` may also be ``mujoco+pybullet`` (training only): the batch split between the two simulators
    (`frbench.backends.split`).
    ``device``: where the simulator runs (`frbench.backends.devices.parse_device`'s value; None: ``cpu``); the CPU
    simulators run on ``cpu`` only. ``device_arrays``: the backend hands out its arrays on that device (MuJoCo Warp:
    torch tensors; training) instead of host numpy arrays (evaluation, the Gymnasium envs); the CPU simulators'
    arrays are numpy on the host either way. ``world``: a compiled world to run instead of compiling one
    (`frbench.backends.mujoco_warp_backend.CompiledWorld`; MuJoCo Warp only).
    """
    if name == SPLIT_NAME:
        refuse_device(name, device, world)
        return SplitBackend(spec, num_envs, terrain=terrain, variants=variants)
    if name not in BACKENDS:
        raise unknown_name("backend", name, training_backend_names())
    return make_simulator(name, spec, num_envs, terrain=terrain, variants=variants, device=device,
                          device_arrays=device_arrays, world=world)


def simulator_parts(backend) -> list[tuple[str, slice]]:
    """(simulator name, its simulations' rows) of each simulator ``backend`` runs: the parts of a split
    batch (`frbench.backends.split`), else one part with every row."""
    if isinstance(backend, SplitBackend):
        return backend.part_rows()
    return [(backend.name, slice(0, backend.num_envs))]
