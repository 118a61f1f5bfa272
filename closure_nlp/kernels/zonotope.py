"""The closed-form load capacity of frictionless contacts (:func:`closure_nlp.zonotope.
frictionless_capacity`, proved there) as one compiled loop over the sets and their
five-subsets: numpy spends most of its time per small determinant, not in its arithmetic."""

from __future__ import annotations

import numpy as np
from numba import njit

from .support import OPTIONS


@njit(**OPTIONS)
def _det(A, n):
    """Determinant of ``A[:n, :n]`` by LU with partial pivoting (overwrites ``A``)."""
    det = 1.0
    for k in range(n):
        p, big = k, abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                p, big = i, abs(A[i, k])
        if big == 0.0:
            return 0.0
        if p != k:
            for c in range(k, n):
                A[k, c], A[p, c] = A[p, c], A[k, c]
            det = -det
        pivot = A[k, k]
        det *= pivot
        for i in range(k + 1, n):
            factor = A[i, k] / pivot
            for c in range(k + 1, n):
                A[i, c] -= factor * A[k, c]
    return det


@njit(**OPTIONS)
def capacity_many(V, subsets, rests, out):
    """``max(0, min_S min(s(n_S), s(-n_S)) / |n_S|)`` of each set ``V[b]`` (m, 6) into
    ``out[b]``: ``subsets`` (C, 5) the five-subsets of full rank candidates, ``rests``
    (C, m - 5) the contacts outside each; a subset whose Gram determinant is at most 1e-16 of
    the product of its generators' squared lengths spans no facet (skipped)."""
    m = V.shape[1]
    dots = np.empty((m, m))  # every pair's dot product, once per set
    gram = np.empty((5, 5))
    A = np.empty((6, 6))
    for b in range(V.shape[0]):
        for i in range(m):
            for k in range(m):
                acc = 0.0
                for c in range(6):
                    acc += V[b, i, c] * V[b, k, c]
                dots[i, k] = acc
        best = np.inf
        for s in range(subsets.shape[0]):
            lengths2 = 1.0
            for i in range(5):
                for k in range(5):
                    gram[i, k] = dots[subsets[s, i], subsets[s, k]]
                lengths2 *= gram[i, i]
            norm2 = _det(gram, 5)
            if not norm2 > 1e-16 * lengths2:
                continue
            up, down = 0.0, 0.0
            for r in range(rests.shape[1]):
                for i in range(5):
                    for c in range(6):
                        A[i, c] = V[b, subsets[s, i], c]
                for c in range(6):
                    A[5, c] = V[b, rests[s, r], c]
                x = _det(A, 6)  # <w_j, n_S>
                if x > 0.0:
                    up += x
                else:
                    down -= x
            value = min(up, down) / np.sqrt(norm2)
            if value < best:
                best = value
        out[b] = best if np.isfinite(best) else 0.0
