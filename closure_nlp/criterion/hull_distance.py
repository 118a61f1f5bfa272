"""The point of a convex set nearest the origin, from its support function alone.

When the origin lies outside ``W`` (some direction has ``p(u) < 0``), ``rho = dist(0, W)``, and
both sides have certificates: ``dist(0, W) >= -p(u)`` for every unit ``u``, and
``dist(0, W) <= |x|`` for every point ``x`` of ``W``, for instance a convex combination of
support points. The loop is Gilbert's (GJK's in collision detection): ``x`` is the point of the
hull of the support points kept so far nearest the origin (Wolfe's exact algorithm), the next
support point is the one at ``-x / |x|``; the two bounds meet at the distance. Both run compiled
(:mod:`closure_nlp.kernels.nearest_point`).
"""

from __future__ import annotations

import numpy as np

from closure_nlp.base.validation import as_shaped, as_whole
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.kernels import kernel_array
from closure_nlp.kernels import nearest_point as kernels


def min_norm_point(points: np.ndarray, tol: float = 1e-15):
    """Wolfe's algorithm: the point of ``conv(points)`` nearest the origin.

    Parameters
    ----------
    points : (n, d) float
    tol : float
        Relative optimality tolerance (against the largest squared norm of the points).

    Returns
    -------
    x : (d,) float
        A convex combination of the points (exactly, up to the combination's roundoff).
    weights : (n,) float
        Its convex weights (non-negative, summing to 1).
    """
    points = as_shaped(points, "points", ("n", "d"))
    if len(points) == 0:  # the weights' first entry is written whatever the points
        raise ValueError(f"points: expected at least one point, got shape {points.shape}")
    if not np.isfinite(points).all():  # the kernel would answer NaN without a word
        raise ValueError("points: numbers must be finite (a NaN or infinite entry)")
    return kernels.min_norm_point(kernel_array(points), float(tol))


def nearest_point_bounds(slots: WrenchSlots, u0: np.ndarray, gap: float, max_iter: int = 200):
    """Certified ``lo <= dist(0, W) <= hi`` when ``p(u0) < 0`` (the origin outside ``W``).

    Returns ``(lo, hi, u, converged, evaluations)``: ``u`` is the unit direction with the lowest
    support value found, ``lo = -p(u)``.
    """
    u0 = as_shaped(u0, "u0", (6,))
    max_iter = as_whole(max_iter, "max_iter", 0)  # the kernel keeps a point per iteration
    lo, hi, u, evaluations = kernels.nearest_point_bounds(
        *slots.packed, _start_directions(u0), float(gap), max_iter
    )
    return lo, hi, u, hi - lo <= gap, evaluations


def _start_directions(u0: np.ndarray) -> np.ndarray:
    """``u0`` and a small cross-polytope around it: support points on every side of the foot."""
    Q, _ = np.linalg.qr(np.column_stack([u0, np.eye(6)]))
    E = Q[:, 1:6].T
    U = np.vstack([u0, u0 + 0.1 * E, u0 - 0.1 * E])
    return kernel_array(U / np.linalg.norm(U, axis=1, keepdims=True))
