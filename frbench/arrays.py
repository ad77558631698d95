"""The array namespace the batch math runs in: numpy on the host, torch on a device.

The state summaries of the backends, the observation, reward, success, height and curriculum code of the tasks
and of training are written once against the Array API standard through `array-api-compat`: ``xp =
namespace(x)`` and only ``xp`` operations, so numpy arrays go through numpy (the same numpy calls as before, bit
for bit) and torch tensors stay on their device. A backend hands out its arrays in one namespace (numpy for the
CPU simulators, torch on its device for MuJoCo Warp in training); everything above it follows the arrays it is
given. This module sits below every layer (the backends use it too) and holds what that code shares:

* `namespace`, `is_numpy`, `device_of`, `like`, `float_dtype`, `copy_of`, `to_host`: namespaces, devices and
  conversions;
* `resident`: a host constant (a robot's default pose, a raster of terrain heights, a contact layout's index
  arrays) in the namespace and on the device of the arrays it meets, converted once per device, not per step;
* two places where numpy and torch need different calls for the same result: `sum_sq` (row-wise sums of
  squares through ``einsum``, numpy's rounding order of the numpy path) and `cummax` (the running maximum
  along an axis: ``np.maximum.accumulate`` / ``torch.cummax``; the standard has no cumulative maximum).
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

#: Array type → its namespace (`namespace`).
_NAMESPACES: dict = {}
#: Host constants converted by `resident` (key → (the host value, its converted copy)); least recently used first.
_RESIDENT: OrderedDict = OrderedDict()
#: Conversions `resident` keeps (each holds its host value, so an id is never reused while it is kept).
_RESIDENT_SIZE = 256


def namespace(*arrays):
    """The Array API namespace of ``arrays`` (None entries and Python scalars ignored); numpy's when none is
    an array. Kept per array type when all arrays have one (the step's hundreds of calls cost a dict lookup)."""
    if len(arrays) == 1:  # the common call: one array
        kind = type(arrays[0])
        known = _NAMESPACES.get(kind)
        if known is not None:
            return known
    kinds = {type(a) for a in arrays if a is not None and not isinstance(a, (bool, int, float))}
    kind = next(iter(kinds)) if len(kinds) == 1 else None
    known = _NAMESPACES.get(kind)
    if known is not None:
        return known
    from array_api_compat import array_namespace, is_array_api_obj

    found = [a for a in arrays if a is not None and is_array_api_obj(a)]
    xp = array_namespace(*found) if found else array_namespace(np.empty(0))
    if kind is not None:
        _NAMESPACES[kind] = xp
    return xp


def is_numpy(xp) -> bool:
    """Whether ``xp`` is numpy's namespace."""
    from array_api_compat import is_numpy_namespace

    return is_numpy_namespace(xp)


def is_host(x) -> bool:
    """Whether ``x`` is a numpy array (or a scalar / sequence, which numpy reads)."""
    return isinstance(x, (np.ndarray, np.generic, float, int, bool, list, tuple))


def device_of(x):
    """The device of array ``x`` ("cpu" for numpy)."""
    if isinstance(x, np.ndarray):
        return "cpu"
    found = getattr(x, "device", None)
    if found is not None and not callable(found):
        return found
    from array_api_compat import device

    return device(x)


def like(value, ref, dtype=None):
    """``value`` (an array of any namespace, a sequence or a scalar) as an array of ``ref``'s namespace and device,
    of ``dtype`` (default ``ref``'s dtype); ``value`` itself when it already is one (no copy)."""
    xp = namespace(ref)
    return xp.asarray(value, dtype=ref.dtype if dtype is None else dtype, device=device_of(ref))


def float_dtype(xp, ref=None):
    """The floating dtype the math runs in: float64 for numpy (as always), ``ref``'s dtype for torch when it
    is floating (float32 on a GPU), else the namespace's default."""
    if is_numpy(xp):
        return xp.float64
    if ref is not None and xp.isdtype(ref.dtype, "real floating"):
        return ref.dtype
    return xp.float32


def copy_of(x):
    """A copy of array ``x`` in its own namespace and on its device (``x.copy()`` for numpy)."""
    if isinstance(x, np.ndarray):
        return x.copy()
    return namespace(x).asarray(x, copy=True)


def to_host(x):
    """``x`` as a numpy array (a torch tensor copied from its device; a numpy array or scalar itself)."""
    if is_host(x):
        return np.asarray(x)
    return x.detach().cpu().numpy()


def resident(value, ref, dtype=None):
    """The host constant ``value`` (a numpy array, sequence or scalar) as an array of ``ref``'s namespace and device
    (`like`), converted once per device and dtype and kept (at most `_RESIDENT_SIZE` conversions, least recently
    used dropped first): for values that are never changed in place, read at every step. For numpy ``ref``: ``value``
    as a numpy array of ``dtype`` (itself when it is one already)."""
    if is_host(ref):
        return np.asarray(value) if dtype is None else np.asarray(value, dtype=dtype)
    dtype = ref.dtype if dtype is None else dtype
    key = (id(value), str(device_of(ref)), str(dtype))
    found = _RESIDENT.get(key)
    if found is not None and found[0] is value:
        _RESIDENT.move_to_end(key)
        return found[1]
    converted = like(np.array(value), ref, dtype)  # a copy: the device's array never shares the host constant
    _RESIDENT[key] = (value, converted)
    if len(_RESIDENT) > _RESIDENT_SIZE:
        _RESIDENT.popitem(last=False)
    return converted


def sum_sq(x):
    """Row-wise sum of squares over the last axis of an (…, k) array, (…,); numpy's ``einsum`` order on numpy."""
    xp = namespace(x)
    return xp.einsum("...i,...i->...", x, x)


def cummax(x, axis: int = 0):
    """The running maximum of ``x`` along ``axis``."""
    xp = namespace(x)
    if is_numpy(xp):
        return np.maximum.accumulate(x, axis=axis)
    import torch

    return torch.cummax(x, dim=axis).values
