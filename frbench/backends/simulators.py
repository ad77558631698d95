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


def make_simulator(name: str, spec, num_envs: int, terrain=None, variants=None):
    """The backend of simulator ``name`` (a key of `BACKENDS`) running ``num_envs`` simulations of ``spec`` on
    ``terrain``; ``variants``: see `frbench.backends.make_backend`."""
    cls = backend_class(name)
    if variants is None:
        return cls(spec, num_envs, terrain=terrain)
    return cls(spec, num_envs, terrain=terrain, variants=variants)


def simulator_refusal(name: str, spec) -> str | None:
    """Why simulator ``name`` cannot take robot ``spec`` (its backend class's ``refusal``, e.g. PhysX's limits on
    self-collision groups), or None when it can."""
    refusal = getattr(backend_class(name), "refusal", None)
    return refusal(spec) if refusal is not None else None
