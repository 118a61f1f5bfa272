"""Frictionless contacts as a zonotope: their load capacity in closed form, and a search on it.

A frictionless contact (FPC) pushes along its inward normal only: its wrench set is the segment
``[0, w_i]`` with ``w_i = f_max (n, torque_scale * r x n)`` (column 0 of its grasp matrix times
``f_max``), and the set of ``m`` of them is the zonotope ``Z = sum_i [0, w_i]`` with support
function ``s(u) = sum_i max(0, <w_i, u>)``. The load capacity ``min_{|u|=1} s(u)`` is the distance
from the origin (a point of ``Z``: all forces zero) to the boundary of ``Z``, so it is attained at
the outer normal of a facet of ``Z``.

Facets (proof of :func:`frictionless_capacity`)
-----------------------------------------------
In ``R^6`` every facet of a zonotope is parallel to five linearly independent generators ``S``;
its normal ``n_S`` is their generalized cross product, ``<x, n_S> = det[w_S; x]`` (the five rows
of ``S`` over ``x``), with ``|n_S|^2 = det(w_S w_S^T)`` (Cauchy-Binet). The facets with normals
``+-n_S`` lie at the distances ``s(+-n_S) / |n_S|``, and
``s(+-n_S) = sum_{j not in S} max(0, +-x_j)`` with ``x_j = det[w_S; w_j]`` (the terms of ``S``
vanish). So ``min_{|u|=1} s(u)`` is the least of these over the five-subsets ``S`` of full rank
(numerically: five generators whose volume is below 1e-8 of the product of their lengths are
skipped; a facet they span is spanned by others too unless two contacts nearly coincide, and
then the value may be high, never low: each remaining term is still a true ``s(n)/|n|``):
when ``Z`` is full-dimensional its least facet distance is its inradius about the origin, and
when it is not (or the origin is on its boundary) some such facet has distance 0. Every value
in that least is ``s(n)/|n|`` for some ``n != 0``, never below the minimum, so no other
direction is needed. The capacity of eq 26 agrees whenever it is positive (force closure):
``p = s`` where some ``<w_i, u>`` is positive, which holds at every ``u`` then.

It serves the search of a placement: a placement's capacity costs ``C(m, 5)`` triples of small
determinants (a compiled loop, :mod:`closure_nlp.kernels.zonotope`: about 0.3 us per five-subset),
over hundreds of placements at once (:func:`climb`), where the certified rho solver spends
milliseconds on one; the placements found are then certified by that solver.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from closure_nlp.base.validation import as_shaped
from closure_nlp.kernels import kernel_array
from closure_nlp.kernels.zonotope import capacity_many

# Contacts at most: C(m, 5) five-subsets are enumerated (792 at 12).
MAX_CONTACTS = 12


def frictionless_capacity(W: np.ndarray) -> np.ndarray:
    """``max(0, min_{|u|=1} sum_i max(0, <w_i, u>))`` of each set of generators.

    Parameters
    ----------
    W : (B, m, 6) float
        ``B`` sets of ``m`` frictionless contact wrenches ``f_max (n, torque_scale * r x n)``,
        ``7 <= m <=`` :data:`MAX_CONTACTS` (fewer than seven are never force closure).

    Returns
    -------
    (B,) float
        Each set's load capacity ``-rho`` when it is force closure, else 0.
    """
    W = np.asarray(as_shaped(W, "W", ("B", "m", 6)), dtype=float)
    B, m, _ = W.shape
    if m < 7:
        return np.zeros(B)
    if m > MAX_CONTACTS:
        raise ValueError(f"W: expected at most {MAX_CONTACTS} contacts, got {m}")
    # a common unit: the determinants are then of order one in any unit of length or force
    unit = np.max(np.abs(W), axis=(1, 2), keepdims=True)
    unit = np.where(unit > 0.0, unit, 1.0)
    V = W / unit
    subsets = np.array(list(combinations(range(m), 5)), dtype=np.int64)  # (C(m, 5), 5)
    rests = np.array([[j for j in range(m) if j not in S] for S in subsets], dtype=np.int64)
    best = np.empty(B)
    capacity_many(kernel_array(V), subsets, rests, best)
    return best * unit[:, 0, 0]


# Relative margin of :func:`facet_rows` for the round-off of its determinants (about 1e-15 of the
# product of their rows' lengths each, divided by the facet normal's length).
FACET_ROUND_OFF = 1e-10


def facet_rows(vertex_wrenches: list[np.ndarray]) -> np.ndarray:
    """Affine upper bounds of the frictionless capacity over a cell (each contact on one piece),
    second order in the pieces' sizes.

    Parameters
    ----------
    vertex_wrenches : list of (k_i, 6) float
        Each contact's wrench ``f_max (n, torque_scale * r x n)`` at the vertices of its piece
        (``k_i = 1`` for a point); ``7 <= m <=`` :data:`MAX_CONTACTS` contacts.

    Returns
    -------
    (K, R) float
        ``R = sum_i k_i`` columns (contact by contact): for every placement in the cell with
        barycentric weights ``lam`` (one simplex per contact),
        ``max(0, min_{|u|=1} s(u)) <= min_k (A lam)_k``. ``K = 0`` when no facet's sign pattern
        is fixed on the cell (no bound from here).

    Notes
    -----
    Proof. Write contact ``i``'s wrench as ``w_i = sum_r lam_ir V_ir``, ``lam0`` the pieces'
    vertex means, ``w0_i = sum_r lam0_ir V_ir``, ``e_i = w_i - w0_i`` (in the hull of
    ``V_ir - w0_i``, so ``|e_i| <= eps_i := max_r |V_ir - w0_i|``) and
    ``delta = lam - lam0``. For six rows, each a contact or a fixed vector, ``P = det[rows]`` is
    multilinear in the rows, so ``P = P0 + a.delta + sum_{|T| >= 2} det[e_T; w0_rest]`` over the
    sets ``T`` of contact rows (``a_ir = det`` with row ``i`` replaced by ``V_ir``; the ``lam0``
    part cancels as ``sum_r delta_ir = 0``). A pair term is bilinear in ``(e_i, e_k)``; its
    absolute value is convex in each, so its largest value is at a pair of vertices ``V_ir -
    w0_i``, ``V_ks - w0_k`` (enumerated). A larger ``T`` has ``|det[e_T; w0_rest]| <=
    prod_T eps_i vol(w0_rest)`` (Fischer's and Hadamard's inequalities). So
    ``|P - P0 - a.delta| <= R``.

    For a five-subset ``S`` let ``n`` be its generalized cross product (``<z, n> =
    det[w_S; z]``), ``n0`` its value at ``lam0`` (unit ``nh``), ``x_j = det[w_S; w_j]`` and
    ``nu = det[w_S; nh] = <nh, n> <= |n|``. By the above ``nu >= L0 + b.delta - R_n`` with
    ``L0 = |n0|``; on the cell ``|nu - L0| <= H`` (``H``: the largest ``|b.delta|`` over the
    cell's vertices plus ``R_n``), so ``|n| >= nu >= L0 - H =: Lmin``; ``S`` is used only when
    ``Lmin > 0``. Likewise each ``x_j`` (``j`` not in ``S``) is used only when its interval
    ``x0_j +- (max |a_j.delta| + R_j)`` excludes 0: its sign ``s_j`` is fixed on the cell.
    When every ``j`` has a fixed sign, ``s(+-n) = sum_{s_j = +-1} +-x_j =: X_+-`` (the terms of
    ``S`` vanish) and the capacity is at most ``X / |n| <= X / nu`` for both (``X >= 0``); when
    one of them sums over no ``j`` it is 0 on the whole cell (a facet through the origin),
    a zero row. With ``X = X0 + xi``, ``xi <= a_X.delta + R_X``, ``nu = L0 + eta`` and
    ``q0 = X0 / L0 >= 0``:

        X / nu - q0 = (xi - q0 eta) / (L0 + eta)
                    <= (xi - q0 eta) / L0 + |xi - q0 eta| |eta| / (L0 Lmin)
                    <= q0 + ((a_X - q0 b).delta + R_X + q0 R_n) / L0 + Z H / (L0 Lmin) - q0,

    ``Z`` the largest ``|xi - q0 eta|`` (the largest ``|(a_X - q0 b).delta|`` plus ``R_X +
    q0 R_n``). That is affine in ``lam``; its constant is spread over the contacts' columns
    (each ``lam_i`` sums to 1). The capacity is the least facet distance (:func:`
    frictionless_capacity`), below each of these, and the rows' minimum is their bound; every
    remainder is of second order in the pieces' sizes, so the bound's excess shrinks with the
    square of the cell, where the interpolation bound of :mod:`closure_nlp.placement.ceiling` is
    first order at contacts on a facet (their ``<w_i, n> = 0``: the kink of ``max(0, .)``).
    """
    V = [np.asarray(v, float) for v in vertex_wrenches]
    m = len(V)
    if not 7 <= m <= MAX_CONTACTS:
        raise ValueError(f"vertex_wrenches: expected 7 to {MAX_CONTACTS} contacts, got {m}")
    k = np.array([len(v) for v in V])
    offsets = np.r_[0, np.cumsum(k)]
    # a common unit: determinants of order one whatever the units; the rows scale back
    unit = max(float(np.max(np.abs(v))) for v in V)
    unit = unit if unit > 0.0 else 1.0
    V = [v / unit for v in V]
    lam0 = [np.full(len(v), 1.0 / len(v)) for v in V]
    w0 = np.array([lam @ v for lam, v in zip(lam0, V)])
    D = [v - w for v, w in zip(V, w0)]
    eps = np.array([float(np.max(np.linalg.norm(d, axis=1))) for d in D])
    volume = {(): 1.0}
    for size in (1, 2, 3):
        for T in combinations(range(m), size):
            A = w0[list(T)]
            volume[T] = float(np.sqrt(max(np.linalg.det(A @ A.T), 0.0)))

    subsets = list(combinations(range(m), 5))
    bases = w0[np.array(subsets)]  # (nS, 5, 6)
    n0 = np.linalg.det(
        np.concatenate(
            [
                np.broadcast_to(bases[:, None], (len(subsets), 6, 5, 6)),
                np.broadcast_to(np.eye(6)[None, :, None], (len(subsets), 6, 1, 6)),
            ],
            axis=2,
        )
    )  # (nS, 6): <e_k, n>
    L0 = np.linalg.norm(n0, axis=1)
    live = L0 > 0.0
    nh = n0 / np.where(live, L0, 1.0)[:, None]

    # the polynomials: per subset, nu (fixed row nh) then x_j for j outside it
    rows, matrices, owner_subset = [], [], []
    for s, S in enumerate(subsets):
        if not live[s]:
            continue
        rows.append(S + (-1,))
        matrices.append(np.vstack([bases[s], nh[s]]))
        owner_subset.append(s)
        for j in range(m):
            if j not in S:
                rows.append(S + (j,))
                matrices.append(np.vstack([bases[s], w0[j]]))
                owner_subset.append(s)
    if not rows:
        return np.zeros((0, int(offsets[-1])))
    base = np.array(matrices)  # (P, 6, 6)
    P = len(base)
    P0 = np.linalg.det(base)

    # linear coefficients a[p, ir]: row i replaced by each vertex wrench
    index, position, column, vector = [], [], [], []
    for p, r in enumerate(rows):
        for a, i in enumerate(r):
            if i >= 0:
                index.append(np.full(k[i], p))
                position.append(np.full(k[i], a))
                column.append(offsets[i] + np.arange(k[i]))
                vector.append(V[i])
    index, position = np.concatenate(index), np.concatenate(position)
    column, vector = np.concatenate(column), np.concatenate(vector)
    M = base[index]
    M[np.arange(len(M)), position] = vector
    grad = np.zeros((P, int(offsets[-1])))
    grad[index, column] = np.linalg.det(M)

    def spread(coefficients):  # largest |c.delta| over the cell, (Q, R) -> (Q,)
        lo = hi = 0.0
        for i in range(m):
            c = coefficients[:, offsets[i] : offsets[i + 1]]
            centre = c @ lam0[i]
            lo = lo + c.min(axis=1) - centre
            hi = hi + c.max(axis=1) - centre
        return np.maximum(-lo, hi)

    # a subset whose nu or some x_j spans 0 by its linear part alone fails with the remainder
    # too: its polynomials are left out before the costly remainders
    owner_subset = np.array(owner_subset)
    linear = spread(grad)
    near_zero = np.abs(P0) <= linear
    keep = np.ones(P, bool)
    for s in np.unique(owner_subset):
        members = owner_subset == s
        keep[members] = not np.any(near_zero[members]) and P0[members][0] > 0.0
    if not keep.any():
        return np.zeros((0, int(offsets[-1])))
    rows = [r for r, k in zip(rows, keep) if k]
    base, P0, grad, owner_subset = base[keep], P0[keep], grad[keep], owner_subset[keep]
    P = len(base)

    # pair terms: largest |det| over vertex pairs of the differences, per (polynomial, pair)
    index, pos1, pos2, vec1, vec2, group = [], [], [], [], [], []
    g = 0
    for p, r in enumerate(rows):
        contacts = [(a, i) for a, i in enumerate(r) if i >= 0]
        for (a, i), (b, j) in combinations(contacts, 2):
            n = k[i] * k[j]
            index.append(np.full(n, p))
            pos1.append(np.full(n, a))
            pos2.append(np.full(n, b))
            vec1.append(np.repeat(D[i], k[j], axis=0))
            vec2.append(np.tile(D[j], (k[i], 1)))
            group.append(np.full(n, g))
            g += 1
    index, group = np.concatenate(index), np.concatenate(group)
    M = base[index]
    at = np.arange(len(M))
    M[at, np.concatenate(pos1)] = np.concatenate(vec1)
    M[at, np.concatenate(pos2)] = np.concatenate(vec2)
    largest = np.zeros(g)
    np.maximum.at(largest, group, np.abs(np.linalg.det(M)))
    remainder = np.zeros(P)
    starts = np.r_[0, np.flatnonzero(np.diff(group)) + 1]
    np.add.at(remainder, index[starts], largest)
    # three rows or more: Fischer (a fixed row nh is orthogonal to the others at lam0)
    for p, r in enumerate(rows):
        contacts = [i for i in r if i >= 0]
        for size in range(3, len(contacts) + 1):
            for T in combinations(contacts, size):
                rest = tuple(sorted(i for i in contacts if i not in T))
                remainder[p] += float(np.prod(eps[list(T)])) * volume[rest]
    # round-off of the determinants
    row_eps = np.array([[eps[i] if i >= 0 else 0.0 for i in r] for r in rows])
    lengths = np.prod(np.linalg.norm(base, axis=2) + row_eps, axis=1)
    remainder += FACET_ROUND_OFF * lengths

    width = spread(grad) + remainder
    centre = np.concatenate(lam0)
    out = []
    for s in np.unique(owner_subset):
        nu, *xs = np.flatnonzero(owner_subset == s)  # nu first, then the x_j
        xs = np.array(xs)
        L, H = P0[nu], width[nu]
        Lmin = L - H
        sign = np.where(P0[xs] - width[xs] > 0.0, 1, np.where(P0[xs] + width[xs] < 0.0, -1, 0))
        if not Lmin > 0.0 or np.any(sign == 0):
            continue
        for side in (1, -1):
            chosen = xs[sign == side]
            if not len(chosen):  # s(side n) = 0 on the whole cell
                out.append(np.zeros(int(offsets[-1])))
                continue
            X0 = side * P0[chosen].sum()
            RX = remainder[chosen].sum()
            q0 = max(X0 / L, 0.0)
            c = side * grad[chosen].sum(axis=0) - q0 * grad[nu]
            slack = RX + q0 * remainder[nu]
            Z = spread(c[None])[0] + slack
            row = c / L
            const = q0 + slack / L + Z * H / (L * Lmin) - row @ centre
            out.append(row + const / m)
    A = np.array(out).reshape(-1, int(offsets[-1]))
    return A * unit


class _Chart:
    """Coordinates of a convex piece (its vertices (k, 3) in order around it) in units of its
    size: 0 for a point, 1 for a segment, 2 for a polygon; with the nearest point of the piece
    to any coordinates, and the affine map to the contact's wrench (its vertex wrenches rows)."""

    def __init__(self, vertices: np.ndarray, rows: np.ndarray):
        self.origin = vertices.mean(axis=0)
        centred = vertices - self.origin
        size = float(np.max(np.linalg.norm(centred, axis=1)))
        k = len(vertices)
        dim = 0 if k == 1 or size == 0.0 else (1 if k == 2 else 2)
        self.dim = dim
        # axes from the vertices themselves (not an SVD, whose basis of a square's plane turns
        # with round-off): along the first edge, and across it towards the other vertices (all
        # on one side of it, the piece being convex)
        axes = np.zeros((dim, 3))
        if dim:
            edges = vertices[1:] - vertices[0]
            axes[0] = edges[0] / np.linalg.norm(edges[0])
        if dim == 2:
            across = edges - np.outer(edges @ axes[0], axes[0])
            j = int(np.argmax(np.linalg.norm(across, axis=1)))
            axes[1] = across[j] / np.linalg.norm(across[j])
        self.axes = axes * size
        # vertices in coordinates (k, dim): unit size, so one step length fits every piece
        self.corners = centred @ self.axes.T / size**2 if dim else np.zeros((k, 0))
        # the wrench is affine in the position: exact least squares through the vertices
        design = np.hstack([self.corners, np.ones((k, 1))])
        self.wrench_map = np.linalg.lstsq(design, rows, rcond=None)[0]  # (dim + 1, 6)
        if dim == 2:
            q = self.corners
            area = np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1])
            self.orientation = 1.0 if area > 0 else -1.0

    def coordinates(self, weights: np.ndarray) -> np.ndarray:
        return weights @ self.corners

    def position(self, x: np.ndarray) -> np.ndarray:
        return self.origin + x @ self.axes

    def wrench(self, x: np.ndarray) -> np.ndarray:
        return x @ self.wrench_map[:-1] + self.wrench_map[-1]

    def nearest(self, x: np.ndarray) -> np.ndarray:
        """The piece's nearest points to ``x`` (N, dim)."""
        if self.dim == 0:
            return x
        if self.dim == 1:
            lo, hi = sorted(self.corners[:, 0])
            return np.clip(x, lo, hi)
        q, inside = self.corners, np.ones(len(x), bool)
        out, distance = x.copy(), np.full(len(x), np.inf)
        for j in range(len(q)):
            a, e = q[j], q[(j + 1) % len(q)] - q[j]
            d = x - a
            inside &= self.orientation * (e[0] * d[:, 1] - e[1] * d[:, 0]) >= 0.0
            t = np.clip(d @ e / (e @ e), 0.0, 1.0)
            foot = a + t[:, None] * e
            gap = np.linalg.norm(x - foot, axis=1)
            closer = gap < distance
            distance[closer], out[closer] = gap[closer], foot[closer]
        out[inside] = x[inside]
        return out


def climb(
    vertices: list[np.ndarray],
    rows: list[np.ndarray],
    starts: list[np.ndarray],
    iterations: int,
    seed: int = 0,
    step: float = 0.2,
) -> tuple[list[np.ndarray], np.ndarray]:
    """A population of placements improved by random steps that are kept when they raise
    :func:`frictionless_capacity` (each member its own step length: longer after a success,
    shorter after a failure; steps in units of each piece's size, projected onto the piece).

    Parameters
    ----------
    vertices : list of (k_i, 3) float
        Each contact's piece: a point, a segment or a convex polygon (vertices in order).
    rows : list of (k_i, 6) float
        The contact's wrench ``f_max (n, torque_scale * r x n)`` at each vertex (affine in the
        position on the piece).
    starts : list of (N, k_i) float
        Each contact's barycentric weights of the ``N`` members at the start.
    iterations : int
    seed : int
    step : float
        First step length (in piece sizes).

    Returns
    -------
    positions : list of (N, 3) float
        Each contact's final positions, member by member.
    values : (N,) float
        The members' capacities.
    """
    rng = np.random.default_rng(seed)
    charts = [_Chart(np.asarray(v, float), np.asarray(r, float)) for v, r in zip(vertices, rows)]
    x = [c.coordinates(np.asarray(w, float)) for c, w in zip(charts, starts)]
    N = len(x[0])

    def value(points):
        return frictionless_capacity(np.stack([c.wrench(p) for c, p in zip(charts, points)], 1))

    f = value(x)
    sigma = np.full(N, step)
    for _ in range(iterations):
        trial = [
            c.nearest(p + sigma[:, None] * rng.standard_normal(p.shape)) for c, p in zip(charts, x)
        ]
        g = value(trial)
        better = g > f
        x = [np.where(better[:, None], t, p) for t, p in zip(trial, x)]
        f = np.where(better, g, f)
        sigma = np.clip(np.where(better, 1.5 * sigma, 0.85 * sigma), 1e-7, 0.5)
    return [c.position(p) for c, p in zip(charts, x)], f


__all__ = ["MAX_CONTACTS", "climb", "facet_rows", "frictionless_capacity"]
