"""Simulator backends behind one batched protocol (see :mod:`frbench.backends.base`)."""

from __future__ import annotations

from frbench.errors import unknown_name

#: Backend name → "module:Class", imported on first use.
BACKENDS = {
    "mujoco": "frbench.backends.mujoco_backend:MujocoBackend",
    "pybullet": "frbench.backends.pybullet_backend:PybulletBackend",
}


def backend_class(name: str):
    """The backend class registered as ``name``."""
    import importlib

    if name not in BACKENDS:
        raise unknown_name("backend", name, BACKENDS)
    module, _, cls = BACKENDS[name].partition(":")
    return getattr(importlib.import_module(module), cls)


def make_backend(name: str, spec, num_envs: int, terrain=None, variants=None):
    """A backend ``name`` running ``num_envs`` simulations of ``spec`` on ``terrain`` (flat if None).

    ``variants`` (specs, assignment, frictions, payloads): per-simulation robots
    of the same structure (morphology randomisation); see `MujocoBackend`.
    """
    cls = backend_class(name)
    if variants is None:
        return cls(spec, num_envs, terrain=terrain)
    return cls(spec, num_envs, terrain=terrain, variants=variants)
