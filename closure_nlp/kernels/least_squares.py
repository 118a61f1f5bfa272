"""Compiled linear least squares for the small systems of Wolfe's nearest point.

``np.linalg.lstsq`` inside a kernel costs seconds of compile (LAPACK's workspace queries, its
error messages formatted as strings) in every kernel that reaches it; the systems here are at
most ``d x d`` (d = 6 for wrenches). Householder QR with column pivoting solves them.

Accuracy: Householder QR is normwise backward stable for least squares (Higham, *Accuracy and
Stability of Numerical Algorithms*, 2nd ed., Thm 20.3): the computed ``z`` is the exact solution
of a problem with ``|dA| <= c m n eps |A|``, ``|db| <= c m n eps |b|``, hence the same forward
error bound as LAPACK's SVD solver, ``kappa(A) eps + kappa(A)^2 eps |r| / (|A| |z|)`` to first
order, for full-rank ``A``. With column pivoting ``|R_jj|`` decreases, and a column whose
remaining norm is at most ``max(m, n) eps |R_00|`` is taken as dependent (rank deficiency, where
LAPACK's ``rcond=-1`` cuts singular values at ``eps s_max``): its weight is zero, which gives a
least squares solution (a basic one, not the minimum-norm one LAPACK returns; Wolfe's step needs
any minimiser of the residual: the point ``A z`` is the same).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .support import OPTIONS

EPS = np.finfo(np.float64).eps


@njit(**OPTIONS)
def least_squares(A, b, z):
    """``z`` (n,) minimising ``|A z - b|`` for ``A`` (m, n), ``b`` (m,); ``A`` and ``b`` are
    overwritten (their QR factors). Returns the numerical rank."""
    m, n = A.shape
    perm = np.empty(n, np.int64)
    for c in range(n):
        perm[c] = c
    cut, rank = 0.0, 0
    for j in range(min(m, n)):
        # pivot: the column with the largest remaining norm (recomputed: tiny systems)
        p, best = j, -1.0
        for c in range(j, n):
            s = 0.0
            for i in range(j, m):
                s += A[i, c] * A[i, c]
            if s > best:
                p, best = c, s
        if p != j:
            perm[j], perm[p] = perm[p], perm[j]
            for i in range(m):
                A[i, j], A[i, p] = A[i, p], A[i, j]
        alpha = np.sqrt(best)
        if j == 0:
            cut = max(m, n) * EPS * alpha
        if not alpha > cut:
            break
        # reflection taking A[j:, j] to (r, 0, ...), r = -sign(x0) alpha; v = x - r e_0
        x0 = A[j, j]
        r = -alpha if x0 >= 0.0 else alpha
        v0 = x0 - r
        vv = 2.0 * alpha * (alpha + abs(x0))  # |v|^2
        for c in range(j + 1, n):
            t = v0 * A[j, c]
            for i in range(j + 1, m):
                t += A[i, j] * A[i, c]
            t *= 2.0 / vv
            A[j, c] -= t * v0
            for i in range(j + 1, m):
                A[i, c] -= t * A[i, j]
        t = v0 * b[j]
        for i in range(j + 1, m):
            t += A[i, j] * b[i]
        t *= 2.0 / vv
        b[j] -= t * v0
        for i in range(j + 1, m):
            b[i] -= t * A[i, j]
        A[j, j] = r
        rank += 1
    for c in range(n):
        z[c] = 0.0
    for j in range(rank - 1, -1, -1):
        s = b[j]
        for c in range(j + 1, rank):
            s -= A[j, c] * z[perm[c]]
        z[perm[j]] = s / A[j, j]
    return rank
