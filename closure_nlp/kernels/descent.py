"""Compiled descents of a support function over the unit sphere: the batched subgradient
descent of :func:`closure_nlp.sphere_search.descend`, and a local minimiser (gradient
sampling) that the default search and the certificate's incumbent use."""

from __future__ import annotations

import numpy as np
from numba import njit

from .arrays import copy_into, dot
from .branch_bound import cloud, normalise
from .nearest_point import TOL, min_norm_point
from .support import OPTIONS, scratch, support_point, support_value


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
