"""Element-wise array operations written as loops, for the kernels.

numba compiles an assignment of one array into another (``a[:] = b``, ``a[i] = b``) through
numpy's broadcasting, with its shape-mismatch messages formatted as strings, and a product of
vectors (``a @ b``) through BLAS with its checks: seconds of compile for each pair of types, and
a larger body at every use (every kernel's compile optimises again the bodies it calls). The
kernels use these instead."""

from __future__ import annotations

from numba import njit

from .support import OPTIONS


@njit(**OPTIONS)
def copy_into(dst, src):
    """``dst[:len(src)] = src`` for vectors."""
    for k in range(len(src)):
        dst[k] = src[k]


@njit(**OPTIONS)
def copy_rows(dst, start, src):
    """``dst[start:start + len(src)] = src`` for matrices of equal width."""
    for i in range(src.shape[0]):
        for k in range(src.shape[1]):
            dst[start + i, k] = src[i, k]


@njit(**OPTIONS)
def fill(dst, n, value):
    """``dst[:n] = value`` for vectors."""
    for k in range(n):
        dst[k] = value


@njit(**OPTIONS)
def dot(a, b):
    """``a @ b`` for vectors of equal length."""
    s = 0.0
    for k in range(len(a)):
        s += a[k] * b[k]
    return s
