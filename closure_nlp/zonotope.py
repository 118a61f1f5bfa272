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

It serves the search of a placement: a placement's capacity costs ``C(m, 5)`` pairs of small
determinants, batched over thousands of placements at once (:func:`climb`), where the certified
rho solver spends milliseconds on one; the placements found are then certified by that solver.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

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
    W = np.asarray(W, float)
    if W.ndim != 3 or W.shape[2] != 6:
        raise ValueError(f"W: expected shape (B, m, 6), got {W.shape}")
    B, m, _ = W.shape
    if m < 7:
        return np.zeros(B)
    if m > MAX_CONTACTS:
        raise ValueError(f"W: expected at most {MAX_CONTACTS} contacts, got {m}")
    # a common unit: the determinants are then of order one in any unit of length or force
    unit = np.max(np.abs(W), axis=(1, 2), keepdims=True)
    unit = np.where(unit > 0.0, unit, 1.0)
    V = W / unit
    best = np.full(B, np.inf)
    for S in combinations(range(m), 5):
        rest = [j for j in range(m) if j not in S]
        base = V[:, list(S)]  # (B, 5, 6)
        stacked = np.concatenate(
            [np.broadcast_to(base[:, None], (B, len(rest), 5, 6)), V[:, rest, None, :]], axis=2
        )
        x = np.linalg.det(stacked)  # (B, len(rest)): <w_j, n_S>
        norm2 = np.linalg.det(base @ base.transpose(0, 2, 1))
        # S spans no facet when its generators are (nearly) dependent: their volume against
        # the product of their lengths below 1e-8, where the determinants lose their digits
        lengths2 = np.prod(np.einsum("bij,bij->bi", base, base), axis=1)
        full = norm2 > 1e-16 * lengths2
        norm = np.sqrt(np.where(full, norm2, 1.0))
        up = np.maximum(x, 0.0).sum(axis=1)
        down = np.maximum(-x, 0.0).sum(axis=1)
        value = np.minimum(up, down) / norm
        best = np.where(full, np.minimum(best, value), best)
    best = np.where(np.isfinite(best), best, 0.0)
    return best * unit[:, 0, 0]


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


__all__ = ["MAX_CONTACTS", "climb", "frictionless_capacity"]
