"""The exchange method's restricted problem by sequential linear programming.

The restricted problem is ``max_c min_k p(u_k; c)`` over a working set of directions ``u_k``,
the weights ``c_i`` of each contact in its simplex and within a trust region. On a facet or a
segment the grasp matrix is affine in the position, ``G_i(c_i) = sum_j c_ij G_ij``, and
``p(u; c) = max_{w in W_c} u . w`` is a maximum of functions linear in ``c`` (a fixed force of
each contact of a fixed subset), so each ``p(u_k; .)`` is convex in the weights. With ``F_ik``
the support force of contact ``i`` in direction ``u_k`` at the current weights ``c0`` (zero for
the contacts outside the support point's subset),

    p(u_k; c) >= L_k(c) = sum_i sum_j c_ij (G_ij^T u_k) . F_ik    for every c,

with equality at ``c0``: the linearisation is a global under-estimator. The linear programme
``max_c min_k L_k(c)`` (HiGHS, :func:`~closure_nlp.placement.max_min_lp.max_min_lp`) therefore has
``c0`` feasible at the true value, and its optimum ``c1`` has a true value at least the LP's:
each step is monotone (the convex-concave procedure). Re-linearising at ``c1`` and repeating
ends at a point no linearisation can improve. A local maximum of a minimum of convex functions
sits where enough of them (or the simplex and trust-region bounds) are active, as in a linear
programme, so the steps are few (median 4, at most 11, on the lamp's 125 restricted problems).

Against IPOPT on the smooth restriction of
:class:`~closure_nlp.placement.restricted.ExchangeProblem`: the true support function is
modelled (every subset and friction piece re-chosen at each step, no smoothing), nothing is
built per problem size, and a step is one small LP.
"""

from __future__ import annotations

import numpy as np

from closure_nlp.contact.wrenches import WrenchSlots, pushing_subsets
from closure_nlp.placement.max_min_lp import OPTIMAL, Highs, max_min_lp, max_min_model

# A step that raises the restricted value by at most this much of the data's scale (the largest
# support term per unit weight) ends the steps; a step's LP is solved to 1e-10 of that scale.
STEP_GAIN = 1e-9
MAX_STEPS = 30


def _contact_linearisation(D, c, f, W):
    """One contact's term ``f (d_n + sqrt(q))``, ``d = G(c)^T u_k``, ``q = W_k . d**2`` with the
    friction piece ``W_k`` of each direction given, and its gradient in the weights.

    Parameters
    ----------
    D : (rows, 4, n) float
        ``G_j^T u_k`` of the contact's vertex rows.
    c : (rows,) float
        Its weights.
    f : float
        Its force bound.
    W : (4, n) float
        The friction piece of each direction (zero: no friction term).

    Returns
    -------
    value : (n,) float
    coefficients : (n, rows) float
        ``coefficients @ c == value``: the term is positively homogeneous of degree one and
        convex in the weights, so ``coefficients @ x`` is at most its value at any ``x``.
    """
    value, coefficients = _linearisations(D[None], c[None], np.array([f]), W[None])
    return value[0], coefficients[0]


def _linearisations(D, c, f, W):
    """:func:`_contact_linearisation` of ``g`` contacts with the same rows at once (the same
    operations element by element, so the same values to the bit): ``D`` (g, rows, 4, n), ``c``
    (g, rows), ``f`` (g,), ``W`` (g, 4, n); returns values (g, n) and coefficients (g, n, rows).
    """
    d = np.einsum("ij,ijck->ick", c, D)  # (g, 4, n)
    root = np.sqrt(np.maximum(np.sum(W * d**2, axis=1), 0.0))
    # the rim's point f (e_n + W d / sqrt(q)); none where q = 0 (any force of the disc)
    inv = np.divide(f[:, None], root, out=np.zeros_like(root), where=root > 0.0)
    force = W * d * inv[:, None, :]
    force[:, 0] += f[:, None]
    return f[:, None] * (d[:, 0] + root), np.einsum("ijck,ick->ikj", D, force)


def linearised_support(local, c, slots: WrenchSlots):
    """The true ``p(u_k; c)`` of the working set and its linearisation in the weights.

    Parameters
    ----------
    local : list of (rows_i, 4, n) float
        ``G_ij^T u_k`` of each contact's vertex rows (:meth:`ElementFrame.local`).
    c : list of (rows_i,) float
        Each contact's weights (summing to one).
    slots : WrenchSlots
        One slot per contact: their friction pieces and force bounds (the grasp matrices are
        not used).

    Returns
    -------
    values : (n,) float
        ``p(u_k; c)`` (eq 26: the sum of the positive contact values, else the largest).
    A : (n, sum rows_i) float
        ``A[k, (i, j)] = (G_ij^T u_k) . F_ik``: ``A @ concat(c) == values``, and ``A @ x <=
        p(u_k; x)`` for all weights ``x``.
    """
    n = local[0].shape[2]
    terms, coefficients = [], []
    for i, (D, ci) in enumerate(zip(local, c)):
        d = np.einsum("j,jck->ck", ci, D)
        W = slots.pieces[slots.starts[i], : slots.n_pieces[i]]  # (pieces, 4)
        chosen = np.zeros((4, n))
        if len(W):
            chosen = W[np.argmax(W @ d**2, axis=0)].T  # the first of equal pieces
        value, coefficient = _contact_linearisation(D, ci, slots.f_max[slots.starts[i]], chosen)
        terms.append(value)
        coefficients.append(coefficient)
    P = np.array(terms)  # (m, n)
    chosen = pushing_subsets(P.T, slots.f_max[slots.starts]).astype(bool)  # (m, n)
    values = np.where(chosen, P, 0.0).sum(axis=0)
    A = np.hstack([chosen[i][:, None] * coefficients[i] for i in range(len(local))])
    return values, A


def restricted_model(slots_at_c: WrenchSlots, f_max, U, margin: float):
    """The exchange method's restricted model of ``p(u_k; .)`` chosen at the weights of
    ``slots_at_c`` (:class:`~closure_nlp.placement.restricted.ExchangeProblem`): each direction's
    subset of
    contacts with ``P_ik > -margin f_i`` (the largest alone if none) and each contact's largest
    friction piece there.

    Returns
    -------
    P : (n, m) float
        The contacts' support values at those weights.
    mask : (m, n) float
        1 where contact ``i`` counts in direction ``k``.
    pieces : (n, m, 4) float
        The friction piece of contact ``i`` in direction ``k`` (zero without friction).
    """
    P, piece = slots_at_c.row_terms(U)  # (n, m) each
    m = P.shape[1]
    mask = pushing_subsets(P, f_max, margin)
    return P, mask, slots_at_c.pieces[np.arange(m)[None, :], piece]


def model_linearisation(local, c, mask, pieces, f_max):
    """The restricted model's ``sum_{i in S_k} f_i (d_n + sqrt(q_ik))`` at weights ``c`` and its
    linearisation, as :func:`linearised_support` for the true support function.

    Parameters
    ----------
    local : list of (rows_i, 4, n) float
    c : list of (rows_i,) float
    mask, pieces : as :func:`restricted_model` returns them.
    f_max : (m,) float

    Returns
    -------
    values : (n,) float
    A : (n, sum rows_i) float
        ``A @ concat(c) == values`` and ``A @ x`` at most the model's value at any ``x``.
    """
    return ModelTerms(local, mask, pieces, f_max)(c)


class ModelTerms:
    """:func:`model_linearisation` for one restricted model, its data stacked once: the contacts
    with the same rows are linearised together (:func:`_linearisations`), a few numpy calls for
    all of them instead of a dozen per contact (the sequential LP's steps call it hundreds of
    times a placement)."""

    def __init__(self, local, mask, pieces, f_max):
        self.mask, self.rows = mask, [len(D) for D in local]
        self.groups = []
        for rows in dict.fromkeys(self.rows):
            ids = [i for i, k in enumerate(self.rows) if k == rows]
            W = np.transpose(pieces[:, ids, :], (1, 2, 0))  # (g, 4, n)
            self.groups.append((ids, np.stack([local[i] for i in ids]), f_max[ids], W))

    def __call__(self, c):
        """Values (n,) and linearisation (n, sum rows_i) at weights ``c`` (list)."""
        terms = [None] * len(self.rows)
        for ids, D, f, W in self.groups:
            values, coefficients = _linearisations(D, np.array([c[i] for i in ids]), f, W)
            for at, i in enumerate(ids):
                terms[i] = values[at], coefficients[at]
        values, columns = 0.0, []
        for i, (value, coefficient) in enumerate(terms):
            values = values + self.mask[i] * value
            columns.append(self.mask[i][:, None] * coefficient)
        return values, np.hstack(columns)


class ExchangeSLP:
    """The restricted problem of the exchange method by sequential linear programming
    (module docstring): from the weights ``c0``, steps of ``max_c min_k L_k(c)`` over the
    simplices and the trust region, each from the linearisation at the last step's weights,
    while one raises the true restricted value. Every contact type; nothing to build.

    Each step's LP is solved by HiGHS's simplex method, from scratch: half the time of its
    interior point method (:func:`~closure_nlp.placement.max_min_lp.max_min_lp`), and a step's
    answer depends on its LP alone. (From the last step's basis a step took one pivot instead
    of 30, but whole plans were no faster, and a run's path depended on the solves before it.)
    One object per thread: it keeps its HiGHS solver.

    ``steps`` after each :meth:`solve`: the LPs it solved.
    """

    solver = "slp"

    def __init__(self, max_steps: int = MAX_STEPS):
        self.max_steps = max_steps
        self.steps = 0
        self._highs = None

    def solve(self, frames, slots_at_c, f_max, U, c0, radius):
        """As :meth:`ExchangeProblem.solve`: the new padded weights (list) and the restricted
        value ``min_k p(u_k; c)`` there (exact, not a model's)."""
        local = [frame.local(U) for frame in frames]
        return self._ascend(lambda c: linearised_support(local, c, slots_at_c), c0, radius)

    def _ascend(self, linearise, c0, radius, centre: bool = False):
        """Steps of the linear programme from ``c0`` within ``radius``: ``linearise(c)`` gives
        the values at ``c`` and their linearisation. ``centre``: once a step gains nothing, one
        more step by the interior point method
        (:func:`~closure_nlp.placement.max_min_lp.max_min_lp`),
        taken unless it loses, so that a non-unique optimum ends inside its optimal face (where
        IPOPT ends) rather than at a vertex; it goes on by that method while it gains.

        Returns the weights (list) and ``min_k`` of the values there."""
        sizes = [len(ci) for ci in c0]
        owner = np.repeat(np.arange(len(c0)), sizes)
        flat = np.concatenate(c0)
        lower, upper = np.maximum(flat - radius, 0.0), np.minimum(flat + radius, 1.0)
        c = [np.asarray(ci, float) for ci in c0]
        values, A = linearise(c)
        value = float(values.min())
        scale = max(float(np.max(np.abs(A), initial=0.0)), np.finfo(float).tiny)
        interior = False
        self.steps = 0
        while self.steps < self.max_steps:
            self.steps += 1
            if interior:
                lam = max_min_lp(A, owner, lower, upper)[0]
            else:
                lam = self._step(A / scale, owner, lower, upper)
            # within the solver's tolerance of the bounds and the simplices
            lam = np.clip(lam, lower, upper)
            trial = [w / w.sum() for w in np.split(lam, np.cumsum(sizes)[:-1])]
            trial_values, trial_A = linearise(trial)
            gain = float(trial_values.min()) - value
            if gain > 0.0 or (interior and gain > -STEP_GAIN * scale):
                c, value, A = trial, float(trial_values.min()), trial_A
            if gain <= STEP_GAIN * scale:
                if interior or not centre:
                    break
                interior = True
        return c, value

    def _step(self, A, owner, lower, upper) -> np.ndarray:
        """``lam`` (R,) maximising ``min_k (A lam)_k`` over the simplices and bounds."""
        if Highs is None:  # pragma: no cover - scipy's linprog instead
            return max_min_lp(A, owner, lower, upper)[0]
        if self._highs is None:
            self._highs = Highs()
            self._highs.setOptionValue("output_flag", False)
            self._highs.setOptionValue("presolve", "off")  # small dense LPs
            self._highs.setOptionValue("solver", "simplex")
        highs = self._highs
        highs.passModel(max_min_model(A, owner, len(np.unique(owner)), lower, upper))
        highs.run()
        if highs.getModelStatus() != OPTIMAL:  # a numerical failure: the interior point
            return max_min_lp(A, owner, lower, upper)[0]
        return np.asarray(highs.getSolution().col_value, float)[: A.shape[1]]


class ModelSLP(ExchangeSLP):
    """The restricted problem of :class:`~closure_nlp.placement.restricted.ExchangeProblem` itself
    (IPOPT's
    model: each direction's subset of contacts and each contact's friction piece fixed at the
    start weights, :func:`restricted_model`) by sequential linear programming. Each term is
    convex in the weights (a norm of a linear function plus a linear one), so every step is
    monotone as for :class:`ExchangeSLP`; the steps end inside the optimal face
    (:meth:`ExchangeSLP._ascend` with ``centre``), as IPOPT's interior point does, so that it
    mostly ends at IPOPT's weights, in a fraction of IPOPT's time (docs/placement.md).
    The value returned is the model's, a lower bound of the true ``min_k p(u_k; c)``, as
    IPOPT's ``r`` is."""

    solver = "slp-model"

    def __init__(self, margin: float = 0.0, max_steps: int = MAX_STEPS):
        super().__init__(max_steps)
        self.margin = margin

    def solve(self, frames, slots_at_c, f_max, U, c0, radius):
        """As :meth:`ExchangeProblem.solve`: the new padded weights (list) and the model's
        ``min_k`` there."""
        local = [frame.local(U) for frame in frames]
        _, mask, pieces = restricted_model(slots_at_c, f_max, U, self.margin)
        return self._ascend(ModelTerms(local, mask, pieces, f_max), c0, radius, centre=True)


__all__ = [
    "ExchangeSLP",
    "ModelSLP",
    "linearised_support",
    "model_linearisation",
    "restricted_model",
]
