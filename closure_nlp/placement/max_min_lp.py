"""The max-min LP of a placement: ``max_lam min_k (A lam)_k`` over one simplex of weights per
contact, by HiGHS (one solver per thread) or scipy's ``linprog`` where HiGHS's module is
missing; and its weak dual bound. Shared by the exchange method's LP steps and the ceiling."""

from __future__ import annotations

import functools
import threading

import numpy as np

try:
    from highspy import HighsLp as _HighsLp
    from highspy import HighsModelStatus as _ModelStatus
    from highspy import MatrixFormat as _MatrixFormat

    # The plain solver class: highspy.Highs, its subclass, prints a banner on stdout when it
    # is made (before any option can silence it), which would break ``--json`` output.
    from highspy import _Highs as Highs
    from highspy import kHighsInf as INF

    _ROWWISE, OPTIMAL = _MatrixFormat.kRowwise, _ModelStatus.kOptimal
except ImportError:  # pragma: no cover - scipy's linprog instead
    Highs = None

# Relative margin added to every dual bound: the round-off of the support values a_ir (a few
# ulps each, summed over at most a few hundred rows) is far below it.
ROUND_OFF = 1e-9


def max_min_lp(A: np.ndarray, owner: np.ndarray, lower=None, upper=None):
    """``max_lam min_k (A lam)_k`` over one simplex per contact (``owner`` (R,): each column's
    contact), ``lam`` also within ``lower`` and ``upper`` (R,) when given: ``lam`` (R,) and the
    optimum. Solved on ``A`` over its largest magnitude (HiGHS's absolute tolerances then mean
    the same at any wrench scale). Raises RuntimeError when every LP solver fails.

    Solved by HiGHS's interior point method without crossover, to 1e-10: where the optimum is
    not unique it ends inside the optimal face, as IPOPT does on the same problem, rather than
    at a vertex (the exchange method's next trust region is centred there)."""
    unit = float(np.max(np.abs(A), initial=0.0))
    unit = unit if unit > 0.0 else 1.0
    m = int(owner.max()) + 1
    if Highs is None:
        x, _, value = linprog_solve(A / unit, owner, m, lower, upper)
    else:
        x, _, value = highs_solve(A / unit, owner, m, lower, upper, interior=True)
    return x[: A.shape[1]], value * unit


_SOLVERS = threading.local()


def max_min_model(A: np.ndarray, owner: np.ndarray, m: int, lower=None, upper=None):
    """HiGHS's model of the LP of :func:`max_min_lp`: columns ``lam`` (R,) then ``t``; rows the
    N directions (``t - A lam <= 0``) then one simplex per contact."""
    N, R = A.shape
    structure = _structure(N, R, m, np.asarray(owner, dtype=np.int64).tobytes())
    lp = _HighsLp()
    lp.num_col_, lp.num_row_ = R + 1, N + m
    lp.col_cost_, lp.row_lower_, lp.row_upper_ = structure[:3]
    lp.col_lower_ = np.r_[np.zeros(R) if lower is None else lower, -INF].tolist()
    lp.col_upper_ = np.r_[np.full(R, INF) if upper is None else upper, INF].tolist()
    lp.a_matrix_.format_ = _ROWWISE
    lp.a_matrix_.start_, lp.a_matrix_.index_ = structure[3:]
    values = np.ones(N * (R + 1) + R)
    values[: N * (R + 1)].reshape(N, R + 1)[:, :R] = -A
    lp.a_matrix_.value_ = values.tolist()  # a list: its conversion costs a third of an array's
    return lp


@functools.lru_cache(maxsize=64)
def _structure(N: int, R: int, m: int, owner: bytes) -> tuple:
    """The parts of :func:`max_min_model`'s LP that depend on its shape alone, as lists (the
    sequential LP passes thousands of models of a few shapes)."""
    owner = np.frombuffer(owner, dtype=np.int64)
    counts = np.bincount(owner, minlength=m)
    return (
        np.r_[np.zeros(R), -1.0].tolist(),
        np.r_[np.full(N, -INF), np.ones(m)].tolist(),
        np.r_[np.zeros(N), np.ones(m)].tolist(),
        np.r_[np.arange(N + 1) * (R + 1), N * (R + 1) + np.cumsum(counts)].tolist(),
        np.r_[np.tile(np.arange(R + 1), N), np.argsort(owner, kind="stable")].tolist(),
    )


def thread_solver(name: str, interior: bool = False):
    """This thread's HiGHS solver ``name``, made at its first use: quiet, no presolve; by the
    interior point method without crossover when ``interior``."""
    solver = getattr(_SOLVERS, name, None)
    if solver is None:
        solver = Highs()
        solver.setOptionValue("output_flag", False)
        solver.setOptionValue("presolve", "off")  # small dense LPs: presolve costs, finds nothing
        if interior:
            solver.setOptionValue("solver", "ipm")
            solver.setOptionValue("run_crossover", "off")
            solver.setOptionValue("ipm_optimality_tolerance", 1e-10)
        setattr(_SOLVERS, name, solver)
    return solver


def highs_solve(A: np.ndarray, owner: np.ndarray, m: int, lower=None, upper=None, interior=False):
    """The LP ``min -t`` s.t. ``t - A lam <= 0``, ``sum_{r of i} lam_r = 1``, ``lam >= 0`` by
    HiGHS itself, one solver per thread (scipy's ``linprog`` around the same solver checks its
    options on every call, which costs more than the solve of a cell's LP):
    (primal x (R + 1,), duals of the N inequality rows, optimal t). ``lower`` and ``upper``
    (R,), optional, bound ``lam`` further (the exchange method's trust region); ``interior``:
    by the interior point method, without crossover (:func:`max_min_lp`)."""
    solver = thread_solver("interior" if interior else "highs", interior)
    N = len(A)
    solver.passModel(max_min_model(A, owner, m, lower, upper))
    solver.run()
    if solver.getModelStatus() != OPTIMAL:
        # always feasible and bounded: a numerical failure of this solve, so the same LP once
        # more from scratch, and scipy's wrapper of HiGHS (its own settings) after that
        solver.clearSolver()
        solver.run()
        if solver.getModelStatus() != OPTIMAL:
            return linprog_solve(A, owner, m, lower, upper)
    solution = solver.getSolution()
    duals = np.asarray(solution.row_dual, float)[:N]
    return np.asarray(solution.col_value, float), duals, -solver.getInfo().objective_function_value


def linprog_solve(A: np.ndarray, owner: np.ndarray, m: int, lower=None, upper=None):
    """The same LP by scipy's ``linprog`` (where HiGHS's own Python module is missing)."""
    from scipy.optimize import linprog  # here: scipy.optimize costs 0.2 s of every start

    N, R = A.shape
    cost = np.zeros(R + 1)
    cost[-1] = -1.0
    A_eq = np.zeros((m, R + 1))
    A_eq[owner, np.arange(R)] = 1.0
    res = linprog(
        cost,
        A_ub=np.hstack([-A, np.ones((N, 1))]),
        b_ub=np.zeros(N),
        A_eq=A_eq,
        b_eq=np.ones(m),
        bounds=[
            *zip(np.zeros(R) if lower is None else lower, [None] * R if upper is None else upper),
            (None, None),
        ],
        method="highs",
    )
    if res.status != 0:
        raise RuntimeError(f"capacity bound: the LP solver failed ({res.message})")
    return res.x, np.asarray(res.ineqlin.marginals, float), float(-res.fun)


def dual_bound(A: np.ndarray, owner: np.ndarray, y: np.ndarray) -> float:
    """``D(y) = sum_i max_{r of i} (y^T A)_r`` plus the round-off margin: for ``y >= 0`` summing
    to one, no ``lam`` does better than this on the directions of ``A`` (weak duality)."""
    scores = y @ A
    m = int(owner.max()) + 1
    best = np.full(m, -np.inf)
    np.maximum.at(best, owner, scores)
    value = float(best.sum())
    return value + ROUND_OFF * max(value, float(A.max(initial=0.0)))
