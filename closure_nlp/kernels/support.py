"""Compiled support function of wrench slots (paper eqs 26-32, 35-36): values and support points.

The one definition of the formulas that :class:`closure_nlp.wrenches.WrenchSlots` evaluates.
Rows are packed as plain arrays (:class:`~closure_nlp.wrenches.WrenchSlots` holds them):

* ``G`` (K, 6, 4): the grasp matrix of each row;
* ``f`` (K,): its force bound ``f_max``;
* ``W`` (K, 2, 4): its friction pieces, ``npc`` (K,) int how many are real (0 FPC, 1 PCwF and
  SFCe, 2 SFCl): the contact type as an integer, no function passed around;
* ``ends`` (m + 1,) int: slot ``i`` holds rows ``ends[i]:ends[i + 1]``.

Row value: with ``d = G^T u``, ``f (d_n + max_k sqrt(q_k))``, ``q_k = sum_j W[k, j] d_j^2``;
its support force is ``f (e_n + W[k*] d / sqrt(q_k*))`` (the rim's point, none at ``q = 0``).
Slot value: the max over its rows. The whole set (eq 26): the sum of the positive slot values,
or the largest when none is positive; its support point sums the chosen slots' wrenches.
"""

from __future__ import annotations

import numpy as np
from numba import njit

OPTIONS = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}


@njit(**OPTIONS)
def row_value(G, f, W, npc, r, u, d):
    """Value of row ``r`` at ``u``; fills ``d`` (4,) with ``G_r^T u``; returns (value, piece,
    square of the largest piece)."""
    for c in range(4):
        s = 0.0
        for k in range(6):
            s += G[r, k, c] * u[k]
        d[c] = s
    piece, q = 0, 0.0
    for k in range(npc[r]):
        qk = 0.0
        for c in range(4):
            qk += W[r, k, c] * d[c] * d[c]
        if k == 0 or qk > q:  # the first of equal pieces
            piece, q = k, qk
    return f[r] * (d[0] + np.sqrt(max(q, 0.0))), piece, q


@njit(**OPTIONS)
def add_row_wrench(G, f, W, r, d, piece, q, weight, out):
    """``out += weight * `` the support wrench of row ``r`` from its ``d``, piece and square."""
    force = np.empty(4)
    inv = 1.0 / np.sqrt(q) if q > 0.0 else 0.0
    for c in range(4):
        force[c] = f[r] * W[r, piece, c] * d[c] * inv
    force[0] += f[r]
    for k in range(6):
        s = 0.0
        for c in range(4):
            s += G[r, k, c] * force[c]
        out[k] += weight * s


@njit(**OPTIONS)
def combine(P):
    """Eq 26 in O(m): the sum of the positive slot values, else the largest."""
    total, top = 0.0, -np.inf
    for v in P:
        if v > 0.0:
            total += v
        if v > top:
            top = v
    return total + min(top, 0.0)


@njit(**OPTIONS)
def support_value(G, f, W, npc, ends, u):
    """``p(u)`` of one direction (6,), without the support point."""
    d = np.empty(4)
    m = len(ends) - 1
    total, top = 0.0, -np.inf
    for i in range(m):
        best = -np.inf
        for r in range(ends[i], ends[i + 1]):
            v = row_value(G, f, W, npc, r, u, d)[0]
            if v > best:
                best = v
        if best > 0.0:
            total += best
        if best > top:
            top = best
    return total + min(top, 0.0)


@njit(**OPTIONS)
def support_point(G, f, W, npc, ends, u, out):
    """``p(u)`` of one direction (6,); fills ``out`` (6,) with a wrench of the set attaining
    it (the sum of the chosen slots' support wrenches: the gradient where unique)."""
    d = np.empty(4)
    m = len(ends) - 1
    P = np.empty(m)
    rows = np.empty(m, np.int64)
    for i in range(m):
        best, at = -np.inf, ends[i]
        for r in range(ends[i], ends[i + 1]):
            v = row_value(G, f, W, npc, r, u, d)[0]
            if v > best:  # the first of equal rows
                best, at = v, r
        P[i], rows[i] = best, at
    out[:] = 0.0
    any_positive = False
    top = 0
    for i in range(m):
        if P[i] > P[top]:
            top = i
        if P[i] > 0.0:
            any_positive = True
    for i in range(m):
        if P[i] > 0.0 or (not any_positive and i == top):
            value, piece, q = row_value(G, f, W, npc, rows[i], u, d)
            add_row_wrench(G, f, W, rows[i], d, piece, q, 1.0, out)
    return combine(P)


@njit(**OPTIONS)
def support_many(G, f, W, npc, ends, U):
    """``p`` of every row of ``U`` (N, 6): (N,)."""
    out = np.empty(len(U))
    for n in range(len(U)):
        out[n] = support_value(G, f, W, npc, ends, U[n])
    return out


@njit(**OPTIONS)
def evaluate_many(G, f, W, npc, ends, U):
    """``p`` and a support point of every row of ``U`` (N, 6): (N,), (N, 6)."""
    values = np.empty(len(U))
    points = np.empty((len(U), 6))
    for n in range(len(U)):
        values[n] = support_point(G, f, W, npc, ends, U[n], points[n])
    return values, points


@njit(**OPTIONS)
def rows_many(G, f, W, npc, U):
    """Row values (N, K) and each row's largest friction piece (N, K) int."""
    K = len(f)
    values = np.empty((len(U), K))
    pieces = np.empty((len(U), K), np.int64)
    d = np.empty(4)
    for n in range(len(U)):
        for r in range(K):
            v, piece, _ = row_value(G, f, W, npc, r, U[n], d)
            values[n, r], pieces[n, r] = v, piece
    return values, pieces


@njit(**OPTIONS)
def row_wrenches_many(G, f, W, npc, U):
    """Row values (N, K) and each row's support wrench (N, K, 6)."""
    K = len(f)
    values = np.empty((len(U), K))
    wrenches = np.zeros((len(U), K, 6))
    d = np.empty(4)
    for n in range(len(U)):
        for r in range(K):
            v, piece, q = row_value(G, f, W, npc, r, U[n], d)
            values[n, r] = v
            add_row_wrench(G, f, W, r, d, piece, q, 1.0, wrenches[n, r])
    return values, wrenches


@njit(**OPTIONS)
def slots_many(G, f, W, npc, ends, U):
    """Slot values ``P_i`` (eq 36) of every row of ``U``: (N, m)."""
    m = len(ends) - 1
    out = np.empty((len(U), m))
    d = np.empty(4)
    for n in range(len(U)):
        for i in range(m):
            best = -np.inf
            for r in range(ends[i], ends[i + 1]):
                v = row_value(G, f, W, npc, r, U[n], d)[0]
                if v > best:
                    best = v
            out[n, i] = best
    return out
