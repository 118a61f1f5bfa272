"""Independent cross-checks of rho by convex optimisation (cvxpy + CLARABEL), no IPOPT involved.

Two facts make rho checkable by convex programs (DESIGN.md):

* **Force closure** is a cone question. The wrench set ``W`` of the slots contains the origin in
  its interior iff the cones spanned by the rows' extreme wrench sets positively span ``R^6``:
  iff the stacked grasp map has rank 6 and some contact forces strictly inside every friction cone
  have zero resultant (Murray, Li and Sastry, Prop. 5.2). The strictness is a margin ``t``
  maximised by a second-order cone program; a slot with several rows (element vertices) spans the
  sum of its rows' cones, so every row is a contact of its own here.
* **The distance** from the origin to ``W`` is ``-min_{|u| <= 1} p(u)`` (min-max duality: ``|w| =
  max_{|v| <= 1} v.w``). The support function ``p`` is a max of convex functions, so this is a
  convex problem: an SOCP through the same epigraph as
  :mod:`closure_nlp.criterion.support_minimum`, but
  over the
  unit *ball*. When the origin is not inside ``W`` the minimum lies on the sphere and equals
  ``-rho``; when it is inside, the minimum is 0 at ``u = 0``, and only :func:`certified_bounds`
  (or IPOPT) can measure how deep.

Both problems are built once per shape (rows, contact types) with cvxpy parameters (DPP), and
re-solved with new numbers, like the CasADi problems of the package.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from closure_nlp.base.errors import MethodError
from closure_nlp.base.solver_cache import PerThread
from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.contact.contact_set import ContactType
from closure_nlp.contact.wrenches import WrenchSlots, as_slots

SOLVER = "CLARABEL"
MARGIN_TOL = 1e-7  # force-closure margin t* (forces normalised to f_n <= 1) counted as positive
RANK_TOL = 1e-9  # singular values below this times the largest one do not count


# --- force closure as a cone program ---------------------------------------------------------


@dataclass(frozen=True)
class ForceClosureCheck:
    """The cvxpy force-closure verdict and its evidence.

    Attributes
    ----------
    force_closure : bool
        ``rank == 6`` and ``margin > MARGIN_TOL``.
    margin : float
        ``t*``: the largest ``t <= 1`` such that forces with ``t <= f_n <= 1`` and at least ``t``
        inside every (scaled) friction cone have zero resultant; 0 when infeasible.
    rank : int
        Rank of the stacked grasp map restricted to each contact's force directions.
    status : str
        The solver status.
    seconds : float
    """

    force_closure: bool
    margin: float
    rank: int
    status: str
    seconds: float

    def __bool__(self) -> bool:
        return self.force_closure


def _row_columns(kind: ContactType, mu: float, mu_s: float):
    """Force components a row can carry and their scales: normalised cone ``||g|| <= f_n``.

    Returns ``(columns, scales, cone)``: the grasp-matrix columns after the normal one, the
    factor that maps a normalised component ``g`` to the force (``f_o = mu g_o`` ...), and the
    cone kind: ``"ray"`` (only ``f_n``), ``"soc"`` (``||g|| <= f_n``) or ``"sfcl"``
    (``||g_ot|| + |g_s| <= f_n``).
    """
    friction = [(1, mu), (2, mu)] if mu > 0 else []
    spin = [(3, mu_s)] if mu_s > 0 else []
    if kind is ContactType.FPC:
        parts = []
    elif kind is ContactType.PCWF:
        parts = friction
    else:
        parts = friction + spin
    cone = "ray" if not parts else "soc"
    if kind is ContactType.SFCL and friction and spin:
        cone = "sfcl"
    return [c for c, _ in parts], [s for _, s in parts], cone


class ForceClosureProblem:
    """``max t`` s.t. zero resultant, ``t <= f_n <= 1``, cones tightened by ``t``: one shape."""

    def __init__(self, layout: tuple):
        self.layout = layout  # per row: (number of friction components, cone kind)
        n = sum(1 + k for k, _ in layout)
        self.G = cp.Parameter((6, n))
        f = cp.Variable(n)
        t = cp.Variable()
        constraints = [self.G @ f == 0, t <= 1]
        col = 0
        for k, cone in layout:
            fn, g = f[col], f[col + 1 : col + 1 + k]
            constraints += [fn <= 1, fn >= t]
            if cone == "soc":
                constraints.append(cp.SOC(fn - t, g))
            elif cone == "sfcl":
                a = cp.Variable()
                constraints += [cp.SOC(a, g[:2]), a + cp.abs(g[2]) <= fn - t]
            col += 1 + k
        self.t = t
        self.problem = cp.Problem(cp.Maximize(t), constraints)

    @staticmethod
    def layout_and_matrix(slots: WrenchSlots):
        """The shape key and the (6, n) scaled, reduced grasp map of every row."""
        layout, blocks = [], []
        for i, start in enumerate(slots.starts):
            kind = slots.types[i]
            mu = float(np.sqrt(slots.pieces[start, 0, 1]))
            mu_s = float(np.sqrt(slots.pieces[start, slots.n_pieces[i] - 1, 3]))
            columns, scales, cone = _row_columns(kind, mu, mu_s)
            for r in range(start, start + slots.rows_per_slot[i]):
                blocks.append(slots.G[r][:, [0, *columns]] * np.array([1.0, *scales]))
                layout.append((len(columns), cone))
        return tuple(layout), np.hstack(blocks)

    def solve(self, G: np.ndarray) -> tuple[float, str]:
        self.G.value = G
        try:
            self.problem.solve(solver=SOLVER)
        except cp.error.SolverError:
            return 0.0, "solver_error"
        status = str(self.problem.status)
        if self.t.value is None or status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            return 0.0, status
        return float(self.t.value), status


# A cvxpy problem holds its parameters' values: one thread's at a time.
_FC_PROBLEMS: PerThread[dict] = PerThread(dict)


def force_closure_check(slots_or_contact_set) -> ForceClosureCheck:
    """Force closure decided by rank and a second-order cone program, independent of IPOPT.

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet
        A slot with several rows (element vertices) spans the sum of its rows' cones.

    Returns
    -------
    ForceClosureCheck
    """
    start_time = time.perf_counter()
    slots = as_slots(slots_or_contact_set)
    layout, G = ForceClosureProblem.layout_and_matrix(slots)
    sv = np.linalg.svd(G, compute_uv=False)
    rank = int(np.sum(sv > RANK_TOL * max(sv[0], 1e-300))) if sv.size else 0
    if rank < 6:
        # Wrenches outside the span of the grasp map cannot be resisted: no cone program needed.
        return ForceClosureCheck(
            False, 0.0, rank, "rank_deficient", time.perf_counter() - start_time
        )
    problems = _FC_PROBLEMS.get()
    if layout not in problems:
        problems[layout] = ForceClosureProblem(layout)
    margin, status = problems[layout].solve(G)
    margin = max(0.0, margin)
    return ForceClosureCheck(
        margin > MARGIN_TOL, margin, rank, status, time.perf_counter() - start_time
    )


def force_closure_cvxpy(slots_or_contact_set) -> bool:
    """``True`` iff the slots (or contacts) are force closure, by :func:`force_closure_check`."""
    return force_closure_check(slots_or_contact_set).force_closure


# --- distance to the wrench set as an SOCP ---------------------------------------------------


@dataclass(frozen=True, eq=False)
class BallMinimum:
    """``min_{|u| <= 1} p(u)`` from the SOCP.

    Attributes
    ----------
    value : float
        ``p`` (numpy, not the solver's epigraph) at the unit ``direction`` when it is negative
        there (beyond ``zero_rho``), else 0: the origin is in the set (or on its boundary).
    direction : (6,) float
        Unit direction of the minimum when the value is negative; the solver's ``u`` (about 0)
        otherwise.
    distance : float
        ``-value``: the distance from the origin to the set.
    status : str
    seconds : float
    """

    value: float
    direction: np.ndarray
    distance: float
    status: str
    seconds: float


class BallMinProblem:
    """The SOCP ``min_{|u| <= 1} p(u)`` for one shape (rows per slot, pieces per slot).

    Epigraph, with ``v_r = f_r ((G_r^T u)_n + s_r)`` the value of row ``r``::

        s_r >= || f_r sqrt(W_rk) * G_r^T u ||    every friction piece k of row r (s_r = 0 for FPC)
        P_i >= v_r                               every row r of slot i
        z_i >= P_i,  z_i >= 0
        t   >= P_i + sum_{j != i} z_j            every slot i
        ||u|| <= 1

    (``s_r`` is scaled by ``f_r`` in the variables so that every parameter multiplies a variable
    once: DPP, compiled once.)
    """

    def __init__(self, n_pieces, rows_per_slot):
        self.n_pieces = tuple(n_pieces)
        self.rows_per_slot = tuple(rows_per_slot)
        m = len(self.rows_per_slot)
        K = sum(self.rows_per_slot)
        row_pieces = np.repeat(self.n_pieces, self.rows_per_slot)
        fric_rows = np.flatnonzero(row_pieces > 0)
        nq = int(row_pieces.sum())
        self.A = cp.Parameter((K, 6))  # f_r * normal column of G_r
        self.B = cp.Parameter((max(nq, 1) * 4, 6))  # f_r sqrt(W_rk) G_r^T, pieces stacked
        u = cp.Variable(6)
        P, z, t = cp.Variable(m), cp.Variable(m), cp.Variable()
        constraints = [cp.SOC(1.0, u)]
        v = self.A @ u
        if len(fric_rows):
            s = cp.Variable(len(fric_rows))
            sel = np.zeros((K, len(fric_rows)))
            sel[fric_rows, np.arange(len(fric_rows))] = 1.0
            v = v + sel @ s
            # piece q belongs to friction row owner[q]
            owner = np.repeat(np.arange(len(fric_rows)), row_pieces[fric_rows])
            expand = np.zeros((nq, len(fric_rows)))
            expand[np.arange(nq), owner] = 1.0
            X = cp.reshape(self.B @ u, (nq, 4), order="C")
            constraints.append(cp.SOC(expand @ s, X, axis=1))
        slot_of_row = np.repeat(np.arange(m), self.rows_per_slot)
        R = np.zeros((K, m))
        R[np.arange(K), slot_of_row] = 1.0
        constraints += [R @ P >= v, z >= P, z >= 0, t >= P + cp.sum(z) - z]
        self.u = u
        self.problem = cp.Problem(cp.Minimize(t), constraints)

    def parameters(self, slots: WrenchSlots):
        """``A`` (K, 6) and ``B`` (4 nq, 6) for the slots' numbers."""
        A = slots.f_max[:, None] * slots.G[:, :, 0]
        blocks = []
        for i, start in enumerate(slots.starts):
            for r in range(start, start + slots.rows_per_slot[i]):
                for k in range(slots.n_pieces[i]):
                    w = np.sqrt(np.maximum(slots.pieces[r, k], 0.0))
                    blocks.append(slots.f_max[r] * w[:, None] * slots.G[r].T)
        B = np.vstack(blocks) if blocks else np.zeros((4, 6))
        return A, B

    def solve(self, slots: WrenchSlots):
        """Returns (optimal value, u, status); ``(nan, None, status)`` on failure."""
        self.A.value, self.B.value = self.parameters(slots)
        try:
            self.problem.solve(solver=SOLVER)
        except cp.error.SolverError:
            return np.nan, None, "solver_error"
        status = str(self.problem.status)
        if self.u.value is None or status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            return np.nan, None, status
        return float(self.problem.value), np.asarray(self.u.value, dtype=float), status


_BALL_PROBLEMS: PerThread[dict] = PerThread(dict)


def ball_minimum(slots_or_contact_set, tolerances: Tolerances = DEFAULT_TOLERANCES) -> BallMinimum:
    """``min_{|u| <= 1} p(u)`` by the SOCP, its direction and the distance it implies.

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet
    tolerances : Tolerances
        ``zero_rho`` decides when a negative optimum counts as 0 (the origin in the set).

    Returns
    -------
    BallMinimum

    Raises
    ------
    MethodError
        When the solver fails.
    """
    start_time = time.perf_counter()
    slots = as_slots(slots_or_contact_set)
    key = (slots.n_pieces, slots.rows_per_slot)
    problems = _BALL_PROBLEMS.get()
    if key not in problems:
        problems[key] = BallMinProblem(*key)
    value, u, status = problems[key].solve(slots)
    if u is None:
        raise MethodError(f"distance SOCP: solver {SOLVER} failed with status {status}")
    norm = float(np.linalg.norm(u))
    direction, value, distance = u, 0.0, 0.0
    if norm > 1e-9:
        # Decide by the support function at the unit direction, never by the solver's value:
        # p(u) < 0 at a unit u proves the origin is outside the set, at least that far.
        unit = u / norm
        at_unit, point = slots.evaluate(unit[None, :])
        scale = max(1.0, float(np.linalg.norm(point[0])))
        if at_unit[0] < -tolerances.zero_rho * scale:
            direction, value, distance = unit, float(at_unit[0]), -float(at_unit[0])
    return BallMinimum(value, direction, distance, status, time.perf_counter() - start_time)


def distance_cvxpy(slots_or_contact_set) -> float:
    """Distance from the origin to the wrench set ``W`` (0 when the origin is in ``W``).

    For sets that are not force closure this is ``rho``; for force-closure sets it is 0 and
    says nothing about ``rho < 0`` (use :func:`closure_nlp.criterion.certificate.certified_bounds`).

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet

    Returns
    -------
    float
    """
    return ball_minimum(slots_or_contact_set).distance


# --- load factor as an SOCP ------------------------------------------------------------------


def load_factor_cvxpy(contact_set_or_slots, load) -> tuple[float, str]:
    """``max k`` such that forces in the exact cones, ``0 <= f_n <= f_max``, balance ``k``
    times ``load`` (6,): the load factor by an SOCP on the forces themselves (no support
    function). A slot of several rows (an element's vertices) is the hull of the origin and its
    rows' sets: row ``r`` carries ``f_n <= theta_r f_max`` with the ``theta`` of a slot summing
    to at most 1 (their perspective). Returns ``(k, status)``; ``(nan, status)`` on failure.
    Forces are normalised by the largest ``f_max`` and the grasp map by its largest entry, so
    the solver's tolerances act relative to the set's scale."""
    slots = as_slots(contact_set_or_slots)
    load = np.asarray(load, dtype=float)
    size = float(np.linalg.norm(load))
    layout, G = ForceClosureProblem.layout_and_matrix(slots)
    g0, f0 = float(np.abs(G).max()), float(slots.f_max.max())
    f = cp.Variable(G.shape[1])
    k = cp.Variable()
    theta = cp.Variable(len(layout), nonneg=True)
    constraints = [(G / g0) @ f == k * (-load / size), k >= 0]
    constraints += [
        cp.sum(theta[start : start + rows]) <= 1
        for start, rows in zip(slots.starts, slots.rows_per_slot)
    ]
    col = 0
    for r, (n_friction, cone) in enumerate(layout):
        fn, g = f[col], f[col + 1 : col + 1 + n_friction]
        constraints += [fn >= 0, fn <= theta[r] * (slots.f_max[r] / f0)]
        if cone == "soc":
            constraints.append(cp.SOC(fn, g))
        elif cone == "sfcl":
            a = cp.Variable()
            constraints += [cp.SOC(a, g[:2]), a + cp.abs(g[2]) <= fn]
        col += 1 + n_friction
    problem = cp.Problem(cp.Maximize(k), constraints)
    try:
        problem.solve(solver=SOLVER)
    except cp.error.SolverError:
        return float("nan"), "solver_error"
    status = str(problem.status)
    if k.value is None or status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        return float("nan"), status
    return float(k.value) * g0 * f0 / size, status


__all__ = [
    "BallMinProblem",
    "BallMinimum",
    "ForceClosureCheck",
    "ForceClosureProblem",
    "as_slots",
    "ball_minimum",
    "distance_cvxpy",
    "force_closure_check",
    "force_closure_cvxpy",
    "load_factor_cvxpy",
]
