"""The matrix game of a cell with one budget of weights per slot.

``p(u) = sum_i max(P_i(u), 0)`` wherever some slot value ``P_i`` is positive, and ``max(P_i,
0) = max_{0 <= l <= 1} l P_i``: so for support points ``w_ik`` of slot ``i`` (its value at
any direction is at least ``w_ik . u``) and weights ``l_ik >= 0`` with ``sum_k l_ik <= 1`` per
slot, ``p(u) >= sum_ik l_ik w_ik . u`` at every ``u`` where that sum is positive. Each slot
picks its own combination: a contact whose support is sharply curved over a cell (a friction
cone seen nearly along its axis) gets as many points as the cell has directions, independently
of the other slots, where a combination of whole support points (sums over the slots at the
same direction) ties every slot to the same weights.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import fill
from .support import OPTIONS

MAX_PIVOTS = 400
EPS = 1e-9  # pivot and optimality tolerance, on entries scaled to [-1, 1]
GIVE_UP_EVERY = 2  # pivots between the checks of the game's dual bound (each about a pivot)


@njit(**OPTIONS)
def pivot(T, i, j):
    """A simplex pivot of the tableau ``T`` on row ``i`` and column ``j``."""
    p = T[i, j]
    for k in range(T.shape[1]):
        T[i, k] /= p
    for r in range(T.shape[0]):
        if r != i and T[r, j] != 0.0:
            factor = T[r, j]
            for k in range(T.shape[1]):
                T[r, k] -= factor * T[i, k]


@njit(**OPTIONS)
def block_bound(M, block, blocks, T, row, first):
    """An upper bound on the value of :func:`block_game_weights`' game: for any mix ``mu`` of
    the rows (here the tableau's dual estimates in ``T[row, first + c]``, clipped at 0 and
    normalised: the optimal mix at the optimum), ``sum_b max(0, max_{k in b} (mu M)_k)`` (LP
    duality: each block's weights sum to at most 1); +inf when no estimate is positive."""
    C, K = M.shape
    total = 0.0
    for c in range(C):
        total += max(T[row, first + c], 0.0)
    if not total > 0.0:
        return np.inf
    top = np.zeros(blocks)
    for k in range(K):
        v = 0.0
        for c in range(C):
            if T[row, first + c] > 0.0:
                v += T[row, first + c] * M[c, k]
        top[block[k]] = max(top[block[k]], v / total)
    bound = 0.0
    for b in range(blocks):
        bound += top[b]
    return bound


@njit(**OPTIONS)
def block_game_weights(M, block, blocks, lam, stop=np.inf, give_up=-np.inf, mix=None):
    """Weights ``lam`` (K,) >= 0 with ``sum lam[block == b] <= 1`` for every block ``b <
    blocks`` that maximise ``min(min_c (M lam)_c, ...)`` for ``M`` (C, K), by a dense primal
    simplex (Dantzig's rule) from ``lam = 0``: every iterate is feasible, so the weights of a
    capped or early-stopped run still give a valid bound (callers recompute it from them).
    Pivoting ends once the iterate's value reaches ``stop``, or once a mix of the rows shows
    the value below ``give_up`` (:func:`block_bound`). ``mix`` (C,), unless None, gets the
    rows' dual estimates where it stopped, clipped at 0 and normalised (all 0 when none is
    positive): the optimal mix of the rows at the optimum. Returns the pivots taken, as ``-1
    - pivots`` when it gave up."""
    C, K = M.shape
    span = 0.0
    for i in range(C):
        for k in range(K):
            span = max(span, abs(M[i, k]))
    if span == 0.0:
        span = 1.0
    # columns: lam (K), t (1), slacks (C + blocks), right-hand side
    T_col = K
    V = K + 1 + C + blocks
    R = C + blocks
    T = np.zeros((R + 1, V + 1))
    for i in range(C):  # t - (M lam)_i + s_i = 0
        for k in range(K):
            T[i, k] = -M[i, k] / span
        T[i, T_col] = 1.0
        T[i, K + 1 + i] = 1.0
    for b in range(blocks):  # sum of the block's weights + s = 1
        T[C + b, K + 1 + C + b] = 1.0
        T[C + b, V] = 1.0
    for k in range(K):
        T[C + block[k], k] = 1.0
    T[R, T_col] = -1.0  # maximise t
    basis = np.empty(R, np.int64)
    for r in range(R):
        basis[r] = K + 1 + r
    # a start off the degenerate origin: each block's best column (the largest least entry)
    # pivoted into its block's row, then t into the game rows
    for b in range(blocks):
        j, best = np.int64(-1), -np.inf  # not literals: one compile of the callees
        for k in range(K):
            if block[k] == b:
                col = np.inf
                for i in range(C):
                    col = min(col, M[i, k])
                if col > best:
                    best, j = col, k
        if j >= 0:
            pivot(T, C + b, j)
            basis[C + b] = j
    pivots = 0
    gave_up = False
    for _ in range(MAX_PIVOTS):
        if span * T[R, V] >= stop:
            break
        check = pivots % GIVE_UP_EVERY == GIVE_UP_EVERY - 1
        if check and block_bound(M, block, blocks, T, R, K + 1) < give_up:
            gave_up = True
            break
        j, low = np.int64(0), np.inf
        for k in range(V):
            if T[R, k] < low:
                low, j = T[R, k], k
        if not low < -EPS:
            break
        i, ratio = np.int64(-1), np.inf
        for r in range(R):
            if T[r, j] > EPS:
                q = T[r, V] / T[r, j]
                if q < ratio:
                    ratio, i = q, r
        if i < 0:
            break
        pivot(T, i, j)
        basis[i] = j
        pivots += 1
    fill(lam, K, 0.0)
    for r in range(R):
        if basis[r] < K:
            lam[basis[r]] = max(T[r, V], 0.0)
    total = np.zeros(blocks)
    for k in range(K):
        total[block[k]] += lam[k]
    for k in range(K):  # roundoff of the pivots: each block's weights at most 1
        if total[block[k]] > 1.0:
            lam[k] /= total[block[k]]
    if mix is not None:
        spread = 0.0
        for c in range(C):
            mix[c] = max(T[R, K + 1 + c], 0.0)
            spread += mix[c]
        for c in range(C):
            mix[c] = mix[c] / spread if spread > 0.0 else 0.0
    return -1 - pivots if gave_up else pivots
