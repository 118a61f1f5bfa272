"""Start directions for the non-convex minimum of a support function over the unit sphere.

Minimising a support function over the sphere has real local minima when the origin is inside
the set (one per nearby facet of the set, roughly). IPOPT from the paper's 12 starts ``+-e_k``
misses the global one on some 4-PCwF grasps. Here a cheap batched descent runs from
hundreds of quasi-uniform directions at once (compiled: :mod:`closure_nlp.kernels.descent`); the
lowest distinct end points become the local solver's starts.
"""

from __future__ import annotations

import numpy as np

from closure_nlp.base.validation import as_shaped
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.kernels import descent as kernels
from closure_nlp.kernels import kernel_array

_SAMPLES: dict[tuple[int, int], np.ndarray] = {}


def sphere_samples(n: int, seed: int = 0) -> np.ndarray:
    """(n + 12, 6) float: ``+-e_k`` and ``n`` fixed pseudo-random unit directions (cached)."""
    key = (n, seed)
    if key not in _SAMPLES:
        rng = np.random.default_rng(seed)
        U = rng.standard_normal((n, 6))
        U /= np.linalg.norm(U, axis=1, keepdims=True)
        samples = np.vstack([np.eye(6), -np.eye(6), U])
        samples.flags.writeable = False  # read-only before any thread can see it
        _SAMPLES.setdefault(key, samples)
    return _SAMPLES[key]


def smoothed_support(slots: WrenchSlots, U: np.ndarray, tau: float):
    """A smooth upper approximation of ``p`` and its gradient: (N, 6) -> (N,), (N, 6).

    Every max of ``p`` (over an element's vertex rows, over the subsets of slots) is replaced by
    its log-sum-exp with temperature ``tau`` (``p <= p_tau <= p + O(tau log K)``). The descent
    on ``p`` itself stalls at kinks, where the subgradient flips from step to step; on
    ``p_tau`` it runs into the basin, and lowering ``tau`` sharpens the basins again.
    """
    rows, wrench = slots.row_support(U)
    if rows.shape[1] == slots.m:  # one row per slot (contacts): its log-sum-exp is the row
        P, grad_P = rows + 0.0, wrench  # + 0.0: the same -0.0 the log-sum-exp turns into 0.0
    else:
        P, weights = _soft_max(rows, tau, slots.starts)  # each slot's max over its vertex rows
        grad_P = np.add.reduceat(weights[..., None] * wrench, slots.starts, axis=1)
    # sum_i max(P_i, 0) + min(max_i P_i, 0), both smoothed: softplus and -softplus(-softmax).
    top, weights = _soft_max(P, tau, [0])
    top = top[:, 0]
    value = tau * np.logaddexp(0.0, P / tau).sum(axis=1) - tau * np.logaddexp(0.0, -top / tau)
    outer = _sigmoid(P / tau) + _sigmoid(-top / tau)[:, None] * weights
    return value, np.einsum("nm,nmr->nr", outer, grad_P)


def _soft_max(X: np.ndarray, tau: float, starts):
    """``tau log sum exp(X / tau)`` over each group of columns starting at ``starts``, and its
    gradient (softmax weights within each group): (N, K) -> (N, len(starts)), (N, K)."""
    counts = np.diff(np.append(starts, X.shape[1]))
    top = np.maximum.reduceat(X, starts, axis=1)
    e = np.exp((X - np.repeat(top, counts, axis=1)) / tau)
    total = np.add.reduceat(e, starts, axis=1)
    return top + tau * np.log(total), e / np.repeat(total, counts, axis=1)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))  # no overflow for large |x|


def descend(
    slots: WrenchSlots,
    U: np.ndarray,
    iterations: int = 30,
    tau: float | None = None,
    stop: float = -np.inf,
):
    """Riemannian (sub)gradient descent on the sphere, batched, with a step per direction.

    Each direction steps along the negative tangential (sub)gradient by an angle that grows
    on success and halves on failure, so every direction's value only ever decreases. With
    ``tau`` the descent runs on :func:`smoothed_support` instead of ``p``. It ends early once
    some direction's ``p`` is at or below ``stop`` (a caller that only asks whether it is).

    Returns
    -------
    U : (N, 6) float
        End directions, unit.
    values : (N,) float
        ``p`` at the end directions (the true support function, also after a smoothed run).
    """
    U = as_shaped(U, "U", ("N", 6))
    if tau is None:  # compiled: the same steps on p itself
        U = kernel_array(U)
        return kernels.descend_many(*slots.packed, U, int(iterations), float(stop))

    if len(slots.G) == slots.m and slots.m <= kernels.PAIRWISE_BLOCK:  # one row per slot:
        # compiled, the same steps as the numpy loop (to the bit)
        return _smoothed_descend(slots, U, int(iterations), float(tau))
    return _smoothed_descend_numpy(slots, U, iterations, tau)


def _smoothed_descend_numpy(slots: WrenchSlots, U: np.ndarray, iterations: int, tau: float):
    """:func:`descend` on :func:`smoothed_support`, in numpy (any set)."""

    def evaluate(V):
        return smoothed_support(slots, V, tau)

    U = np.array(U, dtype=float)
    values, grad = evaluate(U)
    angle = np.full(len(U), 0.3)
    for _ in range(iterations):
        tangent = grad - np.einsum("nr,nr->n", grad, U)[:, None] * U
        norm = np.linalg.norm(tangent, axis=1)
        moving = norm > 1e-12
        step = -tangent / np.where(moving, norm, 1.0)[:, None]
        trial = np.cos(angle)[:, None] * U + np.sin(angle)[:, None] * step
        trial /= np.linalg.norm(trial, axis=1, keepdims=True)
        trial_values, trial_grad = evaluate(trial)
        better = moving & (trial_values < values)
        U[better], values[better], grad[better] = (
            trial[better],
            trial_values[better],
            trial_grad[better],
        )
        angle = np.where(better, np.minimum(angle * 1.5, 0.6), angle * 0.5)
    return U, slots.support(U)


def _smoothed_descend(slots: WrenchSlots, U: np.ndarray, iterations: int, tau: float):
    """:func:`descend` on ``p_tau`` of a set with one row per slot, by the compiled steps of
    :mod:`closure_nlp.kernels.descent` (numpy's tanh between them): the same end points to the
    bit as the numpy loop, in about a tenth of its time."""
    U = np.array(U, dtype=float, order="C")
    N, K = U.shape[0], len(slots.G)
    packed = slots.packed
    P, weights, X = np.zeros((N, K)), np.zeros((N, K)), np.zeros((N, K + 1))
    wrench, top = np.zeros((N, K, 6)), np.zeros(N)
    values, grads = np.empty(N), np.empty((N, 6))
    trial, trial_values, trial_grads = np.zeros((N, 6)), np.zeros(N), np.zeros((N, 6))
    angle, moving = np.full(N, 0.3), np.ones(N, dtype=bool)
    kernels.smoothed_terms(*packed, U, tau, moving, P, wrench, weights, top, X)
    kernels.smoothed_values(P, wrench, weights, top, np.tanh(X), tau, moving, values, grads)
    for _ in range(iterations):
        kernels.smoothed_trials(U, grads, angle, trial, moving)
        kernels.smoothed_terms(*packed, trial, tau, moving, P, wrench, weights, top, X)
        T = np.tanh(X)
        kernels.smoothed_values(P, wrench, weights, top, T, tau, moving, trial_values, trial_grads)
        kernels.smoothed_accept(U, values, grads, angle, trial, moving, trial_values, trial_grads)
    return U, slots.support(U)


def smoothed_descent(slots: WrenchSlots, U: np.ndarray, taus, iterations: int):
    """:func:`descend` on ``p_tau`` for each ``tau`` in turn (relative to the largest f_max)."""
    scale = max(1.0, float(np.max(slots.f_max)))
    values = None
    for tau in taus:
        U, values = descend(slots, U, iterations, tau * scale)
    return U, (slots.support(U) if values is None else values)
