"""An independent reference for rho, written from the paper's formulas and nothing of the package.

Support function: eqs 29-32 per contact and the literal max over all 2^m - 1 subsets (eq 26).
Minimum over the sphere: dense sampling, then SLSQP on the smooth epigraph with one constraint
per subset from the best distinct samples. Slow and simple on purpose.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.optimize import minimize


def frame(n):
    n = np.asarray(n, float) / np.linalg.norm(n)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    o = a - (a @ n) * n
    o /= np.linalg.norm(o)
    return n, o, np.cross(n, o)


def grasp(r, n, torque_scale=1.0):
    """Eq 6 with torque rows scaled."""
    n, o, t = frame(n)
    top = np.column_stack([n, o, t, np.zeros(3)])
    bottom = torque_scale * np.column_stack([np.cross(r, n), np.cross(r, o), np.cross(r, t), n])
    return np.vstack([top, bottom])


def contact_support(d, kind, mu, mu_s, f):
    dn, do, dt, ds = d
    tangential = np.hypot(do, dt)
    return {
        "fpc": f * dn,
        "pcwf": f * dn + mu * f * tangential,
        "sfcl": f * dn + f * max(mu * tangential, mu_s * abs(ds)),
        "sfce": f * dn + f * np.sqrt(mu**2 * tangential**2 + mu_s**2 * ds**2),
    }[kind]


def subset_matrix(m):
    """(2^m - 1, m) 0/1 rows: every non-empty subset of the m contacts (eq 26, literally)."""
    rows = [
        [1.0 if i in subset else 0.0 for i in range(m)]
        for size in range(1, m + 1)
        for subset in itertools.combinations(range(m), size)
    ]
    return np.array(rows)


def _rows(G):
    """A slot's grasp matrices: one (6, 4) for a contact, (k, 6, 4) for an element's vertices."""
    G = np.asarray(G, float)
    return G[None] if G.ndim == 2 else G


def slot_support(u, slot):
    """Eq 36: the largest support value over the slot's rows (one row for a contact)."""
    G, kind, mu, mu_s, f = slot
    return max(contact_support(Gj.T @ u, kind, mu, mu_s, f) for Gj in _rows(G))


def support(u, contacts):
    """``contacts``: list of (G (6, 4) or (k, 6, 4), kind, mu, mu_s, f_max), one per slot."""
    values = np.array([slot_support(u, c) for c in contacts])
    return float(np.max(subset_matrix(len(contacts)) @ values))


def _cone_gap(kind, mu, mu_s, d, s):
    """``s**2`` minus the squared friction terms: the epigraph constraints of one row."""
    t2 = d[1] ** 2 + d[2] ** 2
    if kind == "pcwf":
        return [s**2 - mu**2 * t2]
    if kind == "sfcl":
        return [s**2 - mu**2 * t2, s**2 - mu_s**2 * d[3] ** 2]
    if kind == "sfce":
        return [s**2 - mu**2 * t2 - mu_s**2 * d[3] ** 2]
    return []


def reference_min(contacts, samples=3000, starts=12, seed=0):
    """min over the unit sphere of ``support``; returns (value, u).

    SLSQP on the epigraph: u, one s per row, one P per slot, t; s_r**2 >= friction terms,
    P_i >= f (d_n + s_r) for every row r of slot i, t >= sum of P over every subset.
    """
    rng = np.random.default_rng(seed)
    U = rng.standard_normal((samples, 6))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    U = np.vstack([np.eye(6), -np.eye(6), U])
    vals = np.array([support(u, contacts) for u in U])
    m = len(contacts)
    rows = [(i, Gj) for i, c in enumerate(contacts) for Gj in _rows(c[0])]
    n_rows = len(rows)
    subsets = subset_matrix(m)

    def unpack(x):
        return x[:6], x[6 : 6 + n_rows], x[6 + n_rows : 6 + n_rows + m], x[-1]

    def inequalities(x):
        u, s, P, t = unpack(x)
        out = []
        for r, (i, Gj) in enumerate(rows):
            _, kind, mu, mu_s, f = contacts[i]
            d = Gj.T @ u
            out += _cone_gap(kind, mu, mu_s, d, s[r])
            out.append(P[i] - f * (d[0] + (s[r] if kind != "fpc" else 0.0)))
        out += list(t - subsets @ P)
        return np.array(out)

    cons = [
        {"type": "eq", "fun": lambda x: unpack(x)[0] @ unpack(x)[0] - 1.0},
        {"type": "ineq", "fun": inequalities},
    ]
    bounds = [(-2, 2)] * 6 + [(0, None)] * n_rows + [(None, None)] * (m + 1)
    best = (np.inf, None)
    picked = []
    for idx in np.argsort(vals):
        if any(np.linalg.norm(U[idx] - U[j]) < 0.3 for j in picked):
            continue
        picked.append(idx)
        u0 = U[idx]
        s0, P0 = [], np.full(m, -np.inf)
        for i, Gj in rows:
            _, kind, mu, mu_s, f = contacts[i]
            d = Gj.T @ u0
            s0.append(np.sqrt(mu**2 * (d[1] ** 2 + d[2] ** 2) + mu_s**2 * d[3] ** 2) + 1e-6)
            P0[i] = max(P0[i], f * (d[0] + (s0[-1] if kind != "fpc" else 0.0)) + 1e-6)
        x0 = np.concatenate([u0, s0, P0, [np.max(subsets @ P0) + 1e-3]])
        res = minimize(
            lambda x: x[-1],
            x0,
            method="SLSQP",
            bounds=bounds,
            constraints=cons,
            options={"ftol": 1e-14, "maxiter": 400},
        )
        u = res.x[:6] / np.linalg.norm(res.x[:6])
        value = support(u, contacts)
        if value < best[0]:
            best = (value, u)
        if len(picked) == starts:
            break
    return best


def from_elements(vertex_lists, normals, kinds, torque_scale=1.0):
    """Independent view of element slots: raw vertices and normals, one slot per contact."""
    return [
        (np.array([grasp(v, n, torque_scale) for v in V]), kind, mu, mu_s, f)
        for V, n, (kind, mu, mu_s, f) in zip(vertex_lists, normals, kinds)
    ]


def from_contact_set(cs):
    """Independent view of a ContactSet: only its raw numbers are read."""
    return [
        (grasp(c.position, c.inward_normal, cs.torque_scale), c.type.value, c.mu, c.mu_s, c.f_max)
        for c in cs.contacts
    ]


def zonotope_capacity(V):
    """``max(0, min over five-subsets S of full rank of min(s(n_S), s(-n_S)) / |n_S|)`` of one
    set of frictionless wrenches ``V`` (m, 6), subset by subset with LAPACK determinants:
    ``<w_j, n_S> = det[w_S; w_j]``, ``|n_S|^2 = det(w_S w_S^T)``; a subset whose volume is at
    most 1e-8 of the product of its generators' lengths is skipped."""
    m = len(V)
    best = np.inf
    for S in itertools.combinations(range(m), 5):
        base = V[list(S)]
        norm2 = np.linalg.det(base @ base.T)
        if not norm2 > 1e-16 * np.prod(np.sum(base * base, axis=1)):
            continue
        x = np.array([np.linalg.det(np.vstack([base, V[j]])) for j in range(m) if j not in S])
        best = min(best, min(x[x > 0].sum(), -x[x < 0].sum()) / np.sqrt(norm2))
    return best if np.isfinite(best) else 0.0
