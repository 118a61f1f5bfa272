"""Element-wise array operations written as loops, for the kernels.

numba compiles an assignment of one array into another (``a[:] = b``, ``a[i] = b``) through
numpy's broadcasting, with its shape-mismatch messages formatted as strings, and a product of
vectors (``a @ b``) through BLAS with its checks: seconds of compile for each pair of types, and
a larger body at every use (every kernel's compile optimises again the bodies it calls). The
kernels use these instead."""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from llvmlite.binding import add_symbol
from numba import njit, types
from numba.extending import get_cython_function_address, intrinsic

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


# Partitions below this size are finished by insertion sort (numba's quicksort's constant).
SMALL_SORT = 15


@njit(**OPTIONS)
def _before(a, b):
    """numpy's order of floats: NaN last."""
    return a < b or (np.isnan(b) and not np.isnan(a))


@njit(**OPTIONS)
def argsort(values):
    """``np.argsort(values)`` of a float vector, the same order as numba's (its quicksort step
    for step: ties and NaN end where it puts them), written out here: numba compiles its
    generic sort (a list of partitions, assertions) for seconds in every process that compiles
    a caller."""
    n = len(values)
    order = np.empty(n, np.int64)
    for k in range(n):
        order[k] = k
    if n < 2:
        return order
    # the larger side of each partition waits here, the smaller is sorted first: depth < 64
    stack = np.empty((64, 2), np.int64)
    stack[0, 0], stack[0, 1] = 0, n - 1
    depth = 1
    while depth > 0:
        depth -= 1
        low, high = stack[depth, 0], stack[depth, 1]
        while high - low >= SMALL_SORT:
            # median of three {low, middle, high}, stashed at the end
            mid = (low + high) >> 1
            if _before(values[order[mid]], values[order[low]]):
                order[low], order[mid] = order[mid], order[low]
            if _before(values[order[high]], values[order[mid]]):
                order[high], order[mid] = order[mid], order[high]
            if _before(values[order[mid]], values[order[low]]):
                order[low], order[mid] = order[mid], order[low]
            pivot = values[order[mid]]
            order[high], order[mid] = order[mid], order[high]
            i, j = low, high - 1
            while True:
                while i < high and _before(values[order[i]], pivot):
                    i += 1
                while j >= low and _before(pivot, values[order[j]]):
                    j -= 1
                if i >= j:
                    break
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
            order[i], order[high] = order[high], order[i]
            if high - i > i - low:
                if high > i:
                    stack[depth, 0], stack[depth, 1] = i + 1, high
                    depth += 1
                high = i - 1
            else:
                if i > low:
                    stack[depth, 0], stack[depth, 1] = low, i - 1
                    depth += 1
                low = i + 1
        for i in range(low + 1, high + 1):  # insertion sort of order[low:high + 1]
            k = order[i]
            v = values[k]
            j = i
            while j > low and _before(v, values[order[j - 1]]):
                order[j] = order[j - 1]
                j -= 1
            order[j] = k
    return order


# LAPACK's dgesv, the routine np.linalg.solve calls in a kernel, from scipy's Cython exports (the
# same library numba's np.linalg uses), called by symbol name so that callers stay cacheable.
_DGESV = "closure_nlp_dgesv"
add_symbol(_DGESV, get_cython_function_address("scipy.linalg.cython_lapack", "dgesv"))


@intrinsic
def _dgesv(typingctx, n, nrhs, a, lda, ipiv, b, ldb, info):
    """Fortran's ``dgesv(n, nrhs, a, lda, ipiv, b, ldb, info)``, every argument an address."""

    def codegen(context, builder, signature, args):
        pointer = ir.IntType(8).as_pointer()
        function = builder.module.globals.get(_DGESV) or ir.Function(
            builder.module, ir.FunctionType(ir.VoidType(), [pointer] * 8), _DGESV
        )
        builder.call(function, [builder.inttoptr(x, pointer) for x in args])
        return context.get_dummy_value()

    return types.void(n, nrhs, a, lda, ipiv, b, ldb, info), codegen


@njit(**OPTIONS)
def solve(a, b):
    """``np.linalg.solve(a, b)`` for a square ``a`` (n, n) and a vector ``b`` (n,) of finite
    numbers: the same LAPACK call (``dgesv``) on the same column-major copies, so the same bits,
    without numba's checks and their formatted error messages (seconds of compile in every
    caller)."""
    n = len(b)
    lu = np.empty((n, n))  # its rows a's columns: a in column-major order
    for i in range(n):
        for j in range(n):
            lu[j, i] = a[i, j]
    x = np.empty(n)
    copy_into(x, b)
    pivots = np.empty(n, np.int32)
    ints = np.empty(3, np.int32)  # n (also lda and ldb), nrhs, info
    ints[0], ints[1], ints[2] = n, 1, 0
    at = ints.ctypes.data
    _dgesv(at, at + 4, lu.ctypes.data, at, pivots.ctypes.data, x.ctypes.data, at, at + 8)
    # read after the call, so that numba keeps them alive through it
    if ints[2] != 0 or pivots[0] < 1 or not np.isfinite(lu[n - 1, n - 1]):
        fill(x, n, np.nan)  # singular: no solution
    return x
