"""The simulators frbench runs (MuJoCo, PyBullet, MuJoCo Warp, PhysX): name → backend class, each imported on
first use (``mujoco-warp`` needs the ``gpu`` extra, ``physx`` the ``physx`` extra)."""

from __future__ import annotations

import importlib

from frbench.errors import unknown_name

#: Backend name → "module:Class", imported on first use.
BACKENDS = {
    "mujoco": "frbench.backends.mujoco_backend:MujocoBackend",
    "pybullet": "frbench.backends.pybullet_backend:PybulletBackend",
    "mujoco-warp": "frbench.backends.mujoco_warp_backend:MujocoWarpBackend",
    "physx": "frbench.backends.physx_backend:PhysxBackend",
}


def backend_class(name: str):
    """The backend class registered as ``name``."""
    if name not in BACKENDS:
        raise unknown_name("backend", name, BACKENDS)
    module, _, cls = BACKENDS[name].partition(":")
    return getattr(importlib.import_module(module), cls)


#: The simulators that run on a device of their own and take ``device``, ``device_arrays`` and ``world``.
DEVICE_SIMULATORS = ("mujoco-warp",)


def make_simulator(name: str, spec, num_envs: int, terrain=None, variants=None, device: str | None = None,
                   device_arrays: bool = False, world=None):
    """The backend of simulator ``name`` (a key of `BACKENDS`) running ``num_envs`` simulations of ``spec`` on
    ``terrain``; ``variants``, ``device``, ``device_arrays``, ``world``: see `frbench.backends.make_backend`."""
    cls = backend_class(name)
    kwargs = {} if variants is None else {"variants": variants}
    if name in DEVICE_SIMULATORS:
        kwargs.update(device=device or "cpu", device_arrays=device_arrays, world=world)
    else:
        refuse_device(name, device, world)
    return cls(spec, num_envs, terrain=terrain, **kwargs)


def refuse_device(name: str, device: str | None, world=None) -> None:
    """A ValueError when simulator ``name``, which runs on the CPU and compiles its own world, is asked for another
    device or given a compiled world."""
    if device not in (None, "cpu"):
        raise ValueError(f"backend {name} runs on the CPU; --device {device} is for "
                         f"{', '.join(DEVICE_SIMULATORS)}")
    if world is not None:
        raise ValueError(f"backend {name} compiles its own world; a bundle's compiled world is for "
                         f"{', '.join(DEVICE_SIMULATORS)}")


def simulator_refusal(name: str, spec) -> str | None:
    """Why simulator ``name`` cannot take robot ``spec`` (its backend class's ``refusal``, e.g. PhysX's limits on
    self-collision groups), or None when it can."""
    refusal = getattr(backend_class(name), "refusal", None)
    return refusal(spec) if refusal is not None else None
