"""MuJoCo Warp (``mujoco-warp``, the ``gpu`` extra): importing it quietly, the device, buffer sizes, and a
device model with per-world fields, from the ``MjModel`` that `frbench.backends.mujoco_model.build_model`
compiles.

* `import_warp` imports ``warp`` and ``mujoco_warp`` with Warp's log at warnings and errors only (no
  initialisation banner, no "module … load" line per kernel). On a machine with no NVIDIA driver, Warp's native
  library prints "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver" to the process's stderr
  when it initialises; that line, and only in that case (the driver library cannot be loaded), is silenced
  while Warp initialises: there it says nothing but that Warp will run on the CPU, which `warp_device` says too.
* `warp_device`: ``cuda:0`` when Warp sees a GPU, else ``cpu``.
* `buffer_sizes`: contacts (``nconmax``) and constraint rows (``njmax``) per world, from the robot's collision
  geoms and the terrain's kind (below). Warp's defaults overflow for a Go2.
* `put_batched_model`: ``mjw.put_model`` with the named fields given a leading world dimension N (Warp's model
  fields have a leading dimension of 1 otherwise, shared by every world).

Buffer sizes. Warp allocates ``nconmax`` contacts per world (``naconmax`` = N · nconmax for all worlds
together) and ``njmax`` constraint rows per world. A box touching a plane or a box makes at most 4 and 8
contacts, a cylinder 4, a sphere 1; on a box terrain a geom may lie across two boxes. The sizes below are the
sum of those bounds over the robot's collision geoms (``_CONTACTS_PER_GEOM``, doubled on box terrains), far
above what a fallen robot makes (no run in ``docs/gpu.md`` overflowed), and ``njmax`` gives each contact
its 3 rows (elliptic cone, condim 3) plus one row per joint limit. Warp reports an overflow in
``Data.overflow`` (`BUFFER_OVERFLOW_NAMES`, `buffer_overflow_mask`); the backend flags the world
(`frbench.backends.mujoco_warp_backend`). This module imports nothing heavy of frbench's (no terrain or robot
code), so a machine with only mujoco, mujoco-warp and torch can use it.
"""

from __future__ import annotations

import contextlib
import ctypes
import os

import numpy as np

#: MuJoCo model fields in which morphology variants may differ although Warp has no per-world form of them,
#: harmlessly: ``dof_length`` (Warp reads it only for sleeping islands, which frbench's models do not enable);
#: ``body_sameframe``, ``bvh_aabb``, ``dof_M0`` (not in Warp's model: it recomputes frames, bounds and the mass
#: matrix from the per-world fields).
NOT_IN_WARP = frozenset({"body_sameframe", "bvh_aabb", "dof_M0", "dof_length"})
#: Warp's ``OverflowType`` bits that mean a buffer was too small (the physics of that step lacks constraints);
#: the solver's ITERATIONS / LS_ITERATIONS bits are not among them (MuJoCo C stops at its limits too).
BUFFER_OVERFLOW_NAMES = ("NEFC", "NJMAX_NNZ", "BROADPHASE", "NARROWPHASE", "CCD", "HFIELD", "NVMAX", "EPA_HORIZON")
#: Contacts a robot geom of each MuJoCo type can make with one terrain geom (box-box 8, box-plane 4, ...).
_CONTACTS_PER_GEOM = {"box": 8, "cylinder": 4, "capsule": 2, "ellipsoid": 4, "sphere": 1, "mesh": 8}
#: Contacts per world are rounded up to a multiple of this (Warp's tiles prefer round sizes).
_ROUND = 16


def _cuda_driver_present() -> bool:
    """Whether the NVIDIA driver library loads (what Warp tries when it initialises)."""
    for name in ("libcuda.so", "libcuda.so.1", "nvcuda.dll"):
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


@contextlib.contextmanager
def _stderr_silenced():
    """The process's stderr (file descriptor 2, where native code prints) goes to /dev/null in the block."""
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def import_warp():
    """``(warp, mujoco_warp)``, imported and initialised quietly (module docstring); a `FrbenchError` with the
    install command when the ``gpu`` extra is missing."""
    try:
        import mujoco_warp  # noqa: F401  (imported below once Warp is initialised; here: is it installed?)
        import warp as wp
    except ImportError:
        from frbench.errors import FrbenchError

        raise FrbenchError("backend mujoco-warp: MuJoCo Warp is not installed; install it with "
                           "pip install 'frbench[gpu]'") from None
    from warp._src import context

    if context.runtime is None:  # not initialised yet
        wp.config.log_level = wp.LOG_WARNING  # no banner, no per-module load lines; warnings and errors stay
        if _cuda_driver_present():
            wp.init()
        else:  # the one line Warp prints here says only that no driver exists (module docstring)
            with _stderr_silenced():
                wp.init()
    import mujoco_warp as mjw

    return wp, mjw


def warp_device() -> str:
    """``"cuda:0"`` when Warp has a CUDA device, else ``"cpu"``."""
    wp, _ = import_warp()
    return "cuda:0" if wp.is_cuda_available() else "cpu"


def buffer_sizes(model) -> tuple[int, int]:
    """(nconmax, njmax) per world for ``model`` (an ``MjModel`` of `build_model`: the robot's bodies, the
    terrain's geoms on the world body); see the module docstring."""
    import mujoco

    robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0
             and (model.geom_contype[g] or model.geom_conaffinity[g])]
    terrain_types = {int(model.geom_type[g]) for g in range(model.ngeom) if model.geom_bodyid[g] == 0}
    boxes = int(mujoco.mjtGeom.mjGEOM_BOX) in terrain_types or int(mujoco.mjtGeom.mjGEOM_HFIELD) in terrain_types
    per_geom = [_CONTACTS_PER_GEOM.get(mujoco.mjtGeom(int(model.geom_type[g])).name[len("mjGEOM_"):].lower(), 8)
                for g in robot]
    nconmax = int(sum(per_geom)) * (2 if boxes else 1)
    nconmax = -(-nconmax // _ROUND) * _ROUND
    limits = int(np.count_nonzero(model.jnt_limited))
    njmax = -(-(3 * nconmax + limits) // _ROUND) * _ROUND
    return nconmax, njmax


def batchable_fields() -> frozenset[str]:
    """The ``mujoco_warp`` model fields that take one value per world (a leading ``*`` dimension)."""
    import dataclasses

    _, mjw = import_warp()
    from mujoco_warp._src import warp_util

    return frozenset(f.name for f in dataclasses.fields(mjw.Model)
                     if warp_util.is_array_spec(f.type) and tuple(getattr(f.type, "shape", ()))[:1] == ("*",))


def put_batched_model(model, num_worlds: int, fields):
    """``mjw.put_model(model)`` with each of ``fields`` (names of `batchable_fields`) of shape (num_worlds, …),
    every world starting from ``model``'s value, and box–box contacts computed as MuJoCo C computes them.

    Box–box: MuJoCo C collides two boxes with its box–box routine (``mjc_BoxBox``) whatever its native-CCD flag
    says; Warp by default sends them through its general convex path (CCD with polygon clipping), which returns
    other contact points (on 8 settled Go2 starts on stairs, 7 of 35 touching geom pairs with another number of
    contacts), and uses its port of ``mjc_BoxBox`` when ``NATIVECCD`` is disabled — the only thing that flag
    changes in Warp. So it is disabled here, in Warp's copy of the options only: the same pairs then give the
    same contact counts as MuJoCo C (docs/gpu.md)."""
    _, mjw = import_warp()
    warp_model = mjw.put_model(model, batch_sizes={name: int(num_worlds) for name in fields})
    warp_model.opt.disableflags |= int(mjw.DisableBit.NATIVECCD)
    return warp_model


def buffer_overflow_mask() -> int:
    """The OR of Warp's buffer-overflow bits (`BUFFER_OVERFLOW_NAMES`)."""
    _, mjw = import_warp()
    mask = 0
    for name in BUFFER_OVERFLOW_NAMES:
        mask |= int(getattr(mjw.OverflowType, name))
    return mask
