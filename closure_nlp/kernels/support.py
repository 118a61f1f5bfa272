"""Compiled support function of wrench slots (paper eqs 26-32, 35-36): values and support points.

The one definition of the formulas that :class:`closure_nlp.wrenches.WrenchSlots` evaluates.
Rows are packed as plain arrays (:class:`~closure_nlp.wrenches.WrenchSlots` holds them), each
quantity of every row contiguous (rows last), so that one direction's loops run over the rows
in SIMD lanes:

* ``G`` (6, 4, K): ``G[:, :, r]`` is the grasp matrix of row ``r``;
* ``f`` (K,): its force bound ``f_max``;
* ``W`` (2, 4, K): its friction pieces (``W[k, :, r]``), ``npc`` (K,) int how many are real (0
  FPC, 1 PCwF and SFCe, 2 SFCl): the contact type as an integer, no function passed around;
* ``ends`` (m + 1,) int: slot ``i`` holds rows ``ends[i]:ends[i + 1]``.

Row value: with ``d = G^T u``, ``f (d_n + max_k sqrt(q_k))``, ``q_k = sum_j W[k, j] d_j^2``;
its support force is ``f (e_n + W[k*] d / sqrt(q_k*))`` (the rim's point, none at ``q = 0``).
Slot value: the max over its rows. The whole set (eq 26): the sum of the positive slot values,
or the largest when none is positive; its support point sums the chosen slots' wrenches.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import CACHE

OPTIONS = {"cache": CACHE, "nogil": True, "fastmath": False, "error_model": "numpy"}
# Thin wrappers, inlined where they are called: a call that passes arrays costs more than a
# support point's arithmetic (reference counts of every array).
WRAPPER = {**OPTIONS, "inline": "always"}


# Scratch rows (:func:`scratch`), a value per row in each: ``G^T u`` (4), the square of its
# largest friction piece, that piece, the row's value, whether its wrench enters the support
# point.
D_Q, D_PIECE, D_VALUE, D_CHOSEN = 4, 5, 6, 7
# Sums over the rows (the support point's, eq 26's with a row per slot) may be reordered into
# SIMD lanes: within a few ulps of the sum in row order.
SUMS = {**OPTIONS, "fastmath": {"reassoc", "nsz"}}


@njit(**OPTIONS)
def scratch(f):
    """The per-row scratch (8, K) of :func:`set_value`: callers allocate it once, not per
    direction."""
    return np.empty((8, len(f)))


@njit(**SUMS)
def positive_sum(value, chosen):
    """The sum of the positive ``value`` (K,) (eq 26 with a row per slot; reordered into
    SIMD lanes: within a few ulps of the sum in row order), ``chosen`` (K,) 1 where positive."""
    total = 0.0
    for r in range(len(value)):
        positive = value[r] > 0.0
        chosen[r] = 1.0 if positive else 0.0
        total += value[r] if positive else 0.0
    return total


@njit(**SUMS)
def support_wrench(G, f, W, D, spin, out):
    """The chosen rows' support forces ``f (e_n + W[piece] d / sqrt(q))`` (from the terms
    :func:`set_value` left in ``D``) mapped to one wrench ``out`` (6,); the spin column only
    with ``spin`` (some row has spin friction: others have zero weights there), in a loop of
    its own: inside the first one, its branch kept that loop out of SIMD lanes."""
    o0 = o1 = o2 = o3 = o4 = o5 = 0.0
    for r in range(D.shape[1]):
        q, second = D[D_Q, r], D[D_PIECE, r] > 0.0
        inv = 1.0 / np.sqrt(q) if q > 0.0 else 0.0
        fr = f[r] * D[D_CHOSEN, r]  # zero for the rows left out
        a = fr * (W[1, 0, r] if second else W[0, 0, r]) * D[0, r] * inv + fr
        b = fr * (W[1, 1, r] if second else W[0, 1, r]) * D[1, r] * inv
        c = fr * (W[1, 2, r] if second else W[0, 2, r]) * D[2, r] * inv
        o0 += G[0, 0, r] * a + G[0, 1, r] * b + G[0, 2, r] * c
        o1 += G[1, 0, r] * a + G[1, 1, r] * b + G[1, 2, r] * c
        o2 += G[2, 0, r] * a + G[2, 1, r] * b + G[2, 2, r] * c
        o3 += G[3, 0, r] * a + G[3, 1, r] * b + G[3, 2, r] * c
        o4 += G[4, 0, r] * a + G[4, 1, r] * b + G[4, 2, r] * c
        o5 += G[5, 0, r] * a + G[5, 1, r] * b + G[5, 2, r] * c
    if spin:
        for r in range(D.shape[1]):
            q, second = D[D_Q, r], D[D_PIECE, r] > 0.0
            inv = 1.0 / np.sqrt(q) if q > 0.0 else 0.0
            e = f[r] * D[D_CHOSEN, r] * (W[1, 3, r] if second else W[0, 3, r]) * D[3, r] * inv
            o0 += G[0, 3, r] * e
            o1 += G[1, 3, r] * e
            o2 += G[2, 3, r] * e
            o3 += G[3, 3, r] * e
            o4 += G[4, 3, r] * e
            o5 += G[5, 3, r] * e
    out[0], out[1], out[2], out[3], out[4], out[5] = o0, o1, o2, o3, o4, o5


@njit(**OPTIONS)
def set_value(G, f, W, npc, ends, u, D, out, slots, rows):
    """``p(u)`` (eq 26: the sum of the positive slot values, else the largest) of one unit
    direction ``u`` (6,); ``D`` (8, K) scratch (:func:`scratch`) holds each row's terms after.

    ``out`` (6,) gets a wrench of the set attaining ``p(u)`` (the sum of the chosen slots'
    support wrenches: the gradient where unique), ``slots`` (m,) the slot values ``P_i`` (eq
    36) and ``rows`` (K, 6) every row's support wrench, each unless None or empty. numba
    compiles a version per combination of None and array (the None branches pruned): callers
    pass two, ``out`` alone (the search's, empty for the value alone) or ``slots`` and
    ``rows`` (either empty), each version seconds of every cold compile.

    One flat function, no call per row: in numba a call that passes arrays costs more than a
    row's arithmetic (reference counts), and this runs for every direction of every search.
    Its loops run over the rows, whose numbers lie contiguous (``G`` (6, 4, K)): SIMD lanes,
    faster than a loop over each row's (6, 4) matrix, most of all for many contacts.
    """
    K = len(f)
    u0, u1, u2, u3, u4, u5 = u[0], u[1], u[2], u[3], u[4], u[5]
    # a second friction piece (SFCl), spin friction (soft fingers); not literals: one compile
    two = spin = np.bool_(False)
    for r in range(K):
        two |= npc[r] > 1
        spin |= (W[0, 3, r] != 0.0) | (W[1, 3, r] != 0.0)
    for r in range(K):  # one straight body per row, the rows in SIMD lanes
        d0 = G[0, 0, r] * u0 + G[1, 0, r] * u1 + G[2, 0, r] * u2
        d0 = d0 + G[3, 0, r] * u3 + G[4, 0, r] * u4 + G[5, 0, r] * u5
        d1 = G[0, 1, r] * u0 + G[1, 1, r] * u1 + G[2, 1, r] * u2
        d1 = d1 + G[3, 1, r] * u3 + G[4, 1, r] * u4 + G[5, 1, r] * u5
        d2 = G[0, 2, r] * u0 + G[1, 2, r] * u1 + G[2, 2, r] * u2
        d2 = d2 + G[3, 2, r] * u3 + G[4, 2, r] * u4 + G[5, 2, r] * u5
        q = W[0, 0, r] * d0 * d0 + W[0, 1, r] * d1 * d1  # FPC: zero weights, q = 0
        q = q + W[0, 2, r] * d2 * d2
        D[0, r], D[1, r], D[2, r], D[3, r] = d0, d1, d2, 0.0
        D[D_Q, r], D[D_PIECE, r], D[D_CHOSEN, r] = q, 0.0, 0.0
        D[D_VALUE, r] = f[r] * (d0 + np.sqrt(max(q, 0.0)))
    if spin:  # the spin column (without spin friction its weight is zero: it adds nothing)
        for r in range(K):
            d3 = G[0, 3, r] * u0 + G[1, 3, r] * u1 + G[2, 3, r] * u2
            d3 = d3 + G[3, 3, r] * u3 + G[4, 3, r] * u4 + G[5, 3, r] * u5
            q = D[D_Q, r] + W[0, 3, r] * d3 * d3
            D[3, r], D[D_Q, r] = d3, q
            D[D_VALUE, r] = f[r] * (D[0, r] + np.sqrt(max(q, 0.0)))
    if two:
        for r in range(K):
            d0, d1, d2, d3 = D[0, r], D[1, r], D[2, r], D[3, r]
            q = W[1, 0, r] * d0 * d0 + W[1, 1, r] * d1 * d1
            q = q + W[1, 2, r] * d2 * d2 + W[1, 3, r] * d3 * d3
            if npc[r] > 1 and q > D[D_Q, r]:  # the first of equal pieces
                D[D_Q, r], D[D_PIECE, r] = q, 1.0
                D[D_VALUE, r] = f[r] * (d0 + np.sqrt(max(q, 0.0)))
    value, chosen_ = D[D_VALUE], D[D_CHOSEN]
    total, top, top_row = 0.0, -np.inf, ends[0]
    any_positive = False
    if ends[-1] == len(ends) - 1:  # a row per slot (contacts)
        total = positive_sum(value, chosen_)
        any_positive = total > 0.0
        if slots is not None and len(slots) > 0:
            for r in range(K):
                slots[r] = value[r]
        if any_positive:
            top = 0.0  # the largest is positive: eq 26's sum alone
        else:
            for r in range(K):
                if value[r] > top:  # the first of equal rows
                    top, top_row = value[r], r
    else:
        for i in range(len(ends) - 1):
            best, at = -np.inf, ends[i]
            for r in range(ends[i], ends[i + 1]):
                if value[r] > best:  # the first of equal rows
                    best, at = value[r], r
            if slots is not None and len(slots) > 0:
                slots[i] = best
            if best > 0.0:
                total += best
                any_positive = True
                chosen_[at] = 1.0
            if best > top:
                top, top_row = best, at
    if not any_positive:
        chosen_[top_row] = 1.0
    if rows is not None and len(rows) > 0:
        force = np.empty(4)
        for r in range(K):  # each row's support force f (e_n + W[piece] d / sqrt(q)), wrench
            q, piece = D[D_Q, r], int(D[D_PIECE, r])
            inv = 1.0 / np.sqrt(q) if q > 0.0 else 0.0
            for c in range(4):
                force[c] = f[r] * W[piece, c, r] * D[c, r] * inv
            force[0] += f[r]
            for k in range(6):
                s = 0.0
                for c in range(4):
                    s += G[k, c, r] * force[c]
                rows[r, k] = s
    if out is not None and len(out) > 0:
        support_wrench(G, f, W, D, spin, out)
    return total + min(top, 0.0)


@njit(**WRAPPER)
def no_vector(D):
    """An empty ``out`` or ``slots`` of :func:`set_value` (a view of the scratch ``D``:
    nothing allocated)."""
    return D[0, :0]


@njit(**WRAPPER)
def no_rows(D):
    """An empty ``rows`` of :func:`set_value` (of the type of a (K, 6) array)."""
    return D[:0]


@njit(**WRAPPER)
def support_value(G, f, W, npc, ends, u, D):
    """``p(u)`` of one direction (6,), without the support point; ``D`` scratch."""
    return set_value(G, f, W, npc, ends, u, D, no_vector(D), None, None)


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
            values[n, r], pieces[n, r] = D[D_VALUE, r], int(D[D_PIECE, r])
    return values, pieces


@njit(**OPTIONS)
def row_wrenches_many(G, f, W, npc, ends, U):
    """Row values (N, K) and each row's support wrench (N, K, 6)."""
    K = len(f)
    values = np.empty((len(U), K))
    wrenches = np.empty((len(U), K, 6))
    D = scratch(f)
    for n in range(len(U)):
        set_value(G, f, W, npc, ends, U[n], D, None, no_vector(D), wrenches[n])
        for r in range(K):
            values[n, r] = D[D_VALUE, r]
    return values, wrenches


@njit(**OPTIONS)
def slots_many(G, f, W, npc, ends, U):
    """Slot values ``P_i`` (eq 36) of every row of ``U``: (N, m)."""
    out = np.empty((len(U), len(ends) - 1))
    D = scratch(f)
    for n in range(len(U)):
        set_value(G, f, W, npc, ends, U[n], D, None, out[n], no_rows(D))
    return out
