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
# Thin wrappers, inlined where they are called: a call that passes arrays costs more than a
# support point's arithmetic (reference counts of every array).
WRAPPER = {**OPTIONS, "inline": "always"}


# Scratch columns per row (:func:`scratch`): ``G^T u`` (4), the square of its largest friction
# piece, that piece, the row's value, whether its wrench enters the support point.
D_Q, D_PIECE, D_VALUE, D_CHOSEN = 4, 5, 6, 7


@njit(**OPTIONS)
def scratch(f):
    """The per-row scratch (K, 8) of :func:`set_value`: callers allocate it once, not per
    direction."""
    return np.empty((len(f), 8))


@njit(**OPTIONS)
def set_value(G, f, W, npc, ends, u, D, out, slots, rows):
    """``p(u)`` (eq 26: the sum of the positive slot values, else the largest) of one unit
    direction ``u`` (6,); ``D`` (K, 8) scratch (:func:`scratch`) holds each row's terms after.

    ``out`` (6,) gets a wrench of the set attaining ``p(u)`` (the sum of the chosen slots'
    support wrenches: the gradient where unique), ``slots`` (m,) the slot values ``P_i`` (eq
    36) and ``rows`` (K, 6) every row's support wrench, each unless None (numba compiles a
    version per combination, the unused branches pruned).

    One flat function, no call per row: in numba a call that passes arrays costs more than a
    row's arithmetic (reference counts), and this runs for every direction of every search.
    """
    K = len(f)
    for r in range(K):
        for c in range(4):
            s = 0.0
            for k in range(6):
                s += G[r, k, c] * u[k]
            D[r, c] = s
        piece, q = 0, 0.0
        for k in range(npc[r]):
            qk = 0.0
            for c in range(4):
                qk += W[r, k, c] * D[r, c] * D[r, c]
            if k == 0 or qk > q:  # the first of equal pieces
                piece, q = k, qk
        D[r, D_Q] = q
        D[r, D_PIECE] = piece
        D[r, D_VALUE] = f[r] * (D[r, 0] + np.sqrt(max(q, 0.0)))
        D[r, D_CHOSEN] = 0.0
    total, top, top_row = 0.0, -np.inf, ends[0]
    any_positive = False
    for i in range(len(ends) - 1):
        best, at = -np.inf, ends[i]
        for r in range(ends[i], ends[i + 1]):
            if D[r, D_VALUE] > best:  # the first of equal rows
                best, at = D[r, D_VALUE], r
        if slots is not None:
            slots[i] = best
        if best > 0.0:
            total += best
            any_positive = True
            D[at, D_CHOSEN] = 1.0
        if best > top:
            top, top_row = best, at
    if not any_positive:
        D[top_row, D_CHOSEN] = 1.0
    if out is not None:
        for k in range(6):
            out[k] = 0.0
    if out is not None or rows is not None:
        for r in range(K):
            chosen = out is not None and D[r, D_CHOSEN] > 0.0
            if not chosen and rows is None:
                continue
            # the row's support force f (e_n + W[piece] d / sqrt(q)), then G_r times it
            q, piece = D[r, D_Q], int(D[r, D_PIECE])
            inv = 1.0 / np.sqrt(q) if q > 0.0 else 0.0
            for k in range(6):
                s = 0.0
                for c in range(4):
                    force = f[r] * W[r, piece, c] * D[r, c] * inv
                    if c == 0:
                        force += f[r]
                    s += G[r, k, c] * force
                if rows is not None:
                    rows[r, k] = s
                if chosen:
                    out[k] += s
    return total + min(top, 0.0)


@njit(**WRAPPER)
def support_value(G, f, W, npc, ends, u, D):
    """``p(u)`` of one direction (6,), without the support point; ``D`` scratch."""
    return set_value(G, f, W, npc, ends, u, D, None, None, None)


@njit(**WRAPPER)
def support_point(G, f, W, npc, ends, u, out, D):
    """``p(u)`` of one direction (6,); fills ``out`` (6,) with a wrench of the set attaining
    it; ``D`` scratch."""
    return set_value(G, f, W, npc, ends, u, D, out, None, None)


@njit(**OPTIONS)
def support_many(G, f, W, npc, ends, U):
    """``p`` of every row of ``U`` (N, 6): (N,)."""
    out = np.empty(len(U))
    D = scratch(f)
    for n in range(len(U)):
        out[n] = support_value(G, f, W, npc, ends, U[n], D)
    return out


@njit(**OPTIONS)
def evaluate_many(G, f, W, npc, ends, U):
    """``p`` and a support point of every row of ``U`` (N, 6): (N,), (N, 6)."""
    values = np.empty(len(U))
    points = np.empty((len(U), 6))
    D = scratch(f)
    for n in range(len(U)):
        values[n] = support_point(G, f, W, npc, ends, U[n], points[n], D)
    return values, points


@njit(**OPTIONS)
def rows_many(G, f, W, npc, ends, U):
    """Row values (N, K) and each row's largest friction piece (N, K) int."""
    K = len(f)
    values = np.empty((len(U), K))
    pieces = np.empty((len(U), K), np.int64)
    D = scratch(f)
    for n in range(len(U)):
        support_value(G, f, W, npc, ends, U[n], D)
        for r in range(K):
            values[n, r], pieces[n, r] = D[r, D_VALUE], int(D[r, D_PIECE])
    return values, pieces


@njit(**OPTIONS)
def row_wrenches_many(G, f, W, npc, ends, U):
    """Row values (N, K) and each row's support wrench (N, K, 6)."""
    K = len(f)
    values = np.empty((len(U), K))
    wrenches = np.empty((len(U), K, 6))
    D = scratch(f)
    for n in range(len(U)):
        set_value(G, f, W, npc, ends, U[n], D, None, None, wrenches[n])
        for r in range(K):
            values[n, r] = D[r, D_VALUE]
    return values, wrenches


@njit(**OPTIONS)
def slots_many(G, f, W, npc, ends, U):
    """Slot values ``P_i`` (eq 36) of every row of ``U``: (N, m)."""
    out = np.empty((len(U), len(ends) - 1))
    D = scratch(f)
    for n in range(len(U)):
        set_value(G, f, W, npc, ends, U[n], D, None, out[n], None)
    return out
