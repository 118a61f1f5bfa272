"""The exchange method's restricted problem as a CasADi NLP (IPOPT), and as a linear programme
when every contact is frictionless."""

from __future__ import annotations

import numpy as np

from closure_nlp.base.interrupts import interruptible
from closure_nlp.base.solver_cache import NLPSOL_OPTIONS
from closure_nlp.contact.wrenches import pushing_subsets
from closure_nlp.placement.analytic_centre import analytic_centre
from closure_nlp.placement.max_min_lp import max_min_lp
from closure_nlp.placement.sequential_lp import restricted_model

# Vertex rows above which a contact's position enters the exchange NLP through three variables
# (:class:`ExchangeProblem`): far cheaper solves on facets of many vertices.
AFFINE_ROWS = 4


class ExchangeProblem:
    """``max r`` over weights ``c`` s.t. a smooth lower bound of ``p(u_k; c)`` is ``>= r``.

    For direction ``k`` the bound is ``sum_{i in S_k} f_i (d_n + sqrt(q_ik + eps^2) - eps)`` with
    ``d = G_i(x_i)^T u_k`` at the contact's position ``x_i``, ``S_k`` the contacts with
    ``P_ik > -margin * f_i`` at the current weights (the largest alone if none; a contact about
    to help must be seen) and ``q_ik`` the friction piece that is largest there. Every term is
    at most the true one (a sum over one subset, one piece, ``sqrt(q + eps^2) - eps <=
    sqrt(q)``), so a solution's ``r`` is met by the true support function: each solve is a
    restriction, and re-choosing ``S_k`` and the pieces at the new weights tightens it again.

    ``d`` is linear in the weights (``sum_j c_ij G_ij^T u_k``), and affine in the position. On an
    element with more than :data:`AFFINE_ROWS` vertex rows the position enters through three
    variables ``xi_i`` (offset from the centroid over the size, :class:`ElementFrame`) tied to
    the weights by the linear constraint ``xi_i = Xi_i^T c_i``: the curvature, most of a solve's
    time, then sits in a 3 x 3 block instead of a dense block over all the rows (many times
    faster on facets of many vertices). On smaller elements the extra variables cost more than
    they save (segments and triangles).

    Built once per shape; ``capacity`` directions, unused ones masked out by parameters and
    their rows left free.
    ``components`` (per contact; default all four) are the components of ``d`` its friction
    pieces weigh (PCwF: the two tangential ones). A contact with none (no friction piece: FPC,
    or mu = mu_s = 0) has the linear term ``f_i d_n`` alone: the same value, and no curvature
    at all. The other components are left out of ``q``, the same
    values to the bit with a smaller graph (its Hessian is most of a solve's time).

    ``pairs`` (optional): pairs of contacts kept at least a distance apart, ``|x_i - x_j|^2 >=
    D^2`` with ``x_i = V_i^T c_i`` (the vertices over the part's size, parameters): a
    non-convex constraint IPOPT keeps locally (:class:`~closure_nlp.placement.spacing.Spacing`).
    """

    EPS = 1e-9
    solver = "ipopt"

    def __init__(
        self,
        rows,
        capacity: int,
        tol: float = 1e-10,
        margin: float = 0.0,
        components=(),
        pairs=(),
    ):
        self.margin, self.pairs = margin, tuple(pairs)
        self.rows, self.capacity = tuple(rows), capacity
        self.affine = tuple(k > AFFINE_ROWS for k in self.rows)
        components = tuple(components) or ((0, 1, 2, 3),) * len(self.rows)
        import casadi as ca  # here: only a placement builds this NLP (casadi costs every start)

        m, K = len(self.rows), capacity
        c = [ca.SX.sym(f"c{i}", k) for i, k in enumerate(self.rows)]
        r = ca.SX.sym("r")
        W = [ca.SX.sym(f"W{i}", 4, K) for i in range(m)]  # chosen friction piece per direction
        mask = ca.SX.sym("mask", m, K)  # S_k
        f_max = ca.SX.sym("f_max", m)
        active = ca.SX.sym("active", K)
        total, xis, ties, data = 0, [], [], []
        for i, k in enumerate(self.rows):
            if self.affine[i]:
                xi = ca.SX.sym(f"xi{i}", 3)
                Xi = ca.SX.sym(f"Xi{i}", k, 3)  # the vertices' xi
                A, B = ca.SX.sym(f"A{i}", 4, K), ca.SX.sym(f"B{i}", 12, K)
                d = A + sum(xi[j] * B[4 * j : 4 * j + 4, :] for j in range(3))
                xis.append(xi)
                ties.append(xi - ca.mtimes(Xi.T, c[i]))
                data += [Xi, A, B]
            else:
                D = ca.SX.sym(f"D{i}", 4 * k, K)  # G_ij^T u_k
                d = sum(c[i][j] * D[4 * j : 4 * j + 4, :] for j in range(k))
                data.append(D)
            if not components[i]:  # its pieces are zero: sqrt(0 + eps^2) - eps = 0
                P = f_max[i] * d[0, :]
            else:  # the components its pieces weigh: fewer terms to differentiate
                q = sum(W[i][j, :] * d[j, :] ** 2 for j in components[i])
                P = f_max[i] * (d[0, :] + ca.sqrt(q + self.EPS**2) - self.EPS)
            total = total + mask[i, :] * P
        spaced = sorted({i for pair in self.pairs for i in pair})
        V = {i: ca.SX.sym(f"V{i}", self.rows[i], 3) for i in spaced}
        x_at = {i: ca.mtimes(V[i].T, c[i]) for i in spaced}
        gaps = [ca.sumsqr(x_at[i] - x_at[j]) for i, j in self.pairs]
        data += [V[i] for i in spaced]
        self._spaced = spaced
        g = ca.vertcat(*[ca.sum1(ci) for ci in c], *ties, (total - active.T * r).T, *gaps)
        n_tie, n_gap = 3 * len(xis), len(gaps)
        self._lbg = np.concatenate([np.ones(m), np.zeros(n_tie), np.zeros(K), np.zeros(n_gap)])
        self._ubg = np.concatenate(
            [np.ones(m), np.zeros(n_tie), np.full(K, np.inf), np.full(n_gap, np.inf)]
        )
        x = ca.vertcat(*c, *xis, r)
        p = ca.vertcat(*[ca.vec(a) for a in (*data, *W)], ca.vec(mask), f_max, active)
        self._solver = ca.nlpsol(
            "exchange",
            "ipopt",
            {"x": x, "p": p, "f": -r, "g": g},
            {
                **NLPSOL_OPTIONS,
                "ipopt": {
                    "print_level": 0,
                    "sb": "yes",
                    "tol": tol,
                    "constr_viol_tol": tol,
                    "max_iter": 500,
                },
            },
        )

    def solve(self, frames, slots_at_c, f_max, U, c0, radius, spacing=None):
        """One solve from weights ``c0`` (padded), each weight within ``radius`` of its start;
        ``frames`` holds each contact's :class:`ElementFrame`, ``slots_at_c`` the contacts at
        ``c0``; ``spacing``, with ``pairs``: ``(length, distance)``, the distance kept and the
        part's size the positions are scaled by.

        Returns the new padded weights (list) and ``r``.
        """
        m, K = len(self.rows), self.capacity
        n = len(U)
        P, subsets, chosen = restricted_model(slots_at_c, f_max, U, self.margin)
        mask = np.zeros((m, K))
        mask[:, :n] = subsets

        def padded(a):  # (rows, n) -> (rows, K), flattened column-major as CasADi reads it
            out = np.zeros((len(a), K))
            out[:, :n] = a
            return out.ravel(order="F")

        data, W_parts, xi0 = [], [], []
        for i, frame in enumerate(frames):
            if self.affine[i]:
                A, B = frame.affine(U)
                data += [frame.offsets.ravel(order="F"), padded(A), padded(B)]
                xi0.append(frame.offsets.T @ c0[i])
            else:
                data.append(padded(frame.local(U).reshape(-1, n)))
            W_parts.append(padded(chosen[:, i, :].T))
        if self._spaced:
            length, distance = spacing
            data += [(frames[i].vertices / length).ravel(order="F") for i in self._spaced]
        active = np.zeros(K)
        active[:n] = 1.0
        params = np.concatenate([*data, *W_parts, mask.ravel(order="F"), f_max, active])
        r0 = float(np.min(np.where(mask[:, :n] > 0, P.T, 0.0).sum(axis=0))) - 1e-6
        x0 = np.concatenate([*c0, *xi0, [r0]])
        flat = np.concatenate(c0)
        free = np.full(3 * len(xi0), np.inf)
        lbx = np.concatenate([np.maximum(flat - radius, 0.0), -free, [-np.inf]])
        ubx = np.concatenate([np.minimum(flat + radius, 1.0), free, [np.inf]])
        # The unused directions' rows (0 >= 0) are left free: bounded, their slacks sit at the
        # relaxed bound inside IPOPT's barrier and complementarity measure, which took more
        # iterations to other weights than the NLP of exactly these directions; free, the same.
        lbg = self._lbg.copy()
        n_gap = len(self.pairs)
        lbg[len(lbg) - n_gap - K + n : len(lbg) - n_gap] = -np.inf
        if n_gap:  # a hair above: the NLP keeps it to its constraint tolerance
            lbg[len(lbg) - n_gap :] = (distance / length) ** 2 * (1.0 + 1e-7)
        with interruptible():
            sol = self._solver(x0=x0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=self._ubg)
        x = np.asarray(sol["x"]).ravel()
        weights, at = [], 0
        for k in self.rows:
            weights.append(x[at : at + k])
            at += k
        return weights, float(x[-1])


class ExchangeLP:
    """The restricted problem of :class:`ExchangeProblem` when every contact is frictionless:
    each ``p_i(u_k; c)`` is then ``f_i d_n``, linear in the weights, and the problem is the
    linear programme ``max r`` s.t. ``sum_{i in S_k} f_i d_n(u_k; c_i) >= r``, weights in
    their simplices and the trust region; HiGHS solves it exactly (IPOPT's NLP is the same
    problem: on the pistol's 7 FPC about a tenth of its time per solve). With ``centre``, its
    weights are the analytic centre of the weights within
    :data:`~closure_nlp.placement.analytic_centre.SLAB` of the optimum
    (:func:`~closure_nlp.placement.analytic_centre.analytic_centre`): where the optimum is not
    unique, the
    solver's own point of the optimal face moves with round-off, the centre does not, so the same
    part in any unit takes the same path (:attr:`PlacementOptions.lp_centre`); so do the
    subsets' ties (:func:`~closure_nlp.contact.wrenches.pushing_subsets`).
    """

    solver = "highs"

    def __init__(self, margin: float = 0.0, centre: bool = False):
        self.margin, self.centre = margin, centre

    def solve(self, frames, slots_at_c, f_max, U, c0, radius):
        """As :meth:`ExchangeProblem.solve`: the new padded weights (list) and ``r``."""
        P, _ = slots_at_c.row_terms(U)  # (n, m)
        mask = pushing_subsets(P, f_max, self.margin, self.centre)  # (m, n)
        # A[k, (i, j)] = mask_ik f_i (G_ij^T u_k)_n: row k's value is linear in the weights
        A = np.hstack(
            [
                f_max[i] * mask[i][:, None] * frame.local(U)[:, 0, :].T
                for i, frame in enumerate(frames)
            ]
        )
        owner = np.repeat(np.arange(len(frames)), [len(frame.G) for frame in frames])
        flat = np.concatenate(c0)
        lower, upper = np.maximum(flat - radius, 0.0), np.minimum(flat + radius, 1.0)
        lam, r = max_min_lp(A, owner, lower, upper)
        # the LP solver's point of a non-unique optimum moves with round-off: its centre does not
        centre = analytic_centre(A, owner, lower, upper, r, lam) if self.centre else None
        if centre is not None:
            lam, r = centre, float(np.min(A @ centre))
        weights, at = [], 0
        for c in c0:
            weights.append(lam[at : at + len(c)])
            at += len(c)
        return weights, float(r)
