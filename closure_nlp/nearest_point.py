"""The point of a convex set nearest the origin, from its support function alone.

When the origin lies outside ``W`` (some direction has ``p(u) < 0``), ``rho = dist(0, W)``, and
both sides have certificates: ``dist(0, W) >= -p(u)`` for every unit ``u``, and
``dist(0, W) <= |x|`` for every point ``x`` of ``W``, for instance a convex combination of
support points. The loop is Gilbert's (GJK's in collision detection): ``x`` is the point of the
hull of the support points kept so far nearest the origin (Wolfe's exact algorithm), the next
support point is the one at ``-x / |x|``; the two bounds meet at the distance.
"""

from __future__ import annotations

import numpy as np

from .wrenches import WrenchSlots

STALL = 10  # steps without progress after which the bracket is returned as it is
MAX_LINE_STEPS = 20  # Wolfe's fallback steps in a row (roundoff) before it returns its point


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
    P = np.asarray(points, dtype=float)
    n = len(P)
    # Wolfe's steps are scale-free; run them on points of unit size (any f_max, any units).
    size = float(np.max(np.abs(P))) if P.size else 0.0
    if not size > 0:
        return np.zeros(P.shape[1]), np.eye(n)[0]
    P = P / size
    norms2 = np.einsum("ij,ij->i", P, P)
    scale = max(float(norms2.max()), 1e-300)
    S = [int(np.argmin(norms2))]
    lam = np.array([1.0])
    fallbacks = 0  # steps since the last proper Wolfe step: line steps are slow, a few polish
    for _ in range(50 * (n + 1)):
        x = lam @ P[S]
        j = int(np.argmin(P @ x))
        if x @ x - x @ P[j] <= tol * scale or fallbacks == MAX_LINE_STEPS:
            break
        fallbacks += 1
        if j in S:
            # x is not quite the affine minimiser of S (roundoff of a nearly singular system,
            # e.g. points that nearly repeat): step towards P[j] instead.
            step = _line_step(S, lam, x, P, j)
            if step is None:
                break
            S, lam = step
            continue
        before = (list(S), lam.copy())
        S.append(j)
        lam = np.append(lam, 0.0)
        for _ in range(len(S)):  # minor cycle: each step drops a point, so it ends
            mu = _affine_minimizer(P[S])
            if np.all(mu > 0):
                lam = mu
                break
            neg = mu <= 0
            theta = np.min(lam[neg] / (lam[neg] - mu[neg]))
            lam = lam + theta * (mu - lam)
            keep = lam > 1e-15
            S = [s for s, k in zip(S, keep) if k]
            lam = lam[keep]
            lam /= lam.sum()
        if j in S:
            fallbacks = 0
        else:
            # Roundoff in a nearly singular minor cycle dropped the improving point again (a
            # cycle Wolfe's exact arithmetic excludes): step towards it instead.
            S, lam = before
            step = _line_step(S, lam, x, P, j)
            if step is None:
                break
            S, lam = step
    weights = np.zeros(n)
    weights[S] = lam
    return weights @ (P * size), weights


def _line_step(S, lam, x, P, j):
    """``x`` moved towards ``P[j]`` by exact line search, as new (S, lam); None when the step
    is zero. It shortens ``x`` whenever ``x . P[j] < x . x``."""
    S, lam = list(S), lam.copy()
    d = P[j] - x
    gamma = float(np.clip(-(x @ d) / (d @ d), 0.0, 1.0)) if d @ d > 0 else 0.0
    if not gamma > 0:
        return None
    lam *= 1.0 - gamma
    if j in S:
        lam[S.index(j)] += gamma
    else:
        S, lam = S + [j], np.append(lam, gamma)
    return S, lam


def _affine_minimizer(P: np.ndarray) -> np.ndarray:
    """Weights ``mu`` (summing to 1) of the point of the affine hull of ``P`` nearest 0.

    ``P[0] + sum_i z_i (P[i] - P[0])``, least squares on the differences: not on their Gram
    matrix, whose condition number is the square (points that nearly repeat made the Gram
    system lose the last digits that decide which point leaves)."""
    if len(P) == 1:
        return np.ones(1)
    z = np.linalg.lstsq((P[1:] - P[0]).T, -P[0], rcond=None)[0]
    return np.concatenate([[1.0 - z.sum()], z])


def nearest_point_bounds(slots: WrenchSlots, u0: np.ndarray, gap: float, max_iter: int = 200):
    """Certified ``lo <= dist(0, W) <= hi`` when ``p(u0) < 0`` (the origin outside ``W``).

    Returns ``(lo, hi, u, converged, evaluations)``: ``u`` is the unit direction with the lowest
    support value found, ``lo = -p(u)``.
    """
    U = _start_directions(u0)
    values, points = slots.evaluate(U)
    best = int(np.argmin(values))
    lo, best_u = -float(values[best]), U[best]
    x, w = min_norm_point(points)
    hi = float(np.linalg.norm(x))
    kept = points[w > 0]
    evaluations = len(U)
    stalled = 0
    for _ in range(max_iter):
        if hi - lo <= gap or not hi > 0 or stalled >= STALL:
            break  # converged, or the last steps added nothing (the bracket stays valid)
        u = -x / np.linalg.norm(x)
        value, point = slots.evaluate(u[None])
        evaluations += 1
        if -value[0] > lo:
            lo, best_u = -float(value[0]), u
        kept = np.vstack([kept, point])
        x, w = min_norm_point(kept)
        norm = float(np.linalg.norm(x))
        stalled = stalled + 1 if norm >= hi * (1.0 - 1e-15) else 0
        hi = min(hi, norm)
        kept = kept[w > 0]
    return lo, max(hi, lo), best_u, hi - lo <= gap, evaluations


def _start_directions(u0: np.ndarray) -> np.ndarray:
    """``u0`` and a small cross-polytope around it: support points on every side of the foot."""
    Q, _ = np.linalg.qr(np.column_stack([u0, np.eye(6)]))
    E = Q[:, 1:6].T
    U = np.vstack([u0, u0 + 0.1 * E, u0 - 0.1 * E])
    return U / np.linalg.norm(U, axis=1, keepdims=True)
