"""The quality criteria: rho(0, W_c^M) of contacts and rho(0, What_c^M) of elements (eqs 24, 33).

``rho = -min_{|u| = 1} p(u)`` with ``p`` the support function of
:mod:`closure_nlp.contact.wrenches`.
The minimum is a CasADi NLP solved by IPOPT, smooth through an epigraph:

    min t  over u, s, P, z, t   subject to
        u.u = 1
        s_r >= 0,  s_r**2 >= q_k(G_r^T u)          friction term of row r, every piece k
        P_i >= f_r * ((G_r^T u)_n + s_r)           every row r of slot i (max over vertices)
        z_i >= P_i,  z_i >= 0                      z_i = max(P_i, 0) at the optimum
        t >= P_i + sum_z - z_i,  sum_z = sum_j z_j  every slot i (O(m) nonzeros)

The last line is the max over non-empty subsets in O(m) constraints, including the branch where
every ``P_i`` is negative (the contacts are then not force closure and ``rho > 0`` is the distance
that the selection algorithms steer by). The NLP is built once per shape (slot types and rows per
slot) with the grasp matrices and contact data as parameters, and re-called. The reported value is
the support function at the returned unit direction, never the epigraph variable.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from closure_nlp.base.cores import checked_workers
from closure_nlp.base.interrupts import interruptible
from closure_nlp.base.solver_cache import NLPSOL_OPTIONS, PerThread, cached
from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.base.validation import as_flag, as_unit_vector, is_whole
from closure_nlp.contact.contact_set import ContactSet
from closure_nlp.contact.wrenches import WrenchSlots, as_slots, padded_rows, piece_square
from closure_nlp.criterion.sphere_search import descend, smoothed_descent, sphere_samples
from closure_nlp.kernels import descent as descent_kernels
from closure_nlp.kernels import kernel_array


@dataclass(frozen=True)
class SearchOptions:
    """How the global minimum over the sphere is sought.

    Attributes
    ----------
    samples : int
        Pseudo-random directions (besides ``+-e_k``) that the batched descents start from.
    descent_iterations : int
        Steps of the batched descent on ``p`` itself.
    smoothing : tuple of float
        Temperatures (relative to the largest ``f_max``) of a second batched descent, on
        log-sum-exp smoothings of ``p``, one after the other; ``()`` skips it. Its end points
        join the pool of the local solver's starts. Contact sets only (one row per slot), unless
        ``element_smoothing``: without it, the placement's starts on the pistol's 7 PCwF
        (fixture study, seeds 0-7) ended worse on one seed of 8 (rho -1.272 against -1.450).
    element_smoothing : bool
        The smoothed descent on element sets (several vertex rows per slot) too. Off by
        default: the compiled local minimiser from ``element_ipopt_starts`` basins finds their
        minimum from the plain descent's starts alone (with IPOPT as the local solver the
        plain descent was once seen to rank the global basin's start too low, ``rho_hat``
        7.5e-3 too negative). Measured: the same values as with it on 120 random element sets
        (lamp, pistol, cup: no miss of the certified bracket) and on 150 sets one swap from a
        heuristic's (111 eligible: both missed on the same one), in 1.5x less CPU; the same
        plans on pistol 7-PCwF study seeds 0-7 and lamp seeds 1-8, CPU 1.1x less.
    smoothing_iterations : int
        Steps of the smoothed descent at each temperature.
    ipopt_starts : int
        Basins that IPOPT explores for contact sets (one row per slot): runs from the lowest end
        points of both descents, skipping an end point within ``tolerances.distinct_start`` of a
        start already tried or a minimum already found. A run that ends in a minimum already
        found does not count, up to ``runs_per_basin`` runs per basin in all. The first run that
        ends below zero ends the search: outside W a local minimum is the global one.
    element_ipopt_starts : int
        The same for element sets (a slot with several vertex rows, What_c^M): they have many
        more basins, which the descents' end values rank only roughly. On 205 seeded element
        and contact sets checked against certified bounds, 3 runs missed the global minimum on
        4 element sets (by up to 4.4e-3), 6 runs on 2 (1.8e-3), 8 runs on 1; contact sets were
        never missed with 3. The search is a heuristic: ``rho(..., certify=True)`` is the proof.
    max_iter : int
        IPOPT iteration cap per run.
    runs_per_basin : int
        IPOPT runs per basin of the budget, at most. A run that ends in a minimum already found
        explored no new basin: on a placement's round set two runs from warm starts ended in
        one local minimum and the global basin's start, ranked third, got none (rho 8%
        over-stated; tests/data/l_bracket_round_miss.json). 1: every run counts (enough
        where a certificate follows).
    ipopt_polish : bool
        With the ``"auto"`` solver, one IPOPT run from the compiled runs' best direction ends
        the search (the lower value is kept): what a search alone reports is then as accurate
        as IPOPT (on optimised placements' flat minima the compiled minimiser's values spread
        by up to 5e-6 relative over starts, IPOPT's by under 1e-9). ``False``: the compiled
        runs alone, for searches whose values are only compared and checked later (the
        placement's exchange rounds, screens).
    """

    samples: int = 128
    descent_iterations: int = 30
    smoothing: tuple = (0.1, 0.03, 0.01)
    element_smoothing: bool = False
    smoothing_iterations: int = 10
    ipopt_starts: int = 3
    element_ipopt_starts: int = 6
    max_iter: int = 300
    runs_per_basin: int = 2
    ipopt_polish: bool = True

    def __post_init__(self) -> None:
        for name in ("ipopt_polish", "element_smoothing"):
            object.__setattr__(self, name, as_flag(getattr(self, name), f"search.{name}"))
        may_be_zero = ("samples", "descent_iterations", "smoothing_iterations")
        counts = ("ipopt_starts", "element_ipopt_starts", "max_iter", "runs_per_basin")
        for name in (*may_be_zero, *counts):
            value = getattr(self, name)
            least = 0 if name in may_be_zero else 1
            if not is_whole(value) or value < least:
                raise ValueError(f"search.{name}: must be an integer >= {least}, got {value!r}")
            object.__setattr__(self, name, int(value))
        taus = self.smoothing
        if not isinstance(taus, tuple) or not all(
            isinstance(t, (int, float)) and not isinstance(t, bool) and t > 0 for t in taus
        ):
            raise ValueError(f"search.smoothing: must be a tuple of positive numbers, got {taus!r}")


# "auto": the compiled local minimiser from every start; a search alone (inside selection and
# placement, whose values are compared uncertified) ends with one IPOPT run from its best
# direction unless its options say otherwise (SearchOptions.ipopt_polish): on optimised placements'
# flat minima the compiled minimiser's values spread by up to 5e-6 relative over starts,
# IPOPT's by under 1e-9.
SOLVERS = ("auto", "ipopt", "compiled")
# The local solver of the default path: gradient sampling on the sphere, compiled
# (:func:`closure_nlp.kernels.descent.local_minimum`); its iteration cap and the cloud radius
# (radians) at which it stops.
LOCAL_MAX_ITER = 400
LOCAL_SMALLEST = 1e-12


@dataclass(frozen=True)
class SolverStats:
    """What the solves cost. ``status``/``success`` are those of the run that gave the answer.

    ``solver`` names what found the reported direction: ``"ipopt"`` (the support-minimum NLP),
    ``"local"`` (the compiled local minimiser), ``"descent"`` (a start's descent, no local run
    lowered it) or ``"branch_and_bound"`` (the certificate's search found a lower value)."""

    ipopt_runs: int
    iterations: int
    status: str
    success: bool
    seconds: float
    solver: str = "ipopt"


@dataclass(frozen=True, eq=False)
class SupportMinimum:
    """``min_{|u|=1} p(u)``: the value, where, and the wrench that attains it.

    Attributes
    ----------
    value : float
        ``p(direction)``, evaluated by the support function, not taken from the solver.
    direction : (6,) float
        Unit direction ``u*``.
    support_point : (6,) float
        A wrench of the set with ``u* . w = value``.
    stats : SolverStats
    """

    value: float
    direction: np.ndarray
    support_point: np.ndarray
    stats: SolverStats

    def __post_init__(self) -> None:
        frozen_arrays(self)


def robust_rho(result) -> float | None:
    """The capacity left within the tolerance, certified: every contact set within it has
    ``rho <= hi + shift`` (its support function moves by at most ``shift``), so a negative value
    is a load capacity every such set has. ``hi`` without a tolerance; None without bounds."""
    bounds = getattr(result, "bounds", None)
    return None if bounds is None else float(bounds[1]) + float(getattr(result, "shift", 0.0))


@dataclass(frozen=True, eq=False, kw_only=True)
class Certificate:
    """The fields a certified result adds to its search's (:class:`RhoResult`,
    :class:`~closure_nlp.criterion.rho_hat.EligibilityResult`): keyword-only, after the search's
    own.
    Their meaning for each is in its class."""

    bounds: tuple[float, float] | None = None
    marginal: bool = False
    converged: bool = True
    robust: bool | None = None
    shift: float = 0.0
    timing: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        frozen_arrays(self)

    @property
    def robust_rho(self) -> float | None:
        """:func:`robust_rho` of this result."""
        return robust_rho(self)


def frozen_arrays(result) -> None:
    """Every array field of the frozen ``result`` replaced by a read-only copy: a caller that
    writes into ``result.direction`` would otherwise change a certified result (and whatever
    else shares the array) behind its back."""
    for f in fields(result):
        value = getattr(result, f.name)
        if isinstance(value, np.ndarray):
            value = value.copy()
            value.flags.writeable = False
            object.__setattr__(result, f.name, value)


def certificate_of(result) -> dict:
    """The :class:`Certificate` fields of ``result``, as keyword arguments of another result."""
    return {f.name: getattr(result, f.name) for f in fields(Certificate)}


@dataclass(frozen=True, eq=False)
class RhoResult(Certificate):
    """rho(0, W_c^M) of a contact set.

    Attributes
    ----------
    rho : float
        Negative: force closure, ``-rho`` is the radius of the largest origin-centred ball inside
        ``W_c^M``. Non-negative: not force closure, the distance from the origin (0 when the set
        has no interior).
    force_closure : bool
    direction : (6,) float
        Unit ``u*`` with ``p(u*) = -rho``: the weakest wrench direction.
    support_point : (6,) float
    stats : SolverStats
    bounds : (float, float) or None
        Certified ``(lo, hi)`` with ``lo <= rho <= hi``; None only for results of the search
        alone (inside the selection and placement loops).
    marginal : bool
        The bounds reach within the tolerance of zero: within numerical accuracy of a set
        without interior; never force closure.
    converged : bool
        ``hi - lo`` within the tolerance (1e-6 relative); otherwise the bounds are valid but wider.
    robust : bool or None
        Force closure for every contact set within the set's tolerance
        (:mod:`closure_nlp.criterion.robustness`); None: no tolerance, the same as
        ``force_closure``.
    shift : float
        How far the support function can move within that tolerance (0 without one).
    timing : (float, float) or None
        Seconds of the search and of the certificate; ``stats.seconds`` is their sum.
    """

    rho: float
    force_closure: bool
    direction: np.ndarray
    support_point: np.ndarray
    stats: SolverStats = field(repr=False)

    def to_dict(self) -> dict:
        return {
            "rho": self.rho,
            "force_closure": self.force_closure,
            "direction": self.direction.tolist(),
            "support_point": self.support_point.tolist(),
            "solver": self.stats.solver,
            "ipopt_runs": self.stats.ipopt_runs,
            "iterations": self.stats.iterations,
            "seconds": self.stats.seconds,
            **timing_keys(self),
            **certificate_keys(self),
        }


def timing_keys(result) -> dict:
    """The JSON key ``timing`` (``search`` and ``certificate`` seconds) of a certified result,
    or none for the search alone."""
    timing = getattr(result, "timing", None)
    if timing is None:
        return {}
    return {"timing": {"search": float(timing[0]), "certificate": float(timing[1])}}


def certificate_keys(result) -> dict:
    """The JSON keys of a result's certificate (``bounds``, ``marginal``, ``converged``), or
    none for the search alone; shared by every result that reports rho or rho_hat."""
    if getattr(result, "bounds", None) is None:
        return {}
    lo, hi = result.bounds
    robust = getattr(result, "robust", None)
    if robust is None:  # no tolerance: robust is force closure (or eligibility)
        robust = bool(getattr(result, "force_closure", getattr(result, "eligible", False)))
    keys = {
        "bounds": [float(lo), float(hi)],
        "marginal": result.marginal,
        "converged": result.converged,
        "robust": robust,
        "robust_rho": robust_rho(result),
    }
    if getattr(result, "shift", 0.0):
        keys["tolerance_shift"] = float(result.shift)
    return keys


class SupportMinProblem:
    """The NLP ``min_{|u|=1} p(u)`` for one shape, built once, called many times.

    Parameters
    ----------
    n_pieces : tuple of int
        Friction pieces of each slot's contact type (0 FPC, 1 PCwF/SFCe, 2 SFCl).
    rows_per_slot : tuple of int
        Grasp matrices in each slot (1 for contacts, for elements the vertex count padded by
        :func:`~closure_nlp.contact.wrenches.padded_rows`: a slot's last row is repeated up to it).
    """

    def __init__(
        self,
        n_pieces,
        rows_per_slot,
        tolerances: Tolerances = DEFAULT_TOLERANCES,
        max_iter: int = 300,
        ipopt_options: dict | None = None,
    ):
        self.n_pieces = tuple(n_pieces)
        self.rows_per_slot = tuple(rows_per_slot)
        import casadi as ca  # here: the compiled path needs no NLP (casadi costs every start)

        m = len(self.n_pieces)
        u = ca.SX.sym("u", 6)
        z, t, total = ca.SX.sym("z", m), ca.SX.sym("t"), ca.SX.sym("sum_z")
        s_vars, P_vars, params, g = [], [], [], []
        # A slot's vertex rows at once: column r of its parameter block holds row r's vec(G),
        # f_max and pieces' weights (the order of parameters()). The same scalar expressions as
        # built row by row (the same solves to the bit) from fewer Python calls: element shapes
        # build 1.6-2x faster (a 7-contact set of contacts alone, 1.2x slower, is built once).
        for i, (pieces, rows) in enumerate(zip(self.n_pieces, self.rows_per_slot)):
            block = ca.SX.sym("G", 25 + 4 * pieces, rows)
            params.append(ca.vec(block))
            d = [u.T @ block[6 * j : 6 * j + 6, :] for j in range(4)]  # (G^T u)_j of each row
            f_max = block[24, :]
            if pieces:
                s = ca.SX.sym("s", 1, rows)
                s_vars.append(s.T)
                weights = [[block[25 + 4 * k + j, :] for j in range(4)] for k in range(pieces)]
                # piece by piece for each row in turn: s**2 - q(d)
                g.append(ca.vec(ca.vertcat(*[s**2 - piece_square(w, d) for w in weights])))
                values = f_max * (d[0] + s)
            else:
                values = f_max * d[0]
            if rows == 1:
                P_i = values  # a contact: no max over vertices, no extra variable
            else:
                P_i = ca.SX.sym("P")
                P_vars.append(P_i)
                g.append((P_i - values).T)
            g.append(z[i] - P_i)
            g.append(t - P_i - (total - z[i]))
        n_ineq = sum(part.numel() for part in g)
        g.append(total - ca.sum1(z))  # one sum for all slots: O(m) nonzeros, not O(m^2)
        g.append(ca.dot(u, u))
        x = ca.vertcat(u, *s_vars, *P_vars, z, t, total)
        self._n_s, self._n_P = sum(v.numel() for v in s_vars), len(P_vars)
        nlp = {"x": x, "p": ca.vertcat(*params), "f": t, "g": ca.vertcat(*g)}
        opts = {
            **NLPSOL_OPTIONS,
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "tol": tolerances.ipopt,
                "constr_viol_tol": tolerances.ipopt,
                "acceptable_tol": 1e-8,
                # IPOPT relaxes bounds by 1e-8 by default; on s**2 >= q at a cone's apex that lets
                # the friction term fall sqrt(1e-8) = 1e-4 short. No relaxation: s >= sqrt(q).
                "bound_relax_factor": 0.0,
                # Starts come from the descent, near a local minimum: a small initial barrier
                # keeps IPOPT in that basin instead of drifting to a worse one through the interior.
                "mu_init": 1e-3,
                "max_iter": max_iter,
                **(ipopt_options or {}),
            },
        }
        self._solver = ca.nlpsol("support_min", "ipopt", nlp, opts)
        inf = np.inf
        self._lbg = np.concatenate([np.zeros(n_ineq), [0.0, 1.0]])
        self._ubg = np.concatenate([np.full(n_ineq, inf), [0.0, 1.0]])
        self._lbx = np.concatenate(
            [
                np.full(6, -2.0),
                np.zeros(self._n_s),
                np.full(self._n_P, -inf),
                np.zeros(m),
                [-inf, 0.0],
            ]
        )
        self._ubx = np.concatenate([np.full(6, 2.0), np.full(self._n_s + self._n_P + m + 2, inf)])

    @staticmethod
    def key(slots: WrenchSlots) -> tuple:
        return (slots.n_pieces, tuple(padded_rows(k) for k in slots.rows_per_slot))

    def _rows(self, slots: WrenchSlots) -> np.ndarray:
        """The slots' row of each NLP row: a slot's last one repeated up to its padded size."""
        return np.concatenate(
            [
                start + np.minimum(np.arange(size), count - 1)
                for start, count, size in zip(slots.starts, slots.rows_per_slot, self.rows_per_slot)
            ]
        )

    def parameters(self, slots: WrenchSlots) -> np.ndarray:
        """Pack grasp matrices, force bounds and friction weights in the NLP's order."""
        parts = []
        slot_of_row = np.repeat(np.arange(len(self.n_pieces)), self.rows_per_slot)
        for i, r in zip(slot_of_row, self._rows(slots)):
            parts += [slots.G[r].T.ravel(), [slots.f_max[r]]]
            parts += list(slots.pieces[r, : self.n_pieces[i]])
        return np.concatenate(parts)

    def initial_guess(self, slots: WrenchSlots, u: np.ndarray) -> np.ndarray:
        """A feasible point of the epigraph at direction ``u``."""
        rows = self._rows(slots)
        d = slots.local(u)[0][rows]
        q = piece_square(slots.pieces[rows], d[:, None, :]).max(axis=1)
        has_s = np.repeat(np.array(self.n_pieces) > 0, self.rows_per_slot)
        s = np.sqrt(np.maximum(q, 0.0))[has_s] + 1e-8
        P = slots.slot_values(u)[0] + 1e-8
        z = np.maximum(P, 0.0) + 1e-8
        t = np.max(P + z.sum() - z) + 1e-8
        return np.concatenate([u, s, P[np.array(self.rows_per_slot) > 1], z, [t, z.sum()]])

    def solve(self, slots: WrenchSlots, u0: np.ndarray, params: np.ndarray | None = None):
        """One IPOPT run from ``u0``; returns (unit u, iterations, return status, success)."""
        if params is None:
            params = self.parameters(slots)
        with interruptible():
            sol = self._solver(
                x0=self.initial_guess(slots, u0),
                p=params,
                lbx=self._lbx,
                ubx=self._ubx,
                lbg=self._lbg,
                ubg=self._ubg,
            )
        stats = self._solver.stats()
        u = np.asarray(sol["x"][:6]).ravel()
        norm = np.linalg.norm(u)
        u = u / norm if norm > 0 else u0
        return (
            u,
            int(stats.get("iter_count", 0)),
            str(stats.get("return_status")),
            bool(stats.get("success", False)),
        )


MAX_PROBLEMS = 32  # cached NLP shapes per minimizer: ~7 MB each (a study worker held 42)
# One IPOPT run from a given direction, nothing else: the certificate's local solver.
POLISH_SEARCH = SearchOptions(
    samples=0, descent_iterations=0, smoothing=(), ipopt_starts=1, element_ipopt_starts=1
)
# The start strategy when a certificate follows (rho, certified rho_hat): the certificate proves
# the minimum whatever the incumbent, and lowers it where the search stopped short (polishing
# it by the local solver), so 16 samples and the plain descent do, without a smoothed one.
# Measured in one process on 20 sets per family against 32 samples with one smoothing
# temperature (min of 2 runs per set, CPU): every bracket converged and each pair overlaps;
# per-set ratios (median) 4 PCwF 1.18x, 4 SFCe 1.05x, 7 FPC 1.11x, 4 mixed 1.12x, rho_hat of 4
# lamp facets 1.18x (medians 6.4 -> 3.6 ms).
# Every run counts against its budget (runs_per_basin 1): the certificate lowers the value where
# the seed stopped short, and extra runs cost the certified rho_hat of 4 lamp facets 32 -> 45 ms.
SEED_SEARCH = SearchOptions(
    samples=16, smoothing=(), ipopt_starts=1, element_ipopt_starts=2, runs_per_basin=1
)


class SupportMinimizer:
    """Global ``min_{|u|=1} p(u)`` for any :class:`WrenchSlots`, one cached NLP per shape.

    Starts: two batched compiled descents, on ``p`` and on smoothings of it, from ``+-e_k`` and
    pseudo-random directions (and the warm start, when given), then IPOPT from the lowest end
    points of new basins; the best answer, by the support function evaluated at its unit
    direction, wins.

    ``search`` is the start strategy of a search alone (the comparisons inside selection and
    placement); ``seed_search`` that of a search whose answer a certificate then proves
    (:data:`SEED_SEARCH`; None: ``search`` as well). ``solver`` is the local solver run from
    the starts: ``"compiled"``, the compiled local minimiser (microseconds per run),
    ``"ipopt"``, the CasADi support-minimum NLP (the solver of record, about a millisecond per
    run), or ``"auto"``: the compiled one from every start, and for a search alone one IPOPT
    run from its best direction at the end (:attr:`SearchOptions.ipopt_polish`).
    """

    def __init__(
        self,
        tolerances: Tolerances = DEFAULT_TOLERANCES,
        search: SearchOptions = SearchOptions(),
        ipopt_options: dict | None = None,
        seed_search: SearchOptions | None = SEED_SEARCH,
        solver: str = "auto",
    ):
        if solver not in SOLVERS:
            raise ValueError(f"solver: must be one of {', '.join(SOLVERS)}, got {solver!r}")
        self.solver = solver
        if not isinstance(search, SearchOptions):
            raise TypeError(f"search: expected SearchOptions, got {search!r}")
        if not (seed_search is None or isinstance(seed_search, SearchOptions)):
            raise TypeError(f"seed_search: expected SearchOptions or None, got {seed_search!r}")
        self.tolerances = tolerances
        self.search = search
        self.seed_search = seed_search
        self.ipopt_options = dict(ipopt_options or {})
        # Each thread its own NLPs (solver_cache.py: one solver in two threads crashes IPOPT).
        self._caches: PerThread[dict] = PerThread(dict)

    @property
    def _problems(self) -> dict[tuple, SupportMinProblem]:
        """This thread's NLPs by shape, most recently used last."""
        return self._caches.get()

    def with_search(self, search: SearchOptions) -> SupportMinimizer:
        """The same NLPs (the cache is shared) with another start strategy."""
        other = SupportMinimizer(
            self.tolerances, search, self.ipopt_options, self.seed_search, self.solver
        )
        other._caches = self._caches
        return other

    def with_solver(self, solver: str) -> SupportMinimizer:
        """The same options and NLPs (the cache is shared) with another local solver."""
        return self._variant(self.tolerances, solver)

    def with_tol(self, tol: float) -> SupportMinimizer:
        """The same options and NLPs whose certificates stop at the relative bracket ``tol``
        (:func:`checked_tol`)."""
        return self._variant(replace(self.tolerances, certify=checked_tol(tol)), self.solver)

    def _variant(self, tolerances: Tolerances, solver: str) -> SupportMinimizer:
        other = SupportMinimizer(
            tolerances, self.search, self.ipopt_options, self.seed_search, solver
        )
        other._caches = self._caches
        return other

    def seeding(self) -> SupportMinimizer:
        """The same NLPs with the start strategy of a search that a certificate follows (and,
        with ``solver="auto"``, the compiled local minimiser)."""
        if self.seed_search is None:  # the search as well, solver and all
            return self
        seeded = self.with_search(self.seed_search)
        return seeded.with_solver("compiled") if self.solver == "auto" else seeded

    def local_solver(self) -> str:
        """``"ipopt"`` or ``"compiled"``: the local solver run from this minimizer's starts."""
        return "compiled" if self.solver == "auto" else self.solver

    def polish(self, slots: WrenchSlots, u: np.ndarray) -> np.ndarray:
        """A local minimum's direction of ``p`` near ``u`` (one run of the local solver;
        ``+-e_k`` instead when one is lower): what the certificate's branch and bound polishes
        its incumbent by."""
        polisher = self.with_search(POLISH_SEARCH)
        return (polisher.with_solver("compiled") if self.solver == "auto" else polisher)(
            slots, u
        ).direction

    def problem(self, slots: WrenchSlots) -> SupportMinProblem:
        """The NLP of this shape, built once; the least recently used of more than
        :data:`MAX_PROBLEMS` shapes is dropped (each holds several MB of CasADi functions)."""
        key = SupportMinProblem.key(slots)
        return cached(
            self._problems,
            key,
            lambda: SupportMinProblem(
                *key, self.tolerances, self.search.max_iter, self.ipopt_options
            ),
            MAX_PROBLEMS,
        )

    def __call__(
        self, slots: WrenchSlots, warm_start=None, stop_below: float | None = None
    ) -> SupportMinimum:
        """The search on the slots scaled to unit size (so IPOPT's absolute tolerances mean the
        same for any f_max, units or torque_scale), its value and support point scaled back.

        ``stop_below``: the caller only asks whether ``min p <= stop_below`` (is this trial no
        better than the best so far?); the search returns as soon as a direction shows it, in
        the descent or between IPOPT runs. Whatever the answer, it is as valid as the full
        search's: a support value at a unit direction. The iterative selection's screens of
        neighbours that cannot win then skip most of their work (1.5x faster selection).
        """
        from closure_nlp.criterion.certificate import tolerance_unit

        unit = tolerance_unit(slots)
        stop = None if stop_below is None else stop_below / unit
        found = self._search(slots.scaled(1.0 / unit), warm_start, stop)
        return SupportMinimum(
            found.value * unit, found.direction, found.support_point * unit, found.stats
        )

    def _search(self, slots: WrenchSlots, warm_start=None, stop=None) -> SupportMinimum:
        start_time = time.perf_counter()
        ipopt = self.local_solver() == "ipopt"
        problem = self.problem(slots) if ipopt else None
        search = self.search
        stop = -np.inf if stop is None else stop
        U0 = sphere_samples(search.samples)
        if warm_start is not None:
            U0 = np.vstack([_warm_starts(warm_start), U0])
        U, values = descend(slots, U0, search.descent_iterations, stop=stop)
        # Below zero, one local minimum is the global one (see the loop): no smoothing needed.
        smoothed = search.element_smoothing or slots.m == len(slots.G)
        if smoothed and search.smoothing and values.min() > stop and not values.min() < 0:
            U_s, values_s = smoothed_descent(
                slots, U0, search.smoothing, search.smoothing_iterations
            )
            U, values = np.vstack([U, U_s]), np.concatenate([values, values_s])
        params = problem.parameters(slots) if ipopt else None
        first = int(np.argmin(values))
        best = (values[first], U[first], "descent", False, "descent")
        iterations = runs = basins = 0
        budget = search.ipopt_starts if slots.m == len(slots.G) else search.element_ipopt_starts
        tried: list[np.ndarray] = []  # starts and the minima they led to
        minima: list[np.ndarray] = []
        near = self.tolerances.distinct_start
        for i in np.argsort(values, kind="stable"):
            if basins == budget or runs == search.runs_per_basin * budget or best[0] <= stop:
                break
            if any(np.linalg.norm(U[i] - v) <= near for v in tried):
                continue  # a basin already explored
            if ipopt:
                u, nit, status, success = problem.solve(slots, U[i], params)
            else:
                u, nit, status, success = _local_minimum(slots, U[i])
            runs += 1
            iterations += nit
            # A run that ends in a minimum already found explored no new basin: it does not
            # use up the budget (the descents' end values rank basins only roughly).
            if not any(np.linalg.norm(u - v) <= near for v in minima):
                basins += 1
                minima.append(u)
            tried += [U[i], u]
            value = float(slots.support(u)[0])
            if value < best[0]:
                best = (value, u, status, success, "ipopt" if ipopt else "local")
            if success and value < 0:
                # The origin is outside W, and a KKT point with p(u) < 0 is the global minimum:
                # -p is concave and positive there, so (homogeneity) the sphere's multiplier has
                # the sign of the ball's, and the point maximises -p over the whole unit ball.
                break
        ipopt_runs = runs if ipopt else 0
        if not ipopt and self.solver == "auto" and search.ipopt_polish and best[0] > stop:
            problem = self.problem(slots)
            u, nit, status, success = problem.solve(slots, best[1])
            ipopt_runs, iterations = 1, iterations + nit
            value = float(slots.support(u)[0])
            if value < best[0]:
                best = (value, u, status, success, "ipopt")
        value, u, status, success, solver = best
        stats = SolverStats(
            ipopt_runs,
            iterations,
            status,
            success,
            time.perf_counter() - start_time,
            solver,
        )
        return SupportMinimum(float(value), u, slots.support_point(u), stats)


def _local_minimum(slots: WrenchSlots, u0: np.ndarray):
    """One run of the compiled local minimiser: (unit u, iterations, status, success)."""
    u, _, iterations, converged = descent_kernels.local_minimum(
        *slots.packed, kernel_array(u0), LOCAL_MAX_ITER, LOCAL_SMALLEST
    )
    return u, int(iterations), "converged" if converged else "iteration limit", bool(converged)


def _warm_starts(warm_start) -> np.ndarray:
    """One direction (6,) or several (k, 6), checked and made unit: (k, 6)."""
    try:
        several = np.ndim(warm_start) == 2
    except ValueError:  # rows of unequal lengths: each is refused below, by its index
        several = True
    if not (several and len(warm_start) > 0):
        return as_unit_vector(warm_start, "warm_start", 6)[None]
    return np.array(
        [as_unit_vector(row, f"warm_start[{i}]", 6) for i, row in enumerate(warm_start)]
    )


_DEFAULT_MINIMIZER = SupportMinimizer()
_DEFAULT_MINIMIZERS = {
    "auto": _DEFAULT_MINIMIZER,
    **{name: SupportMinimizer(solver=name) for name in SOLVERS if name != "auto"},
}
# The relative widths a caller may ask of a certified bracket (``tol`` of rho and rho_many):
# down to what float64 sums of a few contacts still resolve, up to a tenth of the set's scale
# (wider says little about a grasp's quality).
TOL_RANGE = (1e-9, 0.1)
MAX_TOL_MINIMIZERS = 4  # minimizers of other brackets kept, the most recently used
_TOL_MINIMIZERS: dict = {}


def checked_tol(tol) -> float:
    """``tol`` checked against :data:`TOL_RANGE` (``TypeError`` or ``ValueError`` naming it);
    the package's certificate tolerance when None."""
    if tol is None:
        return DEFAULT_TOLERANCES.certify
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)):
        raise TypeError(f"tol: expected a number, got {tol!r:.60}")
    low, high = TOL_RANGE
    if not low <= tol <= high:  # NaN fails too
        raise ValueError(f"tol: expected a number in [{low:g}, {high:g}], got {tol!r}")
    return float(tol)


def minimizer_for(tol: float) -> SupportMinimizer:
    """The shared minimizer whose certificates stop at the relative bracket ``tol`` (checked):
    the package's own for its default, else one made once per value (its NLPs built on first
    use)."""
    return tol_variant(_DEFAULT_MINIMIZER, tol, _TOL_MINIMIZERS)


def tol_variant(minimizer: SupportMinimizer, tol: float, cache: dict) -> SupportMinimizer:
    """``minimizer`` itself when its certificates stop at ``tol``, else its variant that does
    (:meth:`SupportMinimizer.with_tol`), kept in ``cache`` (the most recently used
    :data:`MAX_TOL_MINIMIZERS`)."""
    if tol == minimizer.tolerances.certify:
        return minimizer
    return cached(cache, tol, lambda: minimizer.with_tol(tol), MAX_TOL_MINIMIZERS)


def rho(
    contact_set: ContactSet,
    *,
    minimizer: SupportMinimizer | None = None,
    warm_start=None,
    certify: bool = True,
    tolerance=None,
    solver: str | None = None,
    tol: float | None = None,
    workers: int | None = None,
) -> RhoResult:
    """rho(0, W_c^M) of a contact set (eq 24), with certified bounds.

    Parameters
    ----------
    contact_set : ContactSet
    minimizer : SupportMinimizer, optional
        Holds the cached NLPs and the options; a shared default is used when omitted.
    warm_start : (6,) or (k, 6) float, optional
        Non-zero directions to add to the starts (e.g. the previous ``u*`` in a loop).
    certify : bool
        Accepted for compatibility: the bounds are always computed.
    tolerance : ModelTolerance, optional
        The model's accuracy (default: the contact set's own): ``robust`` and ``shift`` of the
        result say whether every set within it is force closure.
    solver : {"auto", "ipopt", "compiled"}, optional
        The local solver of the search (``minimizer``'s when omitted, else ``"auto"``, the
        compiled minimiser under the certificate): ``"ipopt"`` runs the CasADi support-minimum
        NLP, certified the same way.
    tol : float, optional
        Relative width of the certified bracket, ``hi - lo <= tol * max(|rho|, unit)`` with
        ``unit`` the set's own wrench scale, in ``[1e-9, 0.1]`` (default: ``minimizer``'s
        tolerances, 1e-6); the verdicts take the same accuracy. Not with ``minimizer``.
    workers : int, optional
        Threads for a long certificate (round parts, many contacts), at most two of them busy;
        the answer is the same to the bit for any value. Default: the cores this process may
        use.

    Returns
    -------
    RhoResult
        ``rho`` is the lowest support value found (IPOPT's or the certificate's), inside the
        certified ``bounds``; ``force_closure`` only when the bounds are below zero by more than
        the tolerance, ``marginal`` when they reach within it.
    """
    if not isinstance(contact_set, ContactSet):
        raise TypeError(f"contact_set: expected a ContactSet, got {type(contact_set).__name__}")
    certify = as_flag(certify, "certify")
    from closure_nlp.criterion.robustness import with_robustness

    if solver is not None and solver not in SOLVERS:
        raise ValueError(f"solver: must be one of {', '.join(SOLVERS)}, got {solver!r}")
    workers = checked_workers(workers)
    if tol is not None:
        if minimizer is not None:
            raise ValueError("tol: give tol or a minimizer (its tolerances set the bracket)")
        minimizer = minimizer_for(checked_tol(tol))
    if minimizer is None:
        minimizer = _DEFAULT_MINIMIZERS[solver or "auto"]
    elif solver is not None and solver != minimizer.solver:
        minimizer = minimizer.with_solver(solver)
    slots = WrenchSlots.from_contacts(contact_set)
    result = certified_search(minimizer, slots, warm_start, workers=workers)
    tolerance = contact_set.tolerance if tolerance is None else tolerance
    return with_robustness(result, slots, tolerance, minimizer.tolerances)


def search_rho(
    contact_set: ContactSet, *, minimizer: SupportMinimizer | None = None, warm_start=None
) -> RhoResult:
    """rho of the search alone, without bounds (``bounds`` None): for the comparisons inside
    search loops (placement), where a looser answer is fine; every reported value goes through
    :func:`rho`. ``contact_set`` may also be its :class:`WrenchSlots`, when the caller has them."""
    if not isinstance(contact_set, (ContactSet, WrenchSlots)):
        raise TypeError(
            f"contact_set: expected a ContactSet or WrenchSlots, got {type(contact_set).__name__}"
        )
    minimizer = minimizer or _DEFAULT_MINIMIZER
    slots = as_slots(contact_set)
    found = minimizer(slots, warm_start)
    value = signed_distance(found, slots, minimizer.tolerances)
    return RhoResult(value, value < 0.0, found.direction, found.support_point, found.stats)


def certified_search(
    minimizer: SupportMinimizer, slots: WrenchSlots, warm_start=None, *, workers: int = 1
) -> RhoResult:
    """The seed search (:attr:`SupportMinimizer.seed_search`), then its certificate (its long
    rounds in ``workers`` threads: :attr:`BranchBoundOptions.workers`).

    A bracket left unconverged (a continuum of equally weak directions, where the branch and
    bound stops at its budget) holds a reported value that is only as good as the incumbent: the
    full search then starts from the certificate's best direction, and a weaker direction it
    finds becomes the reported value and raises ``lo`` (any direction's support value bounds
    ``min p`` from above), so a light seed never costs the headline number. Not a second
    certificate: on two opposite soft fingers that doubled the time (10 -> 18 s) for the same
    bracket.

    The seed search stops at its first direction with ``p`` below zero by more than the
    certificate's tolerance: the origin is then outside ``W``, where the certificate's
    nearest-point iteration is exact from any such direction (sets not in force closure: 3.2-3.4x
    less CPU, the local minimiser's runs were most of it).
    """
    from closure_nlp.criterion.certificate import tolerance_unit, verdicts

    seed = minimizer.seeding()
    below = -minimizer.tolerances.certify * tolerance_unit(slots)
    result = certified_rho(slots, seed(slots, warm_start, below), minimizer, workers=workers)
    if result.converged or result.marginal or seed is minimizer:
        return result
    more = minimizer(slots, result.direction)
    if more.value >= -result.rho:
        return result
    lo, hi = -more.value, result.bounds[1]
    unit = tolerance_unit(slots)
    gap = minimizer.tolerances.certify * max(abs(lo), unit)
    closure, marginal = verdicts(lo, hi, minimizer.tolerances.certify * unit)
    return replace(
        result,
        rho=lo,
        force_closure=closure,
        direction=more.direction,
        support_point=more.support_point,
        bounds=(lo, hi),
        marginal=marginal,
        converged=hi - lo <= gap,
    )


def certified_rho(
    slots: WrenchSlots, found: SupportMinimum, minimizer: SupportMinimizer, *, workers: int = 1
) -> RhoResult:
    """The search's minimum made certain: bounds started at its direction (and polished by the
    minimizer's local solver), the lower value wins."""
    from closure_nlp.criterion.certificate import certified_bounds, threaded_options

    bounds = certified_bounds(
        slots,
        found.direction,
        options=threaded_options(min(workers, 2)),  # two parts a round: more threads idle
        tolerances=minimizer.tolerances,
        polish=lambda u: minimizer.polish(slots, u),
    )
    if -bounds.lo < found.value:  # the certificate's search found a lower support value
        u = bounds.direction
        stats = replace(found.stats, solver="branch_and_bound")
        found = SupportMinimum(-bounds.lo, u, slots.support_point(u), stats)
    value = -found.value
    if bounds.marginal and bounds.lo <= 0.0 <= bounds.hi:
        value = 0.0  # no interior, within numerical accuracy
    search_seconds = found.stats.seconds
    return RhoResult(
        value,
        bounds.force_closure,
        found.direction,
        found.support_point,
        replace(found.stats, seconds=search_seconds + bounds.seconds),
        bounds=(bounds.lo, bounds.hi),
        marginal=bounds.marginal,
        converged=bounds.converged,
        timing=(search_seconds, bounds.seconds),
    )


def signed_distance(found: SupportMinimum, slots: WrenchSlots, tolerances: Tolerances) -> float:
    """``-min p(u)`` of the search alone, with round-off around 0 (relative to the set's scale)
    snapped to exactly 0 (no interior: not closure)."""
    from closure_nlp.criterion.certificate import tolerance_unit

    value = -found.value
    return 0.0 if abs(value) <= tolerances.zero_rho * tolerance_unit(slots) else value


__all__ = [
    "Certificate",
    "certificate_of",
    "RhoResult",
    "SearchOptions",
    "SolverStats",
    "SupportMinProblem",
    "SupportMinimizer",
    "SupportMinimum",
    "certificate_keys",
    "certified_rho",
    "certified_search",
    "checked_tol",
    "frozen_arrays",
    "minimizer_for",
    "tol_variant",
    "rho",
    "search_rho",
    "signed_distance",
    "timing_keys",
]
