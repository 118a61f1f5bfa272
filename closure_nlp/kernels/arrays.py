"""Element-wise copies written as loops, for the kernels.

numba compiles an assignment of one array into another (``a[:] = b``, ``a[i] = b``) through
numpy's broadcasting, with its shape-mismatch messages formatted as strings: seconds of compile
for each pair of dimensions, and a larger body at every use. The kernels copy with these."""

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
