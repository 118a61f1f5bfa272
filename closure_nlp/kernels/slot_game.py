"""Matrix games by a dense simplex whose tableau outlives a solve: a row or a column added to a
solved game re-enters from its last basis, the game a cell's bound grows a corner or a support
point at a time.

The game: weights ``lam`` (K,) >= 0, in blocks whose weights sum to at most 1 (or exactly 1, a
convex game), that maximise ``min_c (M lam)_c`` for ``M`` (C, K); simplex on ``(M - low) /
span``. Its tableau (:func:`game_tableau`): row 0 the objective, rows ``1 .. blocks`` the
blocks, ``1 + blocks + c`` game row ``c``; column 0 the right-hand side, 1 the value ``t``
(free: once basic it never leaves), ``2 .. 1 + blocks`` the blocks' slacks (an exact block's
never enters), ``2 + blocks + c`` game row ``c``'s slack, then the weights. The slack columns
hold the inverse of the basis: a column added later is priced from them.

A row added to a game leaves its new slack basic, negative where the weights leave the row
below the value: dual simplex pivots restore it in an optimal game (its basis stays dual
feasible), primal pivots on the negative basic variables in a game stopped early. A column
added leaves a feasible basis feasible: primal pivots go on.

Also the game of a cell with one budget of weights per slot. ``p(u) = sum_i max(P_i(u), 0)``
wherever some slot value ``P_i`` is positive, and ``max(P_i, 0) = max_{0 <= l <= 1} l P_i``:
so for support points ``w_ik`` of slot ``i`` (its value at any direction is at least ``w_ik .
u``) and weights ``l_ik >= 0`` with ``sum_k l_ik <= 1`` per slot, ``p(u) >= sum_ik l_ik w_ik .
u`` at every ``u`` where that sum is positive. Each slot picks its own combination: a contact
whose support is sharply curved over a cell (a friction cone seen nearly along its axis) gets
as many points as the cell has directions, independently of the other slots, where a
combination of whole support points (sums over the slots at the same direction) ties every
slot to the same weights.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import fill
from .support import OPTIONS

MAX_PIVOTS = 400
EPS = 1e-9  # pivot and optimality tolerance, on entries scaled to [-1, 1]
GIVE_UP_EVERY = 2  # pivots between the checks of the game's dual bound (each about a pivot)
# A basic variable below this (scaled) is infeasible: the dual simplex pivots it out. Far
# under the pivots' tolerance: a solve's roundoff, not a violated row.
FEASIBLE = 1e-13


@njit(**OPTIONS)
def game_tableau(rows, columns, blocks):
    """An empty tableau and basis for games of up to ``rows`` rows and ``columns`` columns."""
    T = np.zeros((1 + blocks + rows, 2 + blocks + rows + columns))
    return T, np.empty(1 + blocks + rows, np.int64)


@njit(**OPTIONS)
def tableau_pivot(T, basis, i, j, blocks, C, K):
    """A simplex pivot on row ``i`` and column ``j`` over the tableau's live part (``C`` game
    rows, ``K`` weights)."""
    R = 1 + blocks + C
    S = 2 + blocks + C  # columns before the unused slacks
    L0 = 2 + blocks + (T.shape[0] - 1 - blocks)
    p = T[i, j]
    for k in range(S):
        T[i, k] /= p
    for k in range(L0, L0 + K):
        T[i, k] /= p
    for r in range(R):
        if r != i and T[r, j] != 0.0:
            factor = T[r, j]
            for k in range(S):
                T[r, k] -= factor * T[i, k]
            for k in range(L0, L0 + K):
                T[r, k] -= factor * T[i, k]
    basis[i] = j


@njit(**OPTIONS)
def game_open(M, block, blocks, exact, T, basis):
    """A fresh game of ``M`` (C, K) in ``T``: a convex game (``exact``, one block whose weights
    sum to 1) scaled to [0, 1], else scaled by its largest entry; each block's best column
    (the largest least entry) pivoted into its block's row, a start off the degenerate origin.
    Returns ``(low, span)``, the scaling that rows and columns added later keep."""
    C, K = M.shape
    low, high, top = np.inf, -np.inf, 0.0
    for c in range(C):
        for k in range(K):
            low, high = min(low, M[c, k]), max(high, M[c, k])
            top = max(top, abs(M[c, k]))
    if exact:
        span = high - low if high > low else 1.0
    else:
        low, span = 0.0, top if top > 0.0 else 1.0
    L0 = 2 + blocks + (T.shape[0] - 1 - blocks)
    for r in range(1 + blocks + C):
        fill(T[r], T.shape[1], 0.0)
    T[0, 1] = -1.0  # maximise t
    for b in range(blocks):  # the block's weights + its slack = 1
        T[1 + b, 0] = 1.0
        T[1 + b, 2 + b] = 1.0
        basis[1 + b] = 2 + b
    for k in range(K):
        T[1 + block[k], L0 + k] = 1.0
    for c in range(C):  # t - (M' lam)_c + s_c = 0
        r = 1 + blocks + c
        for k in range(K):
            T[r, L0 + k] = -(M[c, k] - low) / span
        T[r, 1] = 1.0
        T[r, 2 + blocks + c] = 1.0
        basis[r] = 2 + blocks + c
    for b in range(blocks):
        j, best = np.int64(-1), -np.inf  # not literals: one compile of the callees
        for k in range(K):
            if block[k] == b:
                col = np.inf
                for c in range(C):
                    col = min(col, M[c, k])
                if col > best:
                    best, j = col, k
        if j >= 0:
            tableau_pivot(T, basis, 1 + b, L0 + j, blocks, C, K)
    return low, span


@njit(**OPTIONS)
def game_add_row(M, block, blocks, T, basis, low, span):
    """Game row ``C - 1`` of ``M`` (C, K) into an optimal game of the other rows, in its
    basis (its slack basic, negative where the weights leave the row below the value)."""
    C, K = M.shape
    c = C - 1
    r = 1 + blocks + c
    L0 = 2 + blocks + (T.shape[0] - 1 - blocks)
    fill(T[r], T.shape[1], 0.0)
    T[r, 1] = 1.0
    T[r, 2 + blocks + c] = 1.0
    for k in range(K):
        T[r, L0 + k] = -(M[c, k] - low) / span
    S = 2 + blocks + C
    for q in range(1, r):  # eliminate the basic columns (unit columns of the tableau)
        a = T[r, basis[q]]
        if a != 0.0:
            for k in range(S):
                T[r, k] -= a * T[q, k]
            for k in range(L0, L0 + K):
                T[r, k] -= a * T[q, k]
            T[r, basis[q]] = 0.0
    basis[r] = 2 + blocks + c


@njit(**OPTIONS)
def game_add_column(M, block, blocks, T, basis, low, span):
    """Column ``K - 1`` of ``M`` (C, K) into a game of the other columns: the tableau's
    column is the basis' inverse (the slack columns) times the column's constraints."""
    C, K = M.shape
    k = K - 1
    L0 = 2 + blocks + (T.shape[0] - 1 - blocks)
    for r in range(1 + blocks + C):
        s = T[r, 2 + block[k]]
        for c in range(C):
            s -= T[r, 2 + blocks + c] * ((M[c, k] - low) / span)
        T[r, L0 + k] = s


@njit(**OPTIONS)
def game_grow_row(M, block, blocks, exact, T, basis, low, span, warm):
    """Game row ``C - 1`` of ``M`` (C, K) into the game in ``T``: by :func:`game_add_row` when
    the last solve left the tableau ``warm``, else the whole game opened afresh
    (:func:`game_open`). Returns ``(low, span)``."""
    if not warm:
        return game_open(M, block, blocks, exact, T, basis)
    game_add_row(M, block, blocks, T, basis, low, span)
    return low, span


@njit(**OPTIONS)
def game_grow_columns(M, block, blocks, exact, T, basis, low, span, warm, first):
    """Columns ``first .. K - 1`` of ``M`` (C, K) into the game in ``T``, as
    :func:`game_grow_row` adds a row."""
    if not warm:
        return game_open(M, block, blocks, exact, T, basis)
    for k in range(first, M.shape[1]):
        game_add_column(M[:, : k + 1], block[: k + 1], blocks, T, basis, low, span)
    return low, span


@njit(**OPTIONS)
def mix_bound(M, block, blocks, exact, T):
    """An upper bound on the game's value from the tableau's dual estimates of its rows
    (``T[0]``'s slack columns, clipped at 0 and normalised: the optimal mix at the optimum):
    for any mix ``mu`` of the rows, ``sum_b max_{k in b} (mu M)_k`` (LP duality), each term
    at least 0 unless the game is ``exact``; +inf when no estimate is positive."""
    C, K = M.shape
    first = 2 + blocks
    total = 0.0
    for c in range(C):
        total += max(T[0, first + c], 0.0)
    if not total > 0.0:
        return np.inf
    top = np.empty(blocks)
    fill(top, blocks, -np.inf if exact else 0.0)
    for k in range(K):
        v = 0.0
        for c in range(C):
            if T[0, first + c] > 0.0:
                v += T[0, first + c] * M[c, k]
        top[block[k]] = max(top[block[k]], v / total)
    bound = 0.0
    for b in range(blocks):
        bound += top[b]
    return bound


@njit(**OPTIONS)
def game_solve(M, block, blocks, exact, T, basis, low, span, lam, stop, give_up, max_pivots,
               eps, mix):  # fmt: skip
    """Pivots of the game in ``T`` (:func:`game_open`, :func:`game_add_row`,
    :func:`game_add_column`) until optimal, until the value reaches ``stop``, until a mix of
    the rows shows it below ``give_up`` (:func:`mix_bound`), or after ``max_pivots``: while a
    basic variable is negative (rows added), dual simplex pivots if the basis is dual feasible
    (rows added to an optimal game), else primal pivots on the sum of the negative ones
    (rows added to a game stopped early); then primal pivots (Dantzig's rule). Fills ``lam``
    (K,) with feasible weights wherever it stopped (clipped, an exact game's normalised, a
    block's scaled down to 1: any such weights give a valid bound) and ``mix`` (C,) with the
    rows' dual estimates, clipped at 0 and normalised. Returns ``(pivots, warm)``, pivots as
    ``-1 - pivots`` when it gave up; ``warm`` whether rows and columns may be added to the
    tableau (its value ``t`` is basic; else the next change starts afresh)."""
    C, K = M.shape
    R = 1 + blocks + C
    S = 2 + blocks + C
    L0 = 2 + blocks + (T.shape[0] - 1 - blocks)
    shut = 2 + blocks if exact else 2  # columns 2 .. shut - 1 never enter
    # the columns that may enter, in scan order: the live slacks, then the weights
    cols = np.empty(S - shut + K, np.int64)
    for m in range(S - shut):
        cols[m] = shut + m
    for m in range(K):
        cols[S - shut + m] = L0 + m
    pivots = 0
    gave_up = False
    warm = False  # a fresh game starts with t at 0, out of the basis: primal pivots alone
    for r in range(1, R):
        warm |= basis[r] == 1
    dual = True
    for k in cols:
        dual &= T[0, k] >= -eps
    sums = np.empty(T.shape[1])
    feasible = not warm
    while warm and pivots < max_pivots:
        i, worst = np.int64(-1), -FEASIBLE  # the most negative basic variable
        for r in range(1, R):
            if basis[r] != 1 and T[r, 0] < worst:  # t is free
                worst, i = T[r, 0], r
        if i < 0:
            feasible = True
            break
        check = pivots % GIVE_UP_EVERY == GIVE_UP_EVERY - 1
        if check and mix_bound(M, block, blocks, exact, T) < give_up:
            gave_up = True
            break
        j = np.int64(-1)
        if dual:  # the entering column keeps the reduced costs non-negative
            ratio = np.inf
            for k in cols:
                if T[i, k] < -eps:
                    q = max(T[0, k], 0.0) / -T[i, k]
                    if q < ratio:
                        ratio, j = q, k
        else:  # the column that raises the negative basic variables' sum fastest
            fill(sums, len(sums), 0.0)
            for r in range(1, R):
                if basis[r] != 1 and T[r, 0] < -FEASIBLE:
                    for k in cols:
                        sums[k] += T[r, k]
            least = -eps
            for k in cols:
                if sums[k] < least:
                    least, j = sums[k], k
            if j >= 0:  # the first basic variable to reach 0, feasible or not
                i, ratio = np.int64(-1), np.inf
                for r in range(1, R):
                    if basis[r] == 1:
                        continue
                    if T[r, 0] >= -FEASIBLE and T[r, j] > eps:
                        q = max(T[r, 0], 0.0) / T[r, j]
                    elif T[r, 0] < -FEASIBLE and T[r, j] < -eps:
                        q = T[r, 0] / T[r, j]
                    else:
                        continue
                    if q < ratio:
                        ratio, i = q, r
        if j < 0 or i < 0:
            break
        tableau_pivot(T, basis, i, j, blocks, C, K)
        pivots += 1
    while feasible and not gave_up and pivots < max_pivots:
        if low + span * T[0, 0] >= stop:
            break
        check = pivots % GIVE_UP_EVERY == GIVE_UP_EVERY - 1
        if check and mix_bound(M, block, blocks, exact, T) < give_up:
            gave_up = True
            break
        j, least = np.int64(-1), -eps
        if T[0, 1] < least:
            least, j = T[0, 1], np.int64(1)
        for k in cols:
            if T[0, k] < least:
                least, j = T[0, k], k
        if j < 0:
            break
        i, ratio = np.int64(-1), np.inf
        for r in range(1, R):
            if basis[r] != 1 and T[r, j] > eps:  # t is free: never leaves
                q = T[r, 0] / T[r, j]
                if q < ratio:
                    ratio, i = q, r
        if i < 0:
            break
        tableau_pivot(T, basis, i, j, blocks, C, K)
        pivots += 1
    fill(lam, K, 0.0)
    warm = False
    for r in range(1, R):
        warm |= basis[r] == 1
        if basis[r] >= L0:
            lam[basis[r] - L0] = max(T[r, 0], 0.0)
    total = np.zeros(blocks)
    for k in range(K):
        total[block[k]] += lam[k]
    for k in range(K):  # roundoff of the pivots: each block's weights at most 1
        if total[block[k]] > 1.0 or (exact and total[block[k]] > 0.0):
            lam[k] /= total[block[k]]
    if exact and not total[0] > 0.0:
        lam[0] = 1.0
    spread = 0.0
    for c in range(C):
        mix[c] = max(T[0, 2 + blocks + c], 0.0)
        spread += mix[c]
    for c in range(C):
        mix[c] = mix[c] / spread if spread > 0.0 else 0.0
    return -1 - pivots if gave_up else pivots, warm


@njit(**OPTIONS)
def block_game_weights(M, block, blocks, lam, stop=np.inf, give_up=-np.inf, mix=None):
    """Weights ``lam`` (K,) >= 0 with ``sum lam[block == b] <= 1`` for every block ``b <
    blocks`` that maximise ``min_c (M lam)_c`` for ``M`` (C, K), by a fresh game
    (:func:`game_solve`): every iterate is feasible, so the weights of a capped or
    early-stopped run still give a valid bound. ``mix`` (C,), unless None, gets the rows'
    optimal mix. Returns the pivots taken, as ``-1 - pivots`` when it gave up."""
    C, K = M.shape
    T, basis = game_tableau(C, K, blocks)
    low, span = game_open(M, block, blocks, False, T, basis)
    out = np.empty(C) if mix is None else mix
    pivots, _ = game_solve(M, block, blocks, False, T, basis, low, span, lam, stop, give_up,
                           MAX_PIVOTS, EPS, out)  # fmt: skip
    return pivots
