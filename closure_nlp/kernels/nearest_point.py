"""Compiled nearest point of a convex hull to the origin (Wolfe), and Gilbert's iteration on a
support function: the mathematics of :mod:`closure_nlp.nearest_point`."""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import copy_into, dot
from .least_squares import least_squares
from .support import OPTIONS, scratch, support_point

MAX_LINE_STEPS = 20  # Wolfe's fallback steps in a row (roundoff) before it returns its point
STALL = 10  # Gilbert steps without progress after which the bracket is returned as it is
TOL = 1e-15  # Wolfe's default optimality tolerance (the kernels pass it: one compile)


@njit(**OPTIONS)
def _affine_minimizer(P, S, k, mu):
    """Weights ``mu[:k]`` (summing to 1) of the point of the affine hull of ``P[S[:k]]``
    nearest 0, by least squares on the differences (not their Gram matrix, whose condition
    number is the square)."""
    if k == 1:
        mu[0] = 1.0
        return
    dim = P.shape[1]
    A = np.empty((dim, k - 1))
    b = np.empty(dim)
    z = np.empty(k - 1)
    for d in range(dim):
        b[d] = -P[S[0], d]
        for i in range(1, k):
            A[d, i - 1] = P[S[i], d] - P[S[0], d]
    least_squares(A, b, z)
    mu[0] = 1.0
    for i in range(1, k):
        mu[i] = z[i - 1]
        mu[0] -= z[i - 1]


@njit(**OPTIONS)
def _current(P, S, lam, k):
    x = np.zeros(P.shape[1])
    for i in range(k):  # loops, not array arithmetic (numba compiles numpy's broadcasting)
        for d in range(P.shape[1]):
            x[d] += lam[i] * P[S[i], d]
    return x


@njit(**OPTIONS)
def _line_step(S, lam, k, x, P, j):
    """``x`` moved towards ``P[j]`` by exact line search; returns the new count, or -1 when
    the step is zero."""
    dd, xd = 0.0, 0.0
    for q in range(len(x)):
        d = P[j, q] - x[q]
        dd += d * d
        xd += x[q] * d
    gamma = min(1.0, max(0.0, -xd / dd)) if dd > 0.0 else 0.0
    if not gamma > 0.0:
        return -1
    keep = 1.0 - gamma
    for i in range(k):
        lam[i] *= keep
    for i in range(k):
        if S[i] == j:
            lam[i] += gamma
            return k
    S[k], lam[k] = j, gamma
    return k + 1


@njit(**OPTIONS)
def min_norm_point(points, tol=TOL):
    """Wolfe's algorithm: the point of ``conv(points)`` (n, d) nearest the origin and its
    convex weights (n,)."""
    n, dim = points.shape
    weights = np.zeros(n)
    point = np.zeros(dim)
    size = 0.0
    for i in range(n):
        for d in range(dim):
            size = max(size, abs(points[i, d]))
    if not size > 0.0:
        weights[0] = 1.0
        return point, weights
    P = np.empty((n, dim))  # Wolfe's steps are scale-free: points of unit size
    scale, first, low = 1e-300, 0, np.inf
    for i in range(n):
        for d in range(dim):
            P[i, d] = points[i, d] / size
        norm2 = dot(P[i], P[i])
        scale = max(scale, norm2)
        if norm2 < low:  # the first of equal norms, as np.argmin
            first, low = i, norm2
    S = np.empty(n + 1, np.int64)
    lam = np.zeros(n + 1)
    mu = np.empty(n + 1)
    S[0], lam[0], k = first, 1.0, np.int64(1)  # not a literal: one compile
    S_before = np.empty(n + 1, np.int64)
    lam_before = np.empty(n + 1)
    fallbacks = 0
    for _ in range(50 * (n + 1)):
        x = _current(P, S, lam, k)
        j, low = np.int64(0), np.inf  # not a literal: one compile of _line_step
        for i in range(n):
            v = dot(P[i], x)
            if v < low:
                j, low = i, v
        if dot(x, x) - low <= tol * scale or fallbacks == MAX_LINE_STEPS:
            break
        fallbacks += 1
        inside = False
        for i in range(k):
            inside |= S[i] == j
        if inside:  # roundoff of a nearly singular system: step towards P[j] instead
            k2 = _line_step(S, lam, k, x, P, j)
            if k2 < 0:
                break
            k = k2
            continue
        copy_into(S_before, S)
        copy_into(lam_before, lam)
        k_before = k
        S[k], lam[k] = j, 0.0
        k += 1
        for _ in range(k):  # minor cycle: each step drops a point, so it ends
            _affine_minimizer(P, S, k, mu)
            positive = True
            for i in range(k):
                positive &= mu[i] > 0.0
            if positive:
                for i in range(k):
                    lam[i] = mu[i]
                break
            theta = np.inf
            for i in range(k):
                if mu[i] <= 0.0:
                    theta = min(theta, lam[i] / (lam[i] - mu[i]))
            kept = 0
            for i in range(k):
                value = lam[i] + theta * (mu[i] - lam[i])
                if value > 1e-15:
                    S[kept], lam[kept] = S[i], value
                    kept += 1
            k = kept
            total = 0.0
            for i in range(k):
                total += lam[i]
            for i in range(k):
                lam[i] /= total
        inside = False
        for i in range(k):
            inside |= S[i] == j
        if inside:
            fallbacks = 0
        else:  # roundoff dropped the improving point again: step towards it instead
            copy_into(S, S_before)
            copy_into(lam, lam_before)
            k = k_before
            k2 = _line_step(S, lam, k, x, P, j)
            if k2 < 0:
                break
            k = k2
    for i in range(k):
        weights[S[i]] += lam[i]
    for i in range(n):
        for d in range(dim):
            point[d] += weights[i] * points[i, d]
    return point, weights


@njit(**OPTIONS)
def nearest_point_bounds(G, f, W, npc, ends, U0, gap, max_iter):
    """Gilbert's iteration from the start directions ``U0`` (n, 6): certified ``lo <= dist(0,
    W) <= hi`` when the origin lies outside ``W``. Returns (lo, hi, best direction,
    evaluations)."""
    D = scratch(f)
    n0 = len(U0)
    kept = np.empty((n0 + max_iter, 6))
    lo, best = -np.inf, 0
    for i in range(n0):
        v = support_point(G, f, W, npc, ends, U0[i], kept[i], D)
        if -v > lo:
            lo, best = -v, i
    best_u = np.empty(6)
    copy_into(best_u, U0[best])
    x, w = min_norm_point(kept[:n0], TOL)
    hi = np.sqrt(dot(x, x))
    count = 0
    for i in range(n0):
        if w[i] > 0.0:
            copy_into(kept[count], kept[i])
            count += 1
    evaluations, stalled = n0, 0
    u = np.empty(6)
    for _ in range(max_iter):
        if hi - lo <= gap or not hi > 0.0 or stalled >= STALL:
            break
        norm = np.sqrt(dot(x, x))
        for k in range(6):
            u[k] = -x[k] / norm
        v = support_point(G, f, W, npc, ends, u, kept[count], D)
        count += 1
        evaluations += 1
        if -v > lo:
            lo = -v
            copy_into(best_u, u)
        x, w = min_norm_point(kept[:count], TOL)
        norm = np.sqrt(dot(x, x))
        stalled = stalled + 1 if norm >= hi * (1.0 - 1e-15) else 0
        hi = min(hi, norm)
        kept_now = 0
        for i in range(count):
            if w[i] > 0.0:
                copy_into(kept[kept_now], kept[i])
                kept_now += 1
        count = kept_now
    return lo, max(hi, lo), best_u, evaluations
