"""Compiled cells, bounds and matrix games of the branch and bound over the sphere.

The mathematics is that of :mod:`closure_nlp.branch_bound` (which drives the rounds and owns
the budget): a cell is a box of the five free coordinates of one face of the cube
``[-1, 1]^6`` mapped by an invertible ``metric`` (6, 6) (a positive diagonal evens the cells
out; a rotation and a shear map the cube's boxes onto a symmetry's fundamental domain,
:mod:`closure_nlp.symmetry`); every support point ``w`` gives
``p(u) >= w . u``, and so does every convex combination of support points.

Incumbent state, shared with the driver and updated in place: ``best`` (2,) holds the lowest
value and the evaluation count, ``best_u`` (6,) its direction, ``anchor`` (31, 6) the support
points of a small cloud around the incumbent and ``anchor_at`` (7,) the direction they were
taken at (last entry 1 when valid).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import argsort, copy_into, copy_rows, fill, solve
from .slot_game import EPS as SLOT_EPS
from .slot_game import MAX_PIVOTS as SLOT_PIVOTS
from .slot_game import game_grow_columns, game_grow_row, game_open, game_solve, game_tableau
from .support import D_VALUE, OPTIONS, WRAPPER, no_vector, scratch, set_value, support_point

SAMPLES = 11  # a cell's centre and the ends of its five axes
CORNERS = 32
ANCHOR_SCALES = np.array([1e-3, 1e-5, 1e-7])
ANCHORS = 1 + 10 * len(ANCHOR_SCALES)
# A cell's game first adds the support points of a cloud around its lowest sample, of this
# share of the cell's radius, and those of its 32 corners only when it stays alive: fewer
# support points in all than one game with the corners and wider and narrower clouds; the cloud
# alone costs fewer still but leaves a continuum of minima (two opposite soft fingers) a wider
# bracket at the cell budget.
REFINE_SCALE = 0.5
REFINE_POINTS = 11
MAX_PIVOTS = 300
# Pivots of a cell's game (:func:`exact_bound`): its weights give a valid bound wherever it
# stops. A few pivots drop the same cells as many, in less time: the games that need more are
# those of cells that stay alive anyway.
CELL_PIVOTS = 40
# Sets of at most this many slots (contacts or elements) give a cell that the cloud leaves alive
# a game with one budget of weights per slot (:func:`slot_bound`) in place of its corners' support
# points: cheaper on soft fingers, the same on the other families. Its game grows with the
# slots: larger sets keep the corners.
SLOT_GAME_SLOTS = 8
# Rounds of columns a slot game adds at the direction of its rows' optimal mix: the game over
# every slot point of the cell has the value of ``min p`` over the hull of the rows'
# directions (LP duality), and the slots' support points at that mix are the columns that
# raise it most. On cells that survive round a cylinder, from the lowest sample alone, a few
# rounds reach the game over a dense grid of the cell's points. These rounds pay off on soft
# fingers (fewer cells) and cost the other families nothing; more rounds cost the larger
# cylinder sets more games than the cells they save.
COLUMN_ROUNDS = 3
# Corners a slot game starts with (the lowest under the cell's best combination so far); the
# others join one by one while the game's weights leave one of them lower than its value.
FIRST_ROWS = 8
# Optimality and pivot tolerance of the games, on games scaled to [0, 1]: weights within about
# this of the value times the spread of the entries, tiny in the small cells near a minimum.
GAME_EPS = 1e-6
# A cell's game stops once its bound clears the drop threshold by this share of the gap: more
# would only widen the cell's bound past what drops it; less would leave the bracket at the gap.
GAME_HEADROOM = 0.5
# A cell whose lowest sample lies within this many ``|target| delta^2`` of the target skips the
# refinement's games (cloud, slot game, corners) and is halved: every linear bound over a cap
# of radius ``delta`` loses about ``p delta^2 / 2`` to the sphere's curvature, so those games
# rarely drop it there. The shallow valleys of soft fingers round a cylinder gain most; the
# other families are unchanged.
HOPELESS = 1.0
# A cell whose lowest sample lies within this many ``|target| delta^2`` of the target skips
# the anchors' Frank-Wolfe bound too (a cap bound loses at least ``p (1 - cos delta)``): the
# coarse cells of shallow valleys (soft fingers round a cylinder gain; the others are
# unchanged).
FLAT = 0.5
# The steps of a round that :func:`advance` calls once each: compiled inside it (numba inlines
# them) rather than as kernels of their own, which LLVM would optimise and compile to machine
# code once alone and once more inside ``advance``, on a cold compile's longest path.
ROUND_STEP = {**OPTIONS, "inline": "always"}


@njit(**OPTIONS)
def face_point(axis, sign, y, metric, out):
    """``metric @ x`` for the cube-face point ``x`` with ``x[axis] = sign`` and the other five
    coordinates ``y`` (5,); into ``out`` (6,), unnormalised."""
    for r in range(6):
        s = metric[r, axis] * sign
        j = 0
        for k in range(6):
            if k != axis:
                s += metric[r, k] * y[j]
                j += 1
        out[r] = s


@njit(**OPTIONS)
def normalise(x):
    s = 0.0
    for k in range(len(x)):
        s += x[k] * x[k]
    s = np.sqrt(s)
    for k in range(len(x)):
        x[k] /= s


@njit(**OPTIONS)
def cell_samples(axis, sign, lo, hi, metric, out):
    """Unit directions of the cell's centre and its five axes' ends: ``out`` (11, 6)."""
    y = np.empty(5)
    for s in range(SAMPLES):
        for j in range(5):
            y[j] = 0.5 * (lo[j] + hi[j])
        if s > 0:
            j = (s - 1) % 5
            half = 0.5 * (hi[j] - lo[j])
            y[j] += half if s <= 5 else -half
        face_point(axis, sign, y, metric, out[s])
        normalise(out[s])


@njit(**OPTIONS)
def cell_geometry(axis, sign, lo, hi, metric, floor, centre, corners, unit):
    """The cap holding the cell: fills its centre (6,), its 32 corners (mapped by ``metric``)
    and their unit directions (32, 6); returns the cap's angular radius and a lower bound on
    ``|metric @ x|`` over the box, ``floor`` (the least singular value of ``metric``) times the
    least ``|x|`` (``c . y / |y|`` is quasi-concave and ``metric`` maps the box's corners to
    those of its image: the minimum is at a corner)."""
    y = np.empty(5)
    for j in range(5):
        y[j] = 0.5 * (lo[j] + hi[j])
    face_point(axis, sign, y, metric, centre)
    normalise(centre)
    # The map is affine in y: corner q (bit 4 - j of q set: y_j = hi_j) is the corner without
    # q's lowest set bit plus one edge of the box, six additions instead of a 6x6 product.
    face_point(axis, sign, lo, metric, corners[0])
    edge = np.empty((5, 6))
    j = 0
    for k in range(6):
        if k != axis:
            for r in range(6):
                edge[j, r] = metric[r, k] * (hi[j] - lo[j])
            j += 1
    # the largest |unit corner - centre|: its angle 2 asin(chord / 2) stays exact for tiny
    # cells, where arccos of the cosine rounds to 0 (squared here: sqrt is monotone)
    chord = 0.0
    for q in range(CORNERS):
        if q > 0:
            j, low = 4, 1
            while not q & low:
                j, low = j - 1, 2 * low
            for k in range(6):
                corners[q, k] = corners[q - low, k] + edge[j, k]
        s = 0.0
        for k in range(6):
            s += corners[q, k] * corners[q, k]
        s = np.sqrt(s)
        c = 0.0
        for k in range(6):
            unit[q, k] = corners[q, k] / s
            c += (unit[q, k] - centre[k]) ** 2
        chord = max(chord, c)
    chord = np.sqrt(chord)
    far = 1.0
    for j in range(5):
        v = max(max(lo[j], -hi[j]), 0.0)
        far += v * v
    # a few ulps more: the unit vectors' own roundoff
    delta = 2.0 * np.arcsin(min(1.0, 0.5 * chord)) + 1e-15
    return delta, np.sqrt(far) * floor


@njit(**OPTIONS)
def geometry(n):
    """Room for the :func:`cell_geometry` of ``n`` cells, one row each: (delta (n,), nearest
    (n,), centre (n, 6), corners (n, 32, 6), unit (n, 32, 6)). The screens fill the rows of
    the cells they keep, in order, and :func:`bound_cells` reads them: a cell's geometry is
    computed once per round."""
    return (
        np.empty(n), np.empty(n), np.empty((n, 6)), np.empty((n, CORNERS, 6)),
        np.empty((n, CORNERS, 6)),
    )  # fmt: skip


@njit(**OPTIONS)
def geometry_into(axis, sign, lo, hi, metric, floor, geo, n, row):
    """:func:`cell_geometry` of cell ``n`` into row ``row`` of ``geo`` (:func:`geometry`)."""
    delta, nearest, centre, corners, unit = geo
    delta[row], nearest[row] = cell_geometry(
        axis[n], sign[n], lo[n], hi[n], metric, floor, centre[row], corners[row], unit[row]
    )


@njit(**OPTIONS)
def move_geometry(geo, n, row):
    """Row ``n`` of ``geo`` (:func:`geometry`) copied to row ``row``."""
    delta, nearest, centre, corners, unit = geo
    if row != n:
        delta[row], nearest[row] = delta[n], nearest[n]
        copy_into(centre[row], centre[n])
        copy_rows(corners[row], np.int64(0), corners[n])
        copy_rows(unit[row], np.int64(0), unit[n])


@njit(**OPTIONS)
def box_bound(w, corners, unit, nearest):
    """A lower bound of ``w . u`` over the cell: exact (the smallest over the unit corners)
    where ``w . x >= 0`` at every corner, else the most negative ``w . x`` over the smallest
    ``|x|``."""
    raw, low = np.inf, np.inf
    for q in range(CORNERS):
        a, b = 0.0, 0.0
        for k in range(6):
            a += corners[q, k] * w[k]
            b += unit[q, k] * w[k]
        raw, low = min(raw, a), min(low, b)
    return low if raw >= 0.0 else raw / nearest


@njit(**OPTIONS)
def line_search(beta, s, A, b, C):
    """argmax over [0, 1] of ``beta g - s sqrt(A g^2 + 2 b g + C)`` (concave)."""
    if not A > 0.0:
        return 0.0
    D = max(A * C - b * b, 0.0)
    r = beta / (s if s > 0.0 else 1e-300)
    room = A - r * r
    if room > 0.0:
        t = np.sign(r) * np.sqrt(r * r * D / room)
        g = (t - b) / A
    else:
        g = 1.0 if beta > 0.0 else 0.0
    if g != g:
        return 0.0
    return min(1.0, max(0.0, g))


@njit(**OPTIONS)
def frank_wolfe(points, n, c, delta, steps, lam, wbar):
    """Convex weights ``lam`` of ``points[:n]`` for a high cap bound ``cos(delta) wbar . c -
    sin(delta) |wbar_perp|`` (concave in the weights; every iterate is valid); fills ``lam``
    and ``wbar`` (their combination) and returns the cap bound."""
    cd, sd = np.cos(delta), np.sin(delta)
    a = np.empty(n)
    B = np.empty((n, 6))
    best, j = -np.inf, 0
    for i in range(n):
        s = 0.0
        for k in range(6):
            s += points[i, k] * c[k]
        a[i] = s
        nb = 0.0
        for k in range(6):
            B[i, k] = points[i, k] - s * c[k]
            nb += B[i, k] * B[i, k]
        single = cd * s - sd * np.sqrt(nb)
        if single > best:
            best, j = single, i
    fill(lam, n, 0.0)
    lam[j] = 1.0
    lam_a = a[j]
    v = np.empty(6)
    copy_into(v, B[j])
    unit = np.empty(6)
    for _ in range(steps):
        nv2 = 0.0
        for k in range(6):
            nv2 += v[k] * v[k]
        nv = np.sqrt(nv2)
        for k in range(6):
            unit[k] = v[k] / nv if nv > 0.0 else v[k]
        best, j = -np.inf, 0
        for i in range(n):
            s = 0.0
            for k in range(6):
                s += B[i, k] * unit[k]
            g = cd * a[i] - sd * s
            if g > best:
                best, j = g, i
        beta = cd * (a[j] - lam_a)
        A = b = 0.0
        for k in range(6):
            dv = B[j, k] - v[k]
            A += dv * dv
            b += v[k] * dv
        gamma = line_search(beta, sd, A, b, nv2)
        for i in range(n):
            lam[i] *= 1.0 - gamma
        lam[j] += gamma
        lam_a += gamma * (a[j] - lam_a)
        for k in range(6):
            v[k] += gamma * (B[j, k] - v[k])
    b_bar = 0.0
    for k in range(6):
        b_bar += v[k] * v[k]
    b_bar = np.sqrt(b_bar)
    for k in range(6):
        s = 0.0
        for i in range(n):
            s += lam[i] * points[i, k]
        wbar[k] = s
    if np.arctan2(b_bar, lam_a) + delta > np.pi:  # past the antipode: -wbar itself
        return -np.hypot(lam_a, b_bar)
    return cd * lam_a - sd * b_bar


@njit(**OPTIONS)
def game_weights(M, lam, stop=np.inf, max_pivots=MAX_PIVOTS, give_up=-np.inf):
    """Convex weights ``lam`` (K,) maximising ``min_c (M lam)_c`` for ``M`` (C, K): the value
    of a small matrix game by a fresh convex game (:func:`.slot_game.game_solve`, scaled to
    [0, 1]); every iterate is feasible, so capped weights still give a valid bound (callers
    recompute the bound from the weights). Pivoting ends early once the iterate's value
    reaches ``stop`` (a cell's bound needs no more than its target), once a mix of the rows
    shows the value below ``give_up`` (the game cannot drop the cell: more pivots would be
    wasted), or after ``max_pivots``. Returns the pivots taken, as ``-1 - pivots`` when it
    gave up."""
    C, K = M.shape
    one = np.int64(1)  # not a literal: one compile of the game
    block = np.zeros(K, np.int64)
    T, basis = game_tableau(C, K, one)
    low, span = game_open(M, block, one, True, T, basis)
    pivots, _ = game_solve(M, block, one, True, T, basis, low, span, lam, stop, give_up,
                           max_pivots, GAME_EPS, np.empty(C))  # fmt: skip
    return pivots


@njit(**OPTIONS)
def lowest_corners(unit, wbar, rows_in):
    """The lowest ``unit[q] . wbar`` over the corners in a game's rows (``rows_in[q]``), the
    lowest over the others and the corner of the latter (-1: none)."""
    low_in, low_out, at = np.inf, np.inf, -1
    for q in range(CORNERS):
        v = dot6(unit[q], wbar)
        if rows_in[q]:
            low_in = min(low_in, v)
        elif v < low_out:
            low_out, at = v, q
    return low_in, low_out, at


@njit(**OPTIONS)
def exact_bound(points, n, corners, unit, nearest, stop, give_up, wbar):
    """The corner bound of the best convex combination of ``points[:n]`` against the cell's
    unit corners (a matrix game), or of one whose game value reaches ``stop`` or that
    :data:`CELL_PIVOTS` pivots reach; the combination into ``wbar`` (6,), which on entry holds
    the cell's best combination so far. Valid for any weights the game returns: the bound is
    :func:`box_bound` of their combination, and ``p(u) >= wbar . u`` for every convex
    combination of support points, so stopping early can only weaken it. The game stops as
    soon as its value is shown below ``give_up`` (the bound cannot drop the cell).

    The game's rows are the :data:`FIRST_ROWS` corners lowest under ``wbar``, then those its
    combination leaves lowest, until none is below the game's value: a game's optimum holds
    about as many active corners as dimensions, and its pivots cost in proportion to its rows."""
    value = np.empty(CORNERS)
    for q in range(CORNERS):
        value[q] = dot6(unit[q], wbar)
    order = argsort(value)
    rows_in = np.zeros(CORNERS, np.bool_)
    M = np.empty((CORNERS, n))
    C = 0
    for q in order[:FIRST_ROWS]:
        rows_in[q] = True
        for i in range(n):
            M[C, i] = dot6(unit[q], points[i])
        C += 1
    lam = np.empty(n)
    # one tableau for the game and its added rows: a row joins an optimal game warm
    # typed values, not literals, and M strided as in the slot game: the game compiles once
    one, exact = np.int64(1), np.bool_(True)
    block = np.zeros(n, np.int64)
    T, basis = game_tableau(CORNERS, n, one)
    mix = np.empty(CORNERS)
    low, span = game_open(M[:C, :n], block, one, exact, T, basis)
    for _ in range(CORNERS):
        pivots, warm = game_solve(M[:C, :n], block, one, exact, T, basis, low, span, lam, stop,
                                  give_up, np.int64(CELL_PIVOTS), GAME_EPS, mix[:C])  # fmt: skip
        fill(wbar, len(wbar), 0.0)
        for i in range(n):
            for k in range(6):
                wbar[k] += lam[i] * points[i, k]
        if pivots < 0:  # more rows only lower the value
            break
        low_in, low_out, at = lowest_corners(unit, wbar, rows_in)
        if at < 0 or low_out >= min(low_in, stop):
            break
        rows_in[at] = True
        for i in range(n):
            M[C, i] = dot6(unit[at], points[i])
        C += 1
        low, span = game_grow_row(M[:C, :n], block, one, exact, T, basis, low, span, warm)
    return box_bound(wbar, corners, unit, nearest)


@njit(**WRAPPER)
def dot6(a, b):
    """``a . b`` of two 6-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]


@njit(**OPTIONS)
def slot_bound(G, f, W, npc, ends, dirs, corners, unit, nearest, stop, give_up, wbar, work):
    """The corner bound of the best combination of every slot's own support points at the
    directions ``dirs`` (N, 6), each slot with its own weights summing to at most 1
    (:mod:`.slot_game`), or of one whose game value reaches ``stop``; the combination into
    ``wbar`` (6,). ``-inf`` unless the bound is positive: ``p(u) >= wbar . u`` holds where
    some slot value is positive, which ``wbar . u > 0`` over the cell ensures (``wbar . u``
    is at most the sum of the positive slot values). Slots not positive at any of ``dirs``
    are left out (weight 0 is always allowed). The game stops as soon as its value is shown
    below ``give_up`` (the bound cannot drop the cell). Then, up to :data:`COLUMN_ROUNDS`
    times, the slots' support points at the direction of the rows' optimal mix ``ubar`` join
    as columns, unless the value ``sum_i max(P_i(ubar), 0)`` that no column can pass (LP
    duality: each column's product with ``ubar`` is at most its slot's value there) lies below
    ``give_up``. ``work`` holds :func:`slot_work`'s buffers."""
    cols, block, M, lam, rows, D, top, index, mix = work
    m = len(ends) - 1
    N = len(dirs)
    for i in range(m):
        top[i] = -np.inf
    for n in range(N):
        set_value(G, f, W, npc, ends, dirs[n], D, None, no_vector(D), rows)
        for i in range(m):
            at = ends[i]
            for r in range(ends[i] + 1, ends[i + 1]):
                if D[D_VALUE, r] > D[D_VALUE, at]:
                    at = r
            copy_into(cols[n * m + i], rows[at])
            top[i] = max(top[i], D[D_VALUE, at])
    blocks = np.int64(0)  # not a literal: one compile of the game
    for i in range(m):
        index[i] = -1
        if top[i] > 0.0:
            index[i] = blocks
            blocks += 1
    K = 0
    for n in range(N):
        for i in range(m):
            if index[i] >= 0:
                copy_into(cols[K], cols[n * m + i])
                block[K] = index[i]
                K += 1
    if K == 0:
        return -np.inf
    # the game's rows: the corners lowest under the cell's best point so far (``wbar`` on
    # entry), then those the game's combination leaves lowest, until none is below its value
    value = np.empty(CORNERS)
    for q in range(CORNERS):
        value[q] = dot6(unit[q], wbar)
    order = argsort(value)
    rows_in = np.zeros(CORNERS, np.bool_)
    picked = np.empty(CORNERS, np.int64)
    C = 0
    for q in order[:FIRST_ROWS]:
        rows_in[q] = True
        picked[C] = q
        C += 1
    for c in range(C):
        for k in range(K):
            M[c, k] = dot6(unit[picked[c]], cols[k])
    # one tableau for the game and its added rows and columns (:mod:`.slot_game`)
    exact = np.bool_(False)
    T, basis = game_tableau(CORNERS, len(cols), blocks)
    low, span = game_open(M[:C, :K], block[:K], blocks, exact, T, basis)
    ubar = np.empty(6)
    added = 0
    for _ in range(CORNERS + COLUMN_ROUNDS):
        pivots, warm = game_solve(M[:C, :K], block[:K], blocks, exact, T, basis, low, span,
                                  lam, stop, give_up, np.int64(SLOT_PIVOTS), SLOT_EPS,
                                  mix[:C])  # fmt: skip
        fill(wbar, len(wbar), 0.0)
        for k in range(K):
            for j in range(6):
                wbar[j] += lam[k] * cols[k, j]
        low_in, low_out, at = lowest_corners(unit, wbar, rows_in)
        if pivots >= 0 and at >= 0 and low_out < low_in:  # given up, more rows only lower it
            rows_in[at] = True
            picked[C] = at
            for k in range(K):
                M[C, k] = dot6(unit[at], cols[k])
            C += 1
            low, span = game_grow_row(M[:C, :K], block[:K], blocks, exact, T, basis, low, span,
                                      warm)  # fmt: skip
            continue
        if low_in >= stop or added == COLUMN_ROUNDS:
            break
        fill(ubar, len(ubar), 0.0)
        for c in range(C):
            for j in range(6):
                ubar[j] += mix[c] * unit[picked[c], j]
        length = np.sqrt(dot6(ubar, ubar))
        if not length > 0.0:
            break
        for j in range(6):
            ubar[j] /= length
        # an empty ``slots`` as above: the version slot values compile, not a third one
        set_value(G, f, W, npc, ends, ubar, D, None, no_vector(D), rows)
        reach, before = 0.0, np.int64(K)
        for i in range(m):
            if index[i] >= 0:
                at = ends[i]
                for r in range(ends[i] + 1, ends[i + 1]):
                    if D[D_VALUE, r] > D[D_VALUE, at]:
                        at = r
                reach += max(D[D_VALUE, at], 0.0)
                copy_into(cols[K], rows[at])
                block[K] = index[i]
                K += 1
        if length * reach < give_up:  # no column can lift the game to the drop
            break
        for k in range(before, K):
            for c in range(C):
                M[c, k] = dot6(unit[picked[c]], cols[k])
        low, span = game_grow_columns(M[:C, :K], block[:K], blocks, exact, T, basis, low, span,
                                      warm, before)  # fmt: skip
        added += 1
    bound = box_bound(wbar, corners, unit, nearest)
    return bound if bound > 0.0 else -np.inf


@njit(**OPTIONS)
def slot_work(f, ends, N):
    """The buffers of :func:`slot_bound` for ``N`` directions and its added columns."""
    N += COLUMN_ROUNDS
    m = len(ends) - 1
    return (
        np.empty((N * m, 6)), np.empty(N * m, np.int64), np.empty((CORNERS, N * m)),
        np.empty(N * m), np.empty((len(f), 6)), scratch(f), np.empty(m), np.empty(m, np.int64),
        np.empty(CORNERS),
    )  # fmt: skip


@njit(**OPTIONS)
def tangent_basis(u, E):
    """An orthonormal basis (5, 6) of the tangent space at unit ``u``: a Householder
    reflection taking ``u`` to ``+-e_0``, its other columns."""
    v = np.empty(6)
    copy_into(v, u)
    v[0] += 1.0 if u[0] >= 0.0 else -1.0
    vv = 0.0
    for k in range(6):
        vv += v[k] * v[k]
    for j in range(1, 6):
        for k in range(6):
            E[j - 1, k] = (1.0 if k == j else 0.0) - 2.0 * v[k] * v[j] / vv


@njit(**OPTIONS)
def cloud(u, scales, out):
    """``u`` and ``u +- eps e_j`` along a tangent basis, normalised: ``out`` (1 + 10 k, 6).
    Their support points hold every piece of ``p`` that meets at ``u``."""
    E = np.empty((5, 6))
    tangent_basis(u, E)
    copy_into(out[0], u)
    at = 1
    for e in range(len(scales)):
        eps = scales[e]
        for sgn in (1.0, -1.0):
            for j in range(5):
                for k in range(6):
                    out[at, k] = u[k] + sgn * eps * E[j, k]
                normalise(out[at])
                at += 1


@njit(**OPTIONS)
def consider(G, f, W, npc, ends, U, points, best, best_u):
    """Support values and points (into ``points``) of unit directions ``U``; the lowest value
    updates the incumbent. Returns the index of the lowest of ``U``."""
    return consider_in(G, f, W, npc, ends, U, points, best, best_u, scratch(f))


@njit(**OPTIONS)
def consider_in(G, f, W, npc, ends, U, points, best, best_u, D):
    """:func:`consider` with the caller's scratch ``D`` (:func:`~.support.scratch`): a loop
    over cells allocates it once (at 2,000 contacts a fresh one per call cost more than the
    support points it held)."""
    low, at = np.inf, 0
    for n in range(len(U)):
        v = support_point(G, f, W, npc, ends, U[n], points[n], D)
        if v < low:
            low, at = v, n
    best[1] += len(U)
    if low < best[0]:
        best[0] = low
        copy_into(best_u, U[at])
    return at


@njit(**ROUND_STEP)
def evaluate_cells(G, f, W, npc, ends, axis, sign, lo, hi, metric, U, points, values, best, best_u,
                   centre_w, centre_v):  # fmt: skip
    """Every cell's 11 samples: unit directions ``U`` (N, 11, 6), support points ``points``
    (N, 11, 6) and values ``values`` (N, 11), filled in place; the lowest updates the
    incumbent. The centres' support points and values are given (``centre_w`` (N, 6),
    ``centre_v`` (N,), :func:`screen_centres`)."""
    D = scratch(f)
    for n in range(len(axis)):
        cell_samples(axis[n], sign[n], lo[n], hi[n], metric, U[n])
        copy_into(points[n, 0], centre_w[n])
        values[n, 0] = centre_v[n]
        for s in range(1, SAMPLES):
            v = set_value(G, f, W, npc, ends, U[n, s], D, points[n, s], None, None)
            values[n, s] = v
            if v < best[0]:
                best[0] = v
                copy_into(best_u, U[n, s])
    best[1] += (SAMPLES - 1) * len(axis)


@njit(**ROUND_STEP)
def bound_cells(
    G, f, W, npc, ends, axis, sign, lo, hi, metric, floor, U, points, values, target, stop,
    margin, fw_steps, refine_below, best, best_u, anchor, anchor_at, lin, geo, cached,
):  # fmt: skip
    """Lower bounds of ``p`` over every cell (N,), from its evaluated samples
    (:func:`evaluate_cells`): each cheaper bound first, the next only for the cells it leaves
    below ``target``. Single support points of the samples and the cell's inherited wrench
    ``lin`` (exact on a linear piece of ``p``); Frank-Wolfe combinations of these with the
    incumbent's anchors (second order at a kink, approximately; not in a cell too flat for any
    cap bound, :data:`FLAT`); in small cells, the best combination of those the Frank-Wolfe
    weights hold and a cloud around the lowest sample (:data:`REFINE_SCALE`), by a matrix game
    pivoted until its bound reaches ``stop`` (at least ``target``); then, for sets of at most
    :data:`SLOT_GAME_SLOTS` slots and a positive target, the game of every slot's own support
    points at the lowest sample and its cloud, and at the directions its rows' optimal mixes
    point to (:func:`slot_bound`), else
    the game with the corners' support points added.

    ``lin`` (N, 6): on entry a point of the set per cell (its parent's, see :func:`screen`),
    or NaN for none; on return the point whose linear bound is the cell's. ``geo``
    (:func:`geometry`): the cells' geometry if ``cached``, else room for it."""
    N = len(axis)
    out = np.empty(N)
    size = SAMPLES + 1 + ANCHORS  # the samples, the inherited point, the anchors
    pool_size = size + REFINE_POINTS + CORNERS
    pool = np.empty((pool_size, 6))
    lam = np.empty(pool_size)
    wbar = np.empty(6)
    refine = np.empty(1)
    anchor_scales = np.empty(len(ANCHOR_SCALES))  # a global is read-only: another compile
    copy_into(anchor_scales, ANCHOR_SCALES)
    # row offsets as int64, not literals: a literal argument compiles another version
    first, one = np.int64(0), np.int64(1)
    more = np.empty((REFINE_POINTS, 6))
    directions = np.empty((ANCHORS, 6))
    D = scratch(f)
    slot_dirs = np.empty((1 + REFINE_POINTS, 6))
    # sets of few slots, contacts or elements (each slot's point at a direction is its
    # highest row's): with every cell refined, the slot game costs less than the corners and
    # leaves fewer cells
    slot_game = len(ends) <= SLOT_GAME_SLOTS + 1
    work = slot_work(f, ends, 1 + REFINE_POINTS if slot_game else 0)
    anchored = False
    need = target + margin  # the least game value that drops a cell
    for n in range(N):
        if not cached:
            geometry_into(axis, sign, lo, hi, metric, floor, geo, n, n)
        delta, nearest = geo[0][n], geo[1][n]
        centre, corners, unit = geo[2][n], geo[3][n], geo[4][n]
        copy_rows(pool, first, points[n])
        copy_into(pool[SAMPLES], points[n, 0] if np.isnan(lin[n, 0]) else lin[n])
        bound, at = -np.inf, 0
        for s in range(SAMPLES + 1):
            b = box_bound(pool[s], corners, unit, nearest)
            if b > bound:
                bound, at = b, s
        copy_into(lin[n], pool[at])
        bound -= margin
        low = 0
        for k in range(1, SAMPLES):  # the first of equal values, as np.argmin
            if values[n, k] < values[n, low]:
                low = k
        if bound < target and values[n, low] - target >= FLAT * abs(target) * delta * delta:
            same = anchor_at[6] != 0.0
            for k in range(6):
                same &= anchor_at[k] == best_u[k]
            if not anchored and not same:
                # the incumbent's anchors: taken once per round, when first needed
                cloud(best_u, anchor_scales, directions)
                copy_into(anchor_at, best_u)
                anchor_at[6] = 1.0
                consider_in(G, f, W, npc, ends, directions, anchor, best, best_u, D)
            anchored = True
            copy_rows(pool, SAMPLES + 1, anchor)
            cap = frank_wolfe(pool, size, centre, delta, fw_steps, lam, wbar)
            box = box_bound(wbar, corners, unit, nearest)
            if max(cap, box) - margin > bound:
                bound = max(cap, box) - margin
                copy_into(lin[n], wbar)
            hopeless = values[n, low] - target < HOPELESS * abs(target) * delta * delta
            if bound < target and delta < refine_below and not hopeless:
                refine[0] = REFINE_SCALE * delta
                cloud(U[n, low], refine, more)
                # the game's columns: the points the cap bound's weights hold, then the
                # cloud's (its pivots cost in proportion to its columns; all the samples and
                # anchors drop about the same cells, at more CPU)
                have = 0
                for i in range(size):
                    if lam[i] > 0.0:
                        copy_into(pool[have], pool[i])
                        have += 1
                added = pool[have : have + REFINE_POINTS]
                consider_in(G, f, W, npc, ends, more[:REFINE_POINTS], added, best, best_u, D)
                have += REFINE_POINTS
                exact = exact_bound(pool, have, corners, unit, nearest, stop + 2 * margin, need,
                                    wbar)  # fmt: skip
                if exact - margin > bound:
                    bound = exact - margin
                    copy_into(lin[n], wbar)
                if bound < target and target > margin and slot_game:
                    copy_into(slot_dirs[0], U[n, low])
                    copy_rows(slot_dirs, one, more[:REFINE_POINTS])
                    slotwise = slot_bound(G, f, W, npc, ends, slot_dirs, corners, unit, nearest,
                                          stop + 2 * margin, need, wbar, work)  # fmt: skip
                    # its point belongs to the set only where it is positive: not inherited
                    bound = max(bound, slotwise - margin)
                elif bound < target:
                    consider_in(G, f, W, npc, ends, unit, pool[have : have + CORNERS], best, best_u,
                                D)  # fmt: skip
                    exact = exact_bound(pool, have + CORNERS, corners, unit, nearest,
                                        stop + 2 * margin, need, wbar)  # fmt: skip
                    if exact - margin > bound:
                        bound = exact - margin
                        copy_into(lin[n], wbar)
        out[n] = bound
    return out


@njit(**OPTIONS)
def screen(axis, sign, lo, hi, metric, floor, lin, target, margin, tally, geo):
    """Which cells (indices) the linear bound of their inherited point ``lin`` (N, 6) leaves
    below ``target``; the others are dropped before their samples are taken, their bounds
    entered in ``tally[LOWER]``. A cell's parent's bounding point is a point of the set,
    and over the smaller cell its bound can only rise. The kept cells' geometry fills the
    first rows of ``geo`` (:func:`geometry`), in order."""
    keep = np.empty(len(axis), np.int64)
    alive = 0
    for n in range(len(axis)):
        geometry_into(axis, sign, lo, hi, metric, floor, geo, n, alive)
        corners, unit, nearest = geo[3][alive], geo[4][alive], geo[1][alive]
        bound = box_bound(lin[n], corners, unit, nearest) - margin
        if bound < target:
            keep[alive] = n
            alive += 1
        else:
            tally[LOWER] = min(tally[LOWER], bound)
    return keep[:alive]


@njit(**ROUND_STEP)
def screen_centres(G, f, W, npc, ends, axis, sign, lo, hi, metric, floor, gap, margin, tally,
                   best, best_u, geo, cached, centre_w, centre_v):  # fmt: skip
    """Which cells (indices) the linear bound of their centre's support point leaves below the
    incumbent minus ``gap``; the others are dropped before their other ten samples are taken,
    their bounds entered in ``tally[LOWER]``. The centres' values update the incumbent. The
    kept cells' geometry (given in ``geo``, :func:`geometry`, if ``cached``), centres' support
    points and values fill the first rows of ``geo``, ``centre_w`` and ``centre_v``, in order.
    On force-closure sets the centre alone drops most of the cells that the eleven samples and
    their games would."""
    D = scratch(f)
    keep = np.empty(len(axis), np.int64)
    alive = 0
    for n in range(len(axis)):
        # the cell's centre (cell_geometry's) is its first sample's direction
        if cached:
            move_geometry(geo, n, alive)
        else:
            geometry_into(axis, sign, lo, hi, metric, floor, geo, n, alive)
        u, corners, unit, nearest = geo[2][alive], geo[3][alive], geo[4][alive], geo[1][alive]
        w = centre_w[alive]
        v = support_point(G, f, W, npc, ends, u, w, D)
        centre_v[alive] = v
        best[1] += 1
        if v < best[0]:
            best[0] = v
            copy_into(best_u, u)
        bound = box_bound(w, corners, unit, nearest) - margin
        if bound < best[0] - gap:
            keep[alive] = n
            alive += 1
        else:
            tally[LOWER] = min(tally[LOWER], bound)
    return keep[:alive]


def no_samples():
    """Empty samples (U, points, values) for :func:`advance`'s first call."""
    return np.empty((0, SAMPLES, 6)), np.empty((0, SAMPLES, 6)), np.empty((0, SAMPLES))


def none_inherited(n):
    """Inherited bounding points (:func:`advance`'s ``lin``) for ``n`` cells that have none."""
    return np.full((n, 6), np.nan)


# What :func:`advance` stops for.
CONVERGED, BUDGET, BELOW_ZERO, POLISH, ROUND = 0, 1, 2, 3, 4
# What :func:`advance`'s cells are on entry.
FRESH, CHILDREN, EVALUATED = 0, 1, 2
# ``tally`` (float64): the search's state between calls of :func:`advance`.
LOWER, CELLS, ROUNDS, ALIVE_AT_BUDGET, POLISHED_AT, POLISHES, LIVE_LOWER = range(7)
# ``settings`` (float64): its budget and tolerances.
(
    GAP, MARGIN, FW_STEPS, REFINE_BELOW, MAX_CELLS, EXTENDED_CELLS, EXTENSION_ALIVE, MAX_ROUNDS,
    STOP_BELOW_ZERO, CELLS_PER_ROUND, MAX_POLISH, FLOOR, SHELLS_BELOW, SHELLS_SHRINK, ROUND_CELLS,
    ROUNDS_AFTER,
) = range(16)  # fmt: skip


@njit(**OPTIONS)
def advance(
    G, f, W, npc, ends, axis, sign, lo, hi, lin, U, points, values, stage, metric, best,
    best_u, anchor, anchor_at, tally, settings,
):  # fmt: skip
    """Rounds of the branch and bound (evaluate every live cell, bound it, drop the cells
    whose bound reaches the incumbent minus the gap, :func:`split` the others) until it converges,
    spends its budget, meets ``p < 0`` (with ``settings[STOP_BELOW_ZERO]``), or its samples
    lowered the incumbent by more than the gap since the last polish and a polish is left
    (``POLISH``: the caller runs its local solver and calls again with the same cells at
    ``stage`` EVALUATED). ``tally[LOWER]`` holds the least bound of the dropped cells, and once
    stopped unconverged, of the live ones too. Halved cells inherit their parent's bounding
    point (their row of ``lin``) and are first :func:`screen`-ed by it, then by their centre's
    support point (:func:`screen_centres`): the cells these drop cost no more samples (and do
    not count in ``tally[CELLS]``, the budget of sampled cells).

    ``stage``: FRESH (cells without inherited points: ``lin`` is room), CHILDREN (a ``ROUND``'s
    cells, screened first) or EVALUATED. A round that leaves at least ``settings[ROUND_CELLS]``
    children, once ``settings[ROUNDS_AFTER]`` cells have been sampled, returns them (``ROUND``,
    ``tally[LIVE_LOWER]`` the least bound of their parents), so that the caller may deal them
    out to workers.

    Returns (status, axis, sign, lo, hi, lin, U, points, values): the live cells, their
    inherited points and their samples."""
    gap, margin = settings[GAP], settings[MARGIN]
    max_cells, extended = settings[MAX_CELLS], settings[EXTENDED_CELLS]
    geo, cached = geometry(len(axis)), False
    while True:
        if stage == CHILDREN:
            live = screen(
                axis, sign, lo, hi, metric, settings[FLOOR], lin, best[0] - gap, margin, tally,
                geo,
            )  # fmt: skip
            cached = True
            axis, sign, lo, hi = take_cells(axis, sign, lo, hi, live)
            if len(live) == 0:
                return CONVERGED, axis, sign, lo, hi, lin, U, points, values
            lin = take_rows(lin, live)
        if stage != EVALUATED:
            centre_w, centre_v = np.empty((len(axis), 6)), np.empty(len(axis))
            live = screen_centres(
                G, f, W, npc, ends, axis, sign, lo, hi, metric, settings[FLOOR], gap, margin,
                tally, best, best_u, geo, cached, centre_w, centre_v,
            )  # fmt: skip
            cached = True
            if len(live) < len(axis):
                axis, sign, lo, hi = take_cells(axis, sign, lo, hi, live)
                lin = take_rows(lin, live)
            if len(live) == 0:
                return CONVERGED, axis, sign, lo, hi, lin, U, points, values
            N = len(axis)
            U = np.empty((N, SAMPLES, 6))
            points = np.empty((N, SAMPLES, 6))
            values = np.empty((N, SAMPLES))
            evaluate_cells(
                G, f, W, npc, ends, axis, sign, lo, hi, metric, U, points, values, best, best_u,
                centre_w, centre_v,
            )  # fmt: skip
            tally[CELLS] += N
            tally[ROUNDS] += 1
            if tally[POLISHES] < settings[MAX_POLISH] and best[0] < tally[POLISHED_AT] - gap:
                return POLISH, axis, sign, lo, hi, lin, U, points, values
        if settings[STOP_BELOW_ZERO] > 0 and best[0] < -margin:
            tally[LOWER] = -np.inf
            return BELOW_ZERO, axis, sign, lo, hi, lin, U, points, values
        target = best[0] - gap  # the round's: refinements may lower the incumbent meanwhile
        stop = target + GAME_HEADROOM * gap
        bound = bound_cells(
            G, f, W, npc, ends, axis, sign, lo, hi, metric, settings[FLOOR], U, points, values,
            target, stop, margin, int(settings[FW_STEPS]), settings[REFINE_BELOW], best, best_u,
            anchor, anchor_at, lin, geo, cached,
        )  # fmt: skip
        alive, lowest_live = 0, np.inf
        keep = np.empty(len(axis), np.int64)
        for n in range(len(axis)):
            if bound[n] < target:
                keep[alive] = n
                alive += 1
                lowest_live = min(lowest_live, bound[n])
            else:
                tally[LOWER] = min(tally[LOWER], bound[n])
        if alive == 0:
            return CONVERGED, axis, sign, lo, hi, lin, U, points, values
        cells = tally[CELLS]
        if cells >= max_cells and tally[ALIVE_AT_BUDGET] < 0:
            tally[ALIVE_AT_BUDGET] = alive
        extending = tally[ALIVE_AT_BUDGET] >= 0 and alive <= max(
            settings[EXTENSION_ALIVE], 2 * tally[ALIVE_AT_BUDGET]
        )
        if (
            tally[ROUNDS] >= settings[MAX_ROUNDS]
            or cells >= max(max_cells, extended)
            or (cells >= max_cells and not extending)
        ):
            tally[LOWER] = min(tally[LOWER], lowest_live)
            return BUDGET, axis, sign, lo, hi, lin, U, points, values
        keep = keep[:alive]
        axis, sign, lo, hi = take_cells(axis, sign, lo, hi, keep)
        radius = INNER_SHARE * np.sqrt(gap / max(abs(best[0]), gap))
        below = settings[SHELLS_BELOW] if alive <= SHELL_ALIVE else 0.0
        per_round, shrink = int(settings[CELLS_PER_ROUND]), settings[SHELLS_SHRINK]
        axis, sign, lo, hi, parent = split(
            axis, sign, lo, hi, per_round, metric, best_u, radius, below, shrink
        )
        inherited = np.empty((len(axis), 6))
        for c in range(len(axis)):
            copy_into(inherited[c], lin[keep[parent[c]]])
        lin, stage = inherited, CHILDREN
        geo, cached = geometry(len(axis)), False
        if len(axis) >= settings[ROUND_CELLS] and tally[CELLS] >= settings[ROUNDS_AFTER]:
            tally[LIVE_LOWER] = lowest_live
            return ROUND, axis, sign, lo, hi, lin, U, points, values


@njit(**OPTIONS)
def take_rows(rows, keep):
    """``rows[keep]`` of a 2-d array, as a loop (see :func:`take_cells`)."""
    out = np.empty((len(keep), rows.shape[1]))
    for c in range(len(keep)):
        copy_into(out[c], rows[keep[c]])
    return out


@njit(**OPTIONS)
def take_cells(axis, sign, lo, hi, rows):
    """The cells ``rows`` (indices, repeats allowed): a loop, not fancy indexing (numba
    compiles numpy's broadcasting for each array type)."""
    n = len(rows)
    axis2, sign2 = np.empty(n, np.int64), np.empty(n)
    lo2, hi2 = np.empty((n, lo.shape[1])), np.empty((n, lo.shape[1]))
    for c in range(n):
        r = rows[c]
        axis2[c], sign2[c] = axis[r], sign[r]
        copy_into(lo2[c], lo[r])
        copy_into(hi2[c], hi[r])
    return axis2, sign2, lo2, hi2


@njit(**OPTIONS)
def halve(axis, sign, lo, hi, cells_per_round):
    """Every cell cut in two across its widest coordinate, ``cuts`` times (``2^cuts``
    children, ``cuts <= 5``), so that a round holds about ``cells_per_round`` cells."""
    n = len(axis)
    cuts = 1
    while cuts < 5 and n * 2 ** (cuts + 1) <= cells_per_round:
        cuts += 1
    for _ in range(cuts):
        twice = np.empty(2 * len(axis), np.int64)
        for c in range(len(twice)):
            twice[c] = c % len(axis)
        axis2, sign2, lo2, hi2 = take_cells(axis, sign, lo, hi, twice)
        for c in range(len(axis)):
            w, widest = 0, hi[c, 0] - lo[c, 0]  # the first widest, as np.argmax
            for j in range(1, hi.shape[1]):
                if hi[c, j] - lo[c, j] > widest:
                    w, widest = j, hi[c, j] - lo[c, j]
            cut = 0.5 * (lo[c, w] + hi[c, w])
            hi2[c, w] = cut
            lo2[c + len(axis), w] = cut
        axis, sign, lo, hi = axis2, sign2, lo2, hi2
    return axis, sign, lo, hi


# A cell under ``settings[SHELLS_BELOW]`` in angular radius that holds the incumbent is cut
# into shells round it (each ``settings[SHELLS_SHRINK]`` times smaller than the one outside it)
# in rounds that leave at most SHELL_ALIVE cells alive: fewer cells at sharp minima; without
# the cap, flat minima (many cells alive per level) would sample more.
SHELL_ALIVE = 4
# The inner box's angular radius, times ``sqrt(gap / |p*|)``: under the refinement's
# :data:`HOPELESS` radius, so its games run, and its curvature loss under the gap.
INNER_SHARE = 0.5


@njit(**OPTIONS)
def holds(axis, sign, lo, hi, x, y):
    """Whether the ray through ``metric @ x`` meets the cell's box; its face coordinates into
    ``y`` (5,)."""
    t = sign * x[axis]
    if not t > 0.0:
        return False
    j = 0
    for k in range(6):
        if k != axis:
            y[j] = x[k] / t
            if not lo[j] <= y[j] <= hi[j]:
                return False
            j += 1
    return True


@njit(**OPTIONS)
def shells(lo, hi, y, h, shrink):
    """The box ``[lo, hi]`` (5,) cut round its point ``y``: an inner box ``y +- h`` (clipped
    to the box) and nested shells between, each ``shrink`` times smaller than the one holding
    it, each shell cut into two slabs per coordinate (the box difference ``B \\ B'`` is the
    union over ``j`` of ``B'``'s range in the coordinates before ``j``, ``B``'s after, and one
    side of ``B'`` in ``j``). Returns (lo, hi) of the pieces: disjoint (up to their faces),
    together exactly the box. At a sharp minimum ``p >= p* + c angle``, so the shells far from
    ``y`` drop at once while their widths are such that ``p* delta^2 / 2`` stays under
    ``c`` times their distance from ``y``; the inner box drops once ``p* h^2 / 2`` is under the
    gap."""
    half = np.empty(5)
    outer_lo, outer_hi = np.empty(5), np.empty(5)
    inner_lo, inner_hi = np.empty(5), np.empty(5)
    count = 11  # at least one shell
    for j in range(5):
        half[j] = 0.5 * (hi[j] - lo[j])
    s = half[0]
    for j in range(1, 5):  # not half.max(): numpy's max costs more to compile than the loop
        s = max(s, half[j])
    while s > h:
        s /= shrink
        count += 10
    out_lo, out_hi = np.empty((count, 5)), np.empty((count, 5))
    copy_into(outer_lo, lo)
    copy_into(outer_hi, hi)
    n = 0
    while True:
        last = True
        for j in range(5):
            half[j] = max(half[j] / shrink, h)
            last &= half[j] == h
            inner_lo[j] = max(outer_lo[j], y[j] - half[j])
            inner_hi[j] = min(outer_hi[j], y[j] + half[j])
        for j in range(5):
            for side in range(2):
                a = outer_lo[j] if side == 0 else inner_hi[j]
                b = inner_lo[j] if side == 0 else outer_hi[j]
                if not b > a:
                    continue
                for i in range(5):
                    if i < j:
                        out_lo[n, i], out_hi[n, i] = inner_lo[i], inner_hi[i]
                    elif i > j:
                        out_lo[n, i], out_hi[n, i] = outer_lo[i], outer_hi[i]
                out_lo[n, j], out_hi[n, j] = a, b
                n += 1
        copy_into(outer_lo, inner_lo)
        copy_into(outer_hi, inner_hi)
        if last:
            break
    copy_into(out_lo[n], inner_lo)
    copy_into(out_hi[n], inner_hi)
    return out_lo[: n + 1], out_hi[: n + 1]


@njit(**OPTIONS)
def split(axis, sign, lo, hi, cells_per_round, metric, best_u, radius, below, shrink):
    """The live cells' children: a cell of angular radius under ``below`` holding the
    incumbent ``best_u`` cut into :func:`shells` round it, its inner box of angular radius
    about ``radius``, when that box is under half the cell's width; every other cell halved
    (:func:`halve`). Returns (axis, sign, lo, hi, parent): ``parent[c]`` indexes the cell child
    ``c`` came from."""
    n = len(axis)
    x = solve(metric, best_u)
    y = np.empty(5)
    h = np.zeros(n)
    centre = np.empty(6)
    corners = np.empty((CORNERS, 6))
    unit = np.empty((CORNERS, 6))
    probe_lo, probe_hi = np.empty(5), np.empty(5)
    rest = np.empty(n, np.int64)
    others = 0
    for c in range(n):
        delta, _ = cell_geometry(axis[c], sign[c], lo[c], hi[c], metric, 1.0, centre, corners,
                                 unit)  # fmt: skip
        if delta < below and holds(axis[c], sign[c], lo[c], hi[c], x, y):
            # the angular radius of a small box round y scales with its half-width
            for j in range(5):
                probe_lo[j], probe_hi[j] = y[j] - 1e-6, y[j] + 1e-6
            delta, _ = cell_geometry(axis[c], sign[c], probe_lo, probe_hi, metric, 1.0, centre,
                                     corners, unit)  # fmt: skip
            h[c] = 1e-6 * radius / delta
            widest = 0.0
            for j in range(5):
                widest = max(widest, hi[c, j] - lo[c, j])
            if 2.0 * h[c] <= 0.5 * widest:
                continue
            h[c] = 0.0
        rest[others] = c
        others += 1
    axis2, sign2, lo2, hi2 = halve(*take_cells(axis, sign, lo, hi, rest[:others]), cells_per_round)
    cut = []  # each held cell's pieces
    total = len(axis2)
    for c in range(n):
        if h[c] > 0.0:
            holds(axis[c], sign[c], lo[c], hi[c], x, y)
            cut.append(shells(lo[c], hi[c], y, h[c], shrink))
            total += len(cut[-1][0])
    axis_all, sign_all = np.empty(total, np.int64), np.empty(total)
    lo_all, hi_all = np.empty((total, 5)), np.empty((total, 5))
    parent = np.empty(total, np.int64)
    for c in range(len(axis2)):  # halve's child c + k * others has parent c
        axis_all[c], sign_all[c] = axis2[c], sign2[c]
        copy_into(lo_all[c], lo2[c])
        copy_into(hi_all[c], hi2[c])
        parent[c] = rest[c % others]
    at, b = len(axis2), 0
    for c in range(n):
        if h[c] > 0.0:
            lo3, hi3 = cut[b]
            b += 1
            for k in range(len(lo3)):
                axis_all[at], sign_all[at] = axis[c], sign[c]
                copy_into(lo_all[at], lo3[k])
                copy_into(hi_all[at], hi3[k])
                parent[at] = c
                at += 1
    return axis_all, sign_all, lo_all, hi_all, parent
