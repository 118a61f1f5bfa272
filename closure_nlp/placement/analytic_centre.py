"""The analytic centre of a near-optimal face: one point of a linear programme's optimal set that
round-off cannot move far.

Where a linear programme's optimum is not unique, an interior point solver stopped at its
tolerance ends somewhere inside the optimal face, and where it ends depends on round-off: on a
part in metres and the same part in millimetres (grasp matrices equal to 1e-16) the exchange
method's restricted problems ended 1e-5 to 1e-3 apart in the weights, and the method then
followed two paths to two local optima. The analytic centre of the near-optimal set is unique and
moves with the data continuously, so it gives both units the same next weights.
"""

from __future__ import annotations

import numpy as np

# Width of the near-optimal slab below the optimum, relative to the rows' largest entry: far
# above the LP solver's tolerance (1e-10), no more than a gain the exchange method acts on.
# On a box and pybullet's domino (7 FPC, metres and millimetres) 1e-6 and 1e-4 gave the same
# placement in both units to 1e-9 of the part's size, 1e-5 to 3e-5 (a near-tie elsewhere).
SLAB = 1e-6
MAX_NEWTON = 120
FIXED = 1e-13  # a variable whose bounds are this close (relative) is held at its lower bound


def analytic_centre(A, owner, lower, upper, value, start) -> np.ndarray | None:
    """The analytic centre of ``{lam : A lam >= value - SLAB * scale, lower <= lam <= upper,
    sum of lam over each contact's columns = 1}`` (``scale = max |A|``) by Newton's method on
    its log barrier from ``start``, a point of the optimal face.

    Parameters
    ----------
    A : (N, R) float
        Row ``k`` of the restricted problem: its value is ``A[k] @ lam``.
    owner : (R,) int
        Each column's contact.
    lower, upper : (R,) float
        Bounds of ``lam`` (the trust region within the simplices).
    value : float
        The LP's optimum ``max_lam min_k (A lam)_k``.
    start : (R,) float
        A solution of the LP (the solver's answer).

    Returns
    -------
    (R,) float, or None when the slab has no interior point near ``start`` (then the LP's own
    answer stands).
    """
    A = np.asarray(A, float)
    scale = float(np.max(np.abs(A), initial=0.0)) or 1.0
    A = A / scale
    # below the LP's value and the start's own (the solver's answer meets its rows to ~1e-10)
    floor = min(value / scale, float(np.min(A @ start))) - SLAB
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    free = hi - lo > FIXED
    lam = _inside(np.asarray(start, float), owner, lo, hi, free)
    lam[~free] = lo[~free]
    shift = A[:, ~free] @ lam[~free]  # the fixed columns' part of each row
    Af, lof, hif = A[:, free], lo[free], hi[free]
    m = int(owner.max()) + 1
    E = np.zeros((m, int(free.sum())))
    E[owner[free], np.arange(int(free.sum()))] = 1.0
    x = lam[free]
    total = np.ones(m) - np.bincount(owner[~free], weights=lam[~free], minlength=m)

    def slacks(x):
        return Af @ x + shift - floor, x - lof, hif - x

    def barrier(x):
        s = np.concatenate(slacks(x))
        return -np.sum(np.log(s)) if np.all(s > 0) else np.inf

    if not np.isfinite(barrier(x)):
        return None
    n, t_last = len(x), 0.0
    for _ in range(MAX_NEWTON):
        sa, sl, sh = slacks(x)
        grad = -Af.T @ (1.0 / sa) - 1.0 / sl + 1.0 / sh
        hess = (Af.T * (1.0 / sa**2)) @ Af + np.diag(1.0 / sl**2 + 1.0 / sh**2)
        # Jacobi scaling: the slab makes some directions 1/SLAB^2 stiffer than others
        d = 1.0 / np.sqrt(np.diag(hess))
        kkt = np.block([[hess * d[:, None] * d[None, :], (E * d).T], [E * d, np.zeros((m, m))]])
        rhs = np.concatenate([-grad * d, total - E @ x])
        try:
            step = d * np.linalg.solve(kkt, rhs)[:n]
        except np.linalg.LinAlgError:
            break
        decrement = float(-grad @ step)
        if decrement < 1e-24 and t_last == 1.0:
            break
        # the largest step that keeps every slack positive, then backtracking on the barrier
        rates = np.concatenate([-(Af @ step) / sa, -step / sl, step / sh])
        t = min(1.0, 0.99 / rates.max()) if rates.max() > 0 else 1.0
        here = barrier(x)
        while barrier(x + t * step) > here - 0.25 * t * decrement and t > 1e-12:
            t *= 0.5
        if t <= 1e-12:
            break
        x, t_last = x + t * step, t
    lam[free] = x
    return lam


def _inside(start, owner, lo, hi, free) -> np.ndarray:
    """``start`` moved a little toward a point strictly inside the bounds and the simplices
    (an LP solver's answer may sit on a bound): far less than the slab's width in any row."""
    m = int(owner.max()) + 1
    low = np.bincount(owner, weights=lo, minlength=m)
    room = np.bincount(owner, weights=hi - lo, minlength=m)
    alpha = np.clip((1.0 - low) / np.where(room > 0, room, 1.0), 0.0, 1.0)
    inner = np.where(free, lo + alpha[owner] * (hi - lo), lo)
    theta = 0.25 * SLAB / (1.0 + float(np.abs(inner - start).sum()))
    return (1.0 - theta) * start + theta * inner


__all__ = ["SLAB", "analytic_centre"]
