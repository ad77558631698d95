"""Small float64 vector products whose last bits do not depend on the processor.

numpy hands ``a @ b``, ``np.dot`` and ``np.linalg.norm`` of float64 vectors to its BLAS, in numpy's wheels
OpenBLAS, which picks its kernels by processor at run time. For the dot products of a few elements that
frbench's episodes take (norms of quaternions and joint axes, a transposed 3 x 3 rotation times a vector),
OpenBLAS's ``Haswell`` kernels (every AVX2 x86-64 without AVX-512: Haswell and later Intel, AMD Zen 1-3)
round each product and add them in index order, while its ``SkylakeX`` kernels (AVX-512 machines, Intel
Skylake-X and later, AMD Zen 4) fuse each multiply into the add (one rounding fewer). The two differ in the
last bit for about one input in ten, and a chaotic episode (a fall on steep slopes) turns that bit into another
trajectory: a record made on one kind of machine did not verify on the other (docs/protocol.md, "Where a
processor changed the numbers"). ``OPENBLAS_CORETYPE=SkylakeX`` or ``Haswell`` picks a kernel on any x86-64.

The functions here compute those products with numpy's elementwise multiply and add, which round each
operation as IEEE 754 prescribes on every processor, in the Haswell kernels' order: the products rounded,
then added from the first to the last. So they give, on every processor and with any BLAS, the numbers that
the records made on Haswell-kernel machines hold (tests/test_portable_products.py checks them bit for bit
against OpenBLAS's Haswell kernel and an episode under both kernels).
"""

from __future__ import annotations

import numpy as np


def dot(a, b) -> np.ndarray:
    """Σ_k a[..., k] · b[..., k] over the last axis (broadcast), the products rounded and added in index order.

    Equals OpenBLAS's Haswell ``ddot`` (numpy's ``a @ b`` of two float64 vectors on such a machine) for fewer
    than 32 elements. Shapes: (..., n) and (..., n) -> (...).
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    products = a * b
    total = np.zeros(products.shape[:-1])
    for k in range(products.shape[-1]):
        total = total + products[..., k]
    return total


def norm(v) -> np.ndarray:
    """Euclidean norm over the last axis, √(`dot` (v, v)): ``np.linalg.norm(v)`` of a vector on a Haswell-kernel
    machine. Shape (..., n) -> (...)."""
    return np.sqrt(dot(v, v))


def unit(v) -> np.ndarray:
    """``v / norm(v)`` over the last axis (a quaternion, a joint axis). Shape (..., n) -> (..., n)."""
    v = np.asarray(v, dtype=np.float64)
    return v / norm(v)[..., None]


def transposed_times(matrix, v) -> np.ndarray:
    """``matrix.T @ v`` of a 3 x 3 (or m x n) ``matrix`` and a vector: y[j] = Σ_k matrix[k, j] v[k] by `dot`.

    Equals OpenBLAS's Haswell ``dgemv`` of a transposed 3 x 3 float64 matrix (what numpy calls for
    ``rotation.T @ vector``). Shapes: (..., m, n) and (..., m) -> (..., n).
    """
    matrix, v = np.asarray(matrix, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return dot(np.swapaxes(matrix, -1, -2), v[..., None, :])
