"""Certified load factors: how many times a given wrench the contacts can hold.

The contacts hold ``k`` times a load ``l`` when some forces in their exact cones with
``0 <= f_n <= f_max`` balance it: when ``k w`` lies in the wrench set ``W`` (the Minkowski sum of
each slot's ``conv({0} U W_i)``), ``w = -l``. The largest such ``k`` is a ray-shooting problem on
the convex set ``W``; by duality

    k* = min over u with u.w > 0 of h(u) / (u.w),    h(u) = sum_i max(P_i(u), 0),

``P_i`` the slot values of :class:`~closure_nlp.contact.wrenches.WrenchSlots` (``h`` is the
support function of ``W``: unlike eq 26's ``p`` it allows the empty subset, every contact idle).

Both sides are bounded by one column-generation loop (Dantzig-Wolfe on the slots): a linear
program over support wrenches already found, per slot a convex combination of them and the
origin, gives a force distribution holding ``lo`` times the load (every column is a support
wrench of its slot, inside ``W`` by construction); its dual direction ``u`` gives
``hi = h(u) / (u.w)`` by the exact support function, and the support wrenches at ``u`` are the
new columns (and, where a support set is a face and the LP's direction adds nothing new, the
support wrenches at directions near it). The loop stops when ``hi - lo <= certify * hi`` (aiming
10x inside it at first).

The lower end is verified against round-off: the LP meets its equations only to its feasibility
tolerance, so the combination is recomputed from the clipped weights (every weight >= 0, every
slot's total <= 1: a point of ``W`` exactly), and its residual off the load's ray is cancelled
by a correction LP scaled by the residual's size, until the wrench it sums lies on the ray
within ``RESIDUAL`` times the set's wrench scale (round-off of a wrench sum); ``lo`` is that
point's factor. The bound is certified to that round-off, as the support values of the rho
engine are. A load no contact can push against at all has ``hi`` within accuracy of zero:
reported ``marginal``, with its bracket.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np

# highspy.Highs, its subclass, prints a banner on stdout when it is made: the plain class
from highspy import HighsModelStatus, _Highs, kHighsInf
from scipy.optimize import linprog

from closure_nlp.base.formatting import certain
from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.base.validation import as_vector
from closure_nlp.contact.contact_set import ContactSet
from closure_nlp.contact.loads import as_loads, load_loads
from closure_nlp.contact.wrenches import WrenchSlots, as_slots

RESIDUAL = 1e-13  # a wrench sum's distance to the ray, relative to the set's wrench scale
MAX_ITERATIONS = 400
SLOW = 40  # iterations after which the width asked is enough
SPREADS = (1e-2, 1e-4, 1e-6)  # perturbations tried when the LP's direction adds no column
# Start columns: the support wrenches in the 12 axis directions and along the load.
_AXES = np.vstack([np.eye(6), -np.eye(6)])


@dataclass(frozen=True, eq=False)
class LoadFactor:
    """One load's certified factor.

    Attributes
    ----------
    load_factor : float
        ``lo``: the contacts certainly hold this many times the load.
    bounds : (float, float)
        ``lo <= k* <= hi``.
    marginal : bool
        ``hi`` is within the bracket's accuracy of zero (``certify`` times the factor at which
        one contact's largest wrench matches the load): the contacts cannot, or can barely,
        push against the load.
    converged : bool
        The bracket reached the relative width asked (``certify``).
    direction : (6,) float
        The unit dual direction ``u`` giving ``hi`` (the wrench direction the load exhausts).
    iterations : int
    seconds : float
    """

    load_factor: float
    bounds: tuple[float, float]
    marginal: bool
    converged: bool
    direction: np.ndarray = field(repr=False)
    iterations: int = 0
    seconds: float = 0.0

    def to_dict(self) -> dict:
        return {
            "load_factor": self.load_factor,
            "bounds": list(self.bounds),
            "marginal": self.marginal,
            "converged": self.converged,
        }


def support_values(slots: WrenchSlots, U: np.ndarray) -> np.ndarray:
    """``h(u) = sum_i max(P_i(u), 0)`` (N,): the support function of ``W``, idle contacts
    allowed."""
    return np.maximum(slots.slot_values(U), 0.0).sum(axis=1)


def _slot_wrenches(slots: WrenchSlots, u: np.ndarray):
    """Each slot's value at ``u`` (m,) and the support wrench of its best row (m, 6)."""
    values, wrenches = slots.row_support(u[None])
    values, wrenches = values[0], wrenches[0]
    ends = np.append(slots.starts, len(slots.G))
    best = np.array([a + int(np.argmax(values[a:b])) for a, b in zip(ends[:-1], ends[1:])])
    return values[best], wrenches[best]


class _Master:
    """The restricted master LP ``max k`` s.t. ``A lam = k t``, ``B lam <= 1``, ``lam >= 0``
    over the support wrenches found so far (scaled by the set's wrench scale), kept in one HiGHS
    model: new columns are added and the LP re-solved from the last basis."""

    def __init__(self, m: int, t: np.ndarray):
        self.m, self.t = m, t
        self.wrenches: list[np.ndarray] = []
        self.slot: list[int] = []
        self._seen: set[bytes] = set()
        h = _Highs()
        h.setOptionValue("output_flag", False)
        h.setOptionValue("presolve", "off")  # a small dense LP, re-solved from its last basis
        # HiGHS's defaults (1e-7) would stop the bracket above 1e-7 relative: reduced costs that
        # small leave improving columns out
        h.setOptionValue("dual_feasibility_tolerance", 1e-10)
        h.setOptionValue("primal_feasibility_tolerance", 1e-10)
        inf = kHighsInf
        h.addRows(6, np.zeros(6), np.zeros(6), 0, np.zeros(7, np.int32), [], [])
        h.addRows(m, np.full(m, -inf), np.ones(m), 0, np.zeros(m + 1, np.int32), [], [])
        # k: the column of -t in the equality rows
        h.addCols(1, [-1.0], [0.0], [inf], 6, [0], np.arange(6, dtype=np.int32), -t)
        self.h = h

    def add(self, slots: WrenchSlots, U: np.ndarray, scale: float) -> int:
        """The slots' support wrenches at each of ``U`` as new columns; returns how many."""
        added = 0
        for u in U:
            values, wrenches = _slot_wrenches(slots, u)
            for i in np.flatnonzero(values > 0.0):
                g = wrenches[i] / scale
                key = np.round(g, 14).tobytes() + int(i).to_bytes(4, "little")
                if key in self._seen:
                    continue
                self._seen.add(key)
                self.wrenches.append(g)
                self.slot.append(int(i))
                rows = np.append(np.arange(6), 6 + i).astype(np.int32)
                self.h.addCols(1, [0.0], [0.0], [kHighsInf], 7, [0], rows, np.append(g, 1.0))
                added += 1
        return added

    def matrices(self):
        """The columns ``A`` (6, n) and their slots' indicator rows ``B`` (m, n)."""
        A = np.array(self.wrenches).T if self.wrenches else np.zeros((6, 0))
        B = np.zeros((self.m, A.shape[1]))
        B[self.slot, np.arange(A.shape[1])] = 1.0
        return A, B

    def solve(self):
        """``(k, lam, u)``: the LP's optimum, weights and dual direction (``u.t >= 0``);
        ``u`` is ``None`` when the solver fails."""
        self.h.run()
        if self.h.getModelStatus() != HighsModelStatus.kOptimal:
            return 0.0, np.zeros(len(self.wrenches)), None
        sol = self.h.getSolution()
        x = np.asarray(sol.col_value)
        u = np.asarray(sol.row_dual[:6], dtype=float)
        if u @ self.t < 0:
            u = -u
        return float(x[0]), x[1:], u


def _feasible(A: np.ndarray, B: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``lam`` made a point of ``W`` exactly: no negative weight, no slot's total above 1."""
    lam = np.maximum(lam, 0.0)
    sums = B @ lam
    return lam / (B.T @ np.maximum(sums, 1.0))


def _verified_lower(A: np.ndarray, B: np.ndarray, lam: np.ndarray, t: np.ndarray) -> float:
    """The factor (along ``t``, scaled units) of a wrench sum of the columns that lies on the
    ray within ``RESIDUAL``, from the LP's weights ``lam``; 0 if none is found.

    The LP leaves its equations satisfied to its feasibility tolerance only; the residual is
    cancelled by a correction LP scaled by the residual's size (weights still >= 0, each slot's
    total still <= 1, the factor as high as it can stay): its own tolerance then acts on the
    residual, not on the wrench, and one or two corrections reach round-off."""
    lam = _feasible(A, B, lam)
    for _ in range(3):
        v = A @ lam
        k = float(v @ t)
        r = v - k * t
        size = float(np.linalg.norm(r))
        if size <= RESIDUAL:
            return max(k, 0.0)
        n = len(lam)
        # max dk s.t. A mu - dk t = -r / size, mu >= -lam / size, B (lam / size + mu) <= 1 / size
        res = linprog(
            np.append(np.zeros(n), -1.0),
            A_ub=np.hstack([B, np.zeros((len(B), 1))]),
            b_ub=(1.0 - B @ lam) / size,
            A_eq=np.hstack([A, -t[:, None]]),
            b_eq=-r / size,
            bounds=[*((-x / size, None) for x in lam), (None, None)],
            method="highs",
        )
        if res.status != 0:
            return 0.0
        lam = _feasible(A, B, lam + size * res.x[:-1])
    return 0.0


def _next_directions(u: np.ndarray, best: np.ndarray) -> np.ndarray:
    """The LP's direction, and one between it and the best dual direction so far (smooths the
    cutting planes' zig-zag)."""
    u = u / np.linalg.norm(u)
    mid = u + best / np.linalg.norm(best)
    norm = np.linalg.norm(mid)
    return np.array([u, mid / norm]) if norm > 0 else u[None]


def _around(u: np.ndarray, spread: float, rng) -> np.ndarray:
    """Directions near ``u``: where a slot's support set is a face (a cone's apex, SFCl's two
    pieces tied) the support wrench at ``u`` is one point of it, and the LP may need others."""
    U = u / np.linalg.norm(u) + spread * rng.standard_normal((12, 6))
    return U / np.linalg.norm(U, axis=1, keepdims=True)


def load_factor(
    slots_or_contact_set,
    load,
    *,
    tolerances: Tolerances = DEFAULT_TOLERANCES,
    max_iterations: int = MAX_ITERATIONS,
) -> LoadFactor:
    """The certified load factor of a load on contacts (or slots of elements).

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet
    load : (6,) float
        The load's wrench in the set's convention (force, then ``torque_scale`` times its
        moment about the reference point), as :meth:`~closure_nlp.contact.loads.LoadCase.wrench`
        gives it; the contacts must balance it.
    tolerances : Tolerances
        ``certify``: the bracket's relative width, and the ``marginal`` threshold.

    Returns
    -------
    LoadFactor
    """
    t0 = time.perf_counter()
    slots = as_slots(slots_or_contact_set)
    load = as_vector(load, "load", 6)
    size = float(np.linalg.norm(load))
    if not size > 0:
        raise ValueError("load: the wrench is zero (no force, no torque)")
    w = -load / size  # unit wrench the contacts must produce
    scale = max(slots.row_scales())
    master = _Master(slots.m, w)
    master.add(slots, np.vstack([_AXES, w]), scale)
    lo = hi = 0.0
    best_u = w.copy()
    converged = False
    iteration = 0
    rng = np.random.default_rng(0)  # the same answer every run

    def target(iteration: int) -> float:
        # aim 10x inside the width asked; accept the width asked once progress is slow (small
        # factors, where the LP's absolute tolerances are felt)
        return (0.1 if iteration < SLOW else 1.0) * tolerances.certify

    for iteration in range(1, max_iterations + 1):
        k, lam, u = master.solve()
        if u is None or not u @ w > 0:
            u = w
        # the dual bound, exact support function: h(u) / (u.w), in units of |load|
        bound = float(support_values(slots, u[None])[0]) / float(u @ w) / size
        if bound < hi or iteration == 1:
            hi, best_u = bound, u
        # verify the LP's point only once it would close the bracket (a correction LP each)
        if hi - k * scale / size <= target(iteration) * hi and k * scale / size > lo:
            lo = max(lo, _verified_lower(*master.matrices(), lam, w) * scale / size)
        if hi * size <= tolerances.certify * scale:  # marginal: no need for more
            break
        if hi - lo <= target(iteration) * hi:
            converged = True
            break
        if not master.add(slots, _next_directions(u, best_u), scale) and not any(
            master.add(slots, _around(u, spread, rng), scale) for spread in SPREADS
        ):
            break
    if k * scale / size > lo and not converged:  # the last LP's point, verified
        A, B = master.matrices()  # columns added after that LP weigh nothing in its point
        lam = np.pad(lam, (0, A.shape[1] - len(lam)))
        lo = max(lo, _verified_lower(A, B, lam, w) * scale / size)
    # within the bracket's accuracy of zero, measured against the factor at which one contact's
    # largest wrench matches the load
    marginal = hi * size <= tolerances.certify * scale
    converged = converged or marginal or hi - lo <= tolerances.certify * hi
    lo = min(lo, hi)
    return LoadFactor(
        lo,
        (lo, hi),
        marginal,
        converged,
        best_u / np.linalg.norm(best_u),
        iteration,
        time.perf_counter() - t0,
    )


@dataclass(frozen=True, eq=False)
class LoadFactors:
    """The certified factor of every load case, and the least.

    Attributes
    ----------
    names : tuple of str
        The cases, in the file's order.
    factors : tuple of LoadFactor
        One per case.
    """

    names: tuple[str, ...]
    factors: tuple[LoadFactor, ...]

    @property
    def load_factor(self) -> float:
        """The least certified factor over the cases: the contacts hold every case that many
        times."""
        return min(f.load_factor for f in self.factors)

    @property
    def bounds(self) -> tuple[float, float]:
        """Bounds on the least ``k*`` over the cases."""
        return min(f.bounds[0] for f in self.factors), min(f.bounds[1] for f in self.factors)

    @property
    def weakest(self) -> str:
        """The case with the least factor (the first of equal ones)."""
        return self.names[int(np.argmin([f.load_factor for f in self.factors]))]

    def to_dict(self) -> dict:
        """``loads``: per case ``name``, ``load_factor``, ``bounds``, ``marginal``;
        ``load_factor``: the least."""
        cases = [
            {
                "name": n,
                "load_factor": f.load_factor,
                "bounds": list(f.bounds),
                "marginal": f.marginal,
            }
            for n, f in zip(self.names, self.factors)
        ]
        return {"loads": cases, "load_factor": self.load_factor}

    def text(self) -> str:
        """One line: the least factor, its case, and every case's bracket."""
        parts = ", ".join(
            f"{n} {certain(f.load_factor, f.bounds)}" + (" (marginal)" if f.marginal else "")
            for n, f in zip(self.names, self.factors)
        )
        return f"load factor {certain(self.load_factor, self.bounds)} ({self.weakest}); {parts}"


def load_factors(
    contact_set,
    loads,
    *,
    reference_point=None,
    torque_scale: float | None = None,
    tolerances: Tolerances = DEFAULT_TOLERANCES,
) -> LoadFactors:
    """Certified load factors of load cases on a contact set.

    Each case's factor ``k*`` is the largest ``k`` such that forces in the contacts' exact cones
    with ``0 <= f_n <= f_max`` balance ``k`` times the case; ``f_max`` is read in the loads' force
    unit (the numbers are used as given).

    Parameters
    ----------
    contact_set : ContactSet or WrenchSlots
        For slots (elements), ``reference_point`` and ``torque_scale`` say how their torques
        were taken (default: the origin and 1).
    loads : Loads, dict, list or path
        The cases: a LOADS.json file, its parsed content, or its list of cases.
    reference_point, torque_scale
        Override the contact set's own (only for slots).
    tolerances : Tolerances
        ``certify``: each bracket's relative width.

    Returns
    -------
    LoadFactors
    """
    if isinstance(loads, (str, os.PathLike)):
        loads = load_loads(loads)
    loads = as_loads(loads)
    if isinstance(contact_set, ContactSet):
        reference_point = contact_set.reference_point
        torque_scale = contact_set.torque_scale
    slots = as_slots(contact_set)
    wrenches = loads.wrenches(reference_point, 1.0 if torque_scale is None else torque_scale)
    factors = tuple(load_factor(slots, w, tolerances=tolerances) for w in wrenches)
    return LoadFactors(tuple(c.name for c in loads.cases), factors)
