"""The array namespace the task math runs in: numpy for evaluation, torch on any device for training.

The observation, reward and success code (`frbench.tasks.observations`, `frbench.training.rewards`,
`frbench.tasks.success`) is written once against the Array API standard through `array-api-compat`:
``xp = namespace(x)`` and only ``xp`` operations, so numpy arrays go through numpy (the same numpy calls as
before, bit for bit) and torch tensors stay on their device. This module holds the few helpers that code
shares; two of them are the places where numpy and torch need different calls for the same result:

* `sum_sq`: row-wise sums of squares through ``einsum`` (numpy's rounding order of the numpy path; torch has
  the same ``einsum``);
* `cummax`: the running maximum along an axis (``np.maximum.accumulate`` / ``torch.cummax``; the standard has
  no cumulative maximum).
"""

from __future__ import annotations

import numpy as np


def namespace(*arrays):
    """The Array API namespace of ``arrays`` (None entries and Python scalars ignored); numpy's when none is
    an array."""
    from array_api_compat import array_namespace, is_array_api_obj

    found = [a for a in arrays if a is not None and is_array_api_obj(a)]
    return array_namespace(*found) if found else array_namespace(np.empty(0))


def is_numpy(xp) -> bool:
    """Whether ``xp`` is numpy's namespace."""
    from array_api_compat import is_numpy_namespace

    return is_numpy_namespace(xp)


def device_of(x):
    """The device of array ``x`` ("cpu" for numpy)."""
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
