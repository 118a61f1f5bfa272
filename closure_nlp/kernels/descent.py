"""Compiled descents of a support function over the unit sphere: the batched subgradient
descent of :func:`closure_nlp.sphere_search.descend` (on ``p``, and the steps of its smoothed
descent), and a local minimiser (gradient sampling) that the default search and the
certificate's incumbent use."""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import copy_into, dot
from .branch_bound import cloud, normalise
from .nearest_point import TOL, min_norm_point
from .support import D_VALUE, OPTIONS, no_vector, scratch, set_value, support_point, support_value


@njit(**OPTIONS)
def _rotate(u, direction, angle, out):
    """``cos(angle) u + sin(angle) direction``, normalised, into ``out``."""
    c, s = np.cos(angle), np.sin(angle)
    for k in range(6):
        out[k] = c * u[k] + s * direction[k]
    normalise(out)


@njit(**OPTIONS)
def descend_many(G, f, W, npc, ends, U0, iterations, stop):
    """Riemannian (sub)gradient descent from every row of ``U0`` (N, 6) at once, a step angle
    per direction that grows on success and halves on failure (values only decrease); ends
    once some value is at or below ``stop``. Returns unit end directions (N, 6) and ``p``
    there (N,)."""
    D = scratch(f)
    N = len(U0)
    U = np.empty((N, 6))
    values = np.empty(N)
    grads = np.empty((N, 6))
    angle = np.empty(N)
    lowest = np.inf
    for n in range(N):
        copy_into(U[n], U0[n])
        normalise(U[n])
        values[n] = support_point(G, f, W, npc, ends, U[n], grads[n], D)
        lowest = min(lowest, values[n])
        angle[n] = 0.3
    step = np.empty(6)
    trial = np.empty(6)
    trial_grad = np.empty(6)
    for _ in range(iterations):
        if lowest <= stop:
            break
        for n in range(N):
            gu = dot(grads[n], U[n])
            norm = 0.0
            for k in range(6):
                step[k] = -(grads[n, k] - gu * U[n, k])
                norm += step[k] * step[k]
            norm = np.sqrt(norm)
            if not norm > 1e-12:
                angle[n] *= 0.5
                continue
            for k in range(6):
                step[k] /= norm
            _rotate(U[n], step, angle[n], trial)
            v = support_point(G, f, W, npc, ends, trial, trial_grad, D)
            if v < values[n]:
                copy_into(U[n], trial)
                copy_into(grads[n], trial_grad)
                values[n] = v
                lowest = min(lowest, v)
                angle[n] = min(angle[n] * 1.5, 0.6)
            else:
                angle[n] *= 0.5
    return U, values


# Iterations of the local minimiser with the plain step (twice the last accepted angle) before
# the Barzilai-Borwein step becomes the first trial: a run that converges with the plain step
# (kinked or well-conditioned minima) is left as it is; one that crawls along a smooth piece
# (round cones, soft fingers) takes secant steps.
PLAIN_ITERATIONS = 150


@njit(**OPTIONS)
def _bb_angle(u, g, last_u, last_g):
    """The Barzilai-Borwein step along ``-g`` at ``u`` as a rotation angle: ``|s|^2 / (s.y)``
    times ``|g|``, with ``s`` the last move and ``y`` the change of ``g``, both taken into the
    tangent space at ``u`` (projection: the transport to first order); 0 when ``s.y <= 0``
    (no positive curvature along the move: no secant step)."""
    su = 0.0
    lu = 0.0
    for k in range(6):
        su += (u[k] - last_u[k]) * u[k]
        lu += last_g[k] * u[k]
    ss = 0.0
    sy = 0.0
    gg = 0.0
    for k in range(6):
        s = u[k] - last_u[k] - su * u[k]
        y = g[k] - (last_g[k] - lu * u[k])
        ss += s * s
        sy += s * y
        gg += g[k] * g[k]
    if not sy > 0.0:
        return 0.0
    return ss / sy * np.sqrt(gg)


@njit(**OPTIONS)
def local_minimum(G, f, W, npc, ends, u0, max_iter, smallest):
    """A local minimum of ``p`` on the sphere near ``u0`` by gradient sampling: the shortest
    convex combination ``g`` of the tangential parts of the support points of a cloud of radius
    ``eps`` around ``u`` (they hold every piece of ``p`` meeting within ``eps``), a backtracking
    step along ``-g`` (its first trial twice the last accepted angle, or, after
    :data:`PLAIN_ITERATIONS`, the Barzilai-Borwein step of the last two iterates: on a smooth
    piece a secant step, far fewer iterations than a step grown from the last one), and
    ``eps`` cut tenfold once ``|g|`` is below ``eps`` times the wrench scale (stationary at
    that resolution) or no step lowers ``p``; done below ``smallest``.

    Returns (unit direction, value, iterations, converged)."""
    D = scratch(f)
    u = np.empty(6)
    copy_into(u, u0)
    normalise(u)
    value = support_value(G, f, W, npc, ends, u, D)
    directions = np.empty((11, 6))
    points = np.empty((11, 6))
    tangent = np.empty((11, 6))
    trial = np.empty(6)
    step = np.empty(6)
    scales = np.empty(1)
    last_u = np.empty(6)
    last_g = np.empty(6)
    paired = False  # last_u, last_g hold the previous iterate at the same eps
    eps, angle = 1e-2, 1e-2
    iterations = 0
    while iterations < max_iter and eps >= smallest:
        iterations += 1
        scales[0] = eps
        cloud(u, scales, directions)
        size = 0.0
        for i in range(11):
            support_point(G, f, W, npc, ends, directions[i], points[i], D)
            a = dot(points[i], u)
            for k in range(6):
                tangent[i, k] = points[i, k] - a * u[k]
            size = max(size, np.sqrt(dot(points[i], points[i])))
        g = min_norm_point(tangent, TOL)[0]
        gn = np.sqrt(dot(g, g))
        if not gn > eps * size:
            eps *= 0.1
            paired = False
            continue
        for k in range(6):
            step[k] = -g[k] / gn
        angle = min(2.0 * angle, 0.5)
        if paired and iterations > PLAIN_ITERATIONS:
            secant = _bb_angle(u, g, last_u, last_g)
            if secant > 0.0:
                angle = min(secant, 0.5)
        copy_into(last_u, u)
        copy_into(last_g, g)
        moved = False
        while angle > 1e-3 * smallest:
            _rotate(u, step, angle, trial)
            v = support_value(G, f, W, npc, ends, trial, D)
            if v <= value - 1e-4 * angle * gn:
                copy_into(u, trial)
                value = v
                moved = True
                break
            angle *= 0.5
        paired = moved
        if not moved:
            eps *= 0.1
            angle = eps
    return u, value, iterations, eps < smallest


# The smoothed descent of a set with one row per slot (contacts), in the order of numpy's
# operations in :func:`closure_nlp.sphere_search.descend` (its ``tau`` branch), so that both end
# at the same directions to the bit: sums in numpy's orders (:func:`_pairwise_sum`, the
# sequential einsum, :func:`_dot6`), exp, log, log1p, sin and cos from the same C library as
# numpy's (numpy builds for AVX-512 have their own exp and log: there the two agree to
# round-off, not to the bit). numpy's tanh (its own SIMD code) stays in numpy: the caller
# applies it between :func:`smoothed_terms` and :func:`smoothed_values`.
PAIRWISE_BLOCK = 128


@njit(**OPTIONS)
def _pairwise_sum(a, lo, hi):
    """``a[lo:hi].sum()`` in numpy's order (its pairwise summation of a contiguous axis) for
    up to :data:`PAIRWISE_BLOCK` terms (numpy splits longer ones in halves: not done here, a
    recursive kernel crashes when loaded from numba's disk cache)."""
    n = hi - lo
    if n < 8:
        total = 0.0
        for i in range(lo, hi):
            total += a[i]
        return total
    r = a[lo : lo + 8].copy()
    i = lo + 8
    while i < hi - n % 8:
        for j in range(8):
            r[j] += a[i + j]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < hi:
        total += a[i]
        i += 1
    return total


@njit(**OPTIONS)
def _dot6(a, b):
    """``einsum("r,r->", a, b)`` of two (6,) in numpy's order (two SIMD lanes)."""
    even = ((0.0 + a[0] * b[0]) + a[2] * b[2]) + a[4] * b[4]
    odd = ((0.0 + a[1] * b[1]) + a[3] * b[3]) + a[5] * b[5]
    return 0.0 + (even + odd)


@njit(**OPTIONS)
def _logaddexp0(y):
    """``np.logaddexp(0.0, y)`` (numpy's formula)."""
    if y == 0.0:
        return 0.0 + np.log(2.0)
    t = 0.0 - y
    if t > 0.0:
        return 0.0 + np.log1p(np.exp(-t))
    if t <= 0.0:
        return y + np.log1p(np.exp(t))
    return t


@njit(**OPTIONS)
def smoothed_terms(G, f, W, npc, ends, U, tau, active, P, wrench, weights, top, X):
    """Each row's value ``P`` (N, K) and support wrench (N, K, 6), the softmax ``weights``
    (N, K) and log-sum-exp ``top`` (N,) of the rows, at the directions ``U`` (N, 6) marked
    ``active``; into ``X`` (N, K + 1) the arguments whose tanh the sigmoids of
    :func:`smoothed_values` take (``P / tau`` and ``-top / tau``, halved). One row per slot."""
    K = len(f)
    D = scratch(f)
    e = np.empty(K)
    for n in range(len(U)):
        if not active[n]:
            continue
        set_value(G, f, W, npc, ends, U[n], D, None, no_vector(D), wrench[n])
        for r in range(K):
            P[n, r] = D[D_VALUE, r] + 0.0  # as numpy's ``rows + 0.0``: no -0.0
        largest = P[n, 0]
        for r in range(1, K):  # np.maximum's: a NaN wins
            if not (largest >= P[n, r] or np.isnan(largest)):
                largest = P[n, r]
        for r in range(K):
            e[r] = np.exp((P[n, r] - largest) / tau)
        total = e[0] + _pairwise_sum(e, np.int64(1), K) if K > 1 else e[0]
        top[n] = largest + tau * np.log(total)
        for r in range(K):
            weights[n, r] = e[r] / total
            X[n, r] = 0.5 * (P[n, r] / tau)
        X[n, K] = 0.5 * (-top[n] / tau)


@njit(**OPTIONS)
def smoothed_values(P, wrench, weights, top, T, tau, active, values, grads):
    """The smoothed value (N,) and gradient (N, 6) from :func:`smoothed_terms` and ``T``
    (N, K + 1), the tanh of its ``X``, at the ``active`` directions."""
    K = P.shape[1]
    lse = np.empty(K)
    outer = np.empty(K)
    for n in range(len(P)):
        if not active[n]:
            continue
        for r in range(K):
            lse[r] = _logaddexp0(P[n, r] / tau)
        values[n] = tau * _pairwise_sum(lse, np.int64(0), K) - tau * _logaddexp0(-top[n] / tau)
        below = 0.5 * (1.0 + T[n, K])
        for r in range(K):
            outer[r] = 0.5 * (1.0 + T[n, r]) + below * weights[n, r]
        for k in range(6):
            g = 0.0
            for r in range(K):
                g = g + outer[r] * wrench[n, r, k]
            grads[n, k] = g


@njit(**OPTIONS)
def smoothed_trials(U, grads, angle, trial, moving):
    """Each direction's trial: the step ``angle`` along its negative tangential gradient;
    ``moving`` False where that gradient vanishes (no trial)."""
    tangent = np.empty(6)
    for n in range(len(U)):
        gu = _dot6(grads[n], U[n])
        for k in range(6):
            tangent[k] = grads[n, k] - gu * U[n, k]
        norm = np.sqrt(dot(tangent, tangent))  # np.linalg.norm's sum, in its order
        moving[n] = norm > 1e-12
        if not moving[n]:
            continue
        c, s = np.cos(angle[n]), np.sin(angle[n])
        for k in range(6):
            trial[n, k] = c * U[n, k] + s * (-tangent[k] / norm)
        length = np.sqrt(dot(trial[n], trial[n]))
        for k in range(6):
            trial[n, k] /= length


@njit(**OPTIONS)
def smoothed_accept(U, values, grads, angle, trial, moving, trial_values, trial_grads):
    """Each moving direction takes its trial where the value fell (its angle grows by 1.5,
    at most 0.6), else its angle halves."""
    for n in range(len(U)):
        if moving[n] and trial_values[n] < values[n]:
            for k in range(6):
                U[n, k] = trial[n, k]
                grads[n, k] = trial_grads[n, k]
            values[n] = trial_values[n]
            angle[n] = min(angle[n] * 1.5, 0.6)
        else:
            angle[n] *= 0.5
