"""Certified ``lo <= rho <= hi`` for every rho and rho_hat, independent of the local solver.

``rho = -min_{|u|=1} p(u)`` with ``p`` the support function of a compact convex set ``W``
(:class:`~closure_nlp.contact.wrenches.WrenchSlots`). Two regimes, each with an exact certificate:

* some direction has ``p(u) < 0``: the origin is outside ``W`` and ``rho = dist(0, W)``, bracketed
  by ``-p(u)`` below and the norm of a point of ``W`` above
  (:mod:`closure_nlp.criterion.hull_distance`);
* otherwise ``min p`` is bracketed by the best direction found above and by a branch and bound
  over the sphere below (:mod:`closure_nlp.criterion.sphere_branch_bound`); when the branch and
  bound
  meets a
  direction with ``p < 0`` it hands over to the first regime.

On the boundary (``p`` within the gap of zero at the start direction) a frictionless set first
looks for a point of ``W`` at the origin by a linear program: ``rho <= |x|`` for every point
``x`` of ``W``, so one such point closes the bracket at 0 where both regimes would crawl (a set
without interior, e.g. locators that let the part spin).

Tolerances are relative to the set's scale (:func:`tolerance_unit`), never absolute: the same
part in metres and in millimetres, or with ``f_max`` scaled by any factor, gets the same verdict
and the same relative bracket.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.base.validation import as_unit_vector, is_whole
from closure_nlp.contact.wrenches import WrenchSlots, as_slots
from closure_nlp.criterion.hull_distance import min_norm_point, nearest_point_bounds
from closure_nlp.criterion.sphere_branch_bound import BranchBoundOptions, sphere_minimum
from closure_nlp.criterion.sphere_search import descend, sphere_samples

# Torque rows this many times larger or smaller than force rows: verdicts on a whitened copy.
# Below it the metric alone evens the cells out (at 100, 4 of 70 sets with lever arms 10-100
# stopped 4-34% wide on the whitened copy's small budget; at 1e4 one, 7% wide).
WHITEN = 1e4
ANISOTROPIC_CELLS = 4000


@dataclass(frozen=True)
class CertifyOptions:
    """Budget of the certificate.

    Attributes
    ----------
    branch_bound : BranchBoundOptions
        Budget and shape of the branch and bound (regime ``rho <= 0``).
    max_iter : int
        Support points added by the nearest-point iteration (regime ``rho > 0``).
    """

    branch_bound: BranchBoundOptions = BranchBoundOptions()
    max_iter: int = 200

    def __post_init__(self) -> None:
        if not isinstance(self.branch_bound, BranchBoundOptions):
            raise TypeError(
                f"options.branch_bound: expected BranchBoundOptions, got "
                f"{type(self.branch_bound).__name__}"
            )
        value = self.max_iter
        if not is_whole(value) or value < 1:
            raise ValueError(f"options.max_iter: must be an integer >= 1, got {value!r}")
        object.__setattr__(self, "max_iter", int(value))


@lru_cache(maxsize=4)
def threaded_options(workers: int) -> CertifyOptions:
    """The default budget, the branch and bound's long rounds run in ``workers`` threads."""
    return CertifyOptions(branch_bound=BranchBoundOptions(workers=workers))


@dataclass(frozen=True)
class CertifiedBounds:
    """``lo <= rho <= hi``; unpacks as ``lo, hi = certified_bounds(...)``.

    Attributes
    ----------
    lo, hi : float
    converged : bool
        ``hi - lo <= tol * max(|rho|, unit)`` (:func:`tolerance_unit`); otherwise the bounds are
        valid but wider.
    force_closure : bool
        ``hi < -tol * unit``: certified force closure (eligible, for element sets) beyond the
        numerical accuracy.
    marginal : bool
        The bracket comes within ``tol * unit`` of zero: within numerical accuracy of a set
        without interior. Never force closure.
    iterations : int
        Branch-and-bound rounds or nearest-point steps.
    points : int
        Directions at which ``p`` and a support point were evaluated.
    seconds : float
    direction : (6,) float
        The unit direction with the lowest support value found: ``p(direction) = -lo``.
    unit : float
        The scale the tolerances are relative to.
    """

    lo: float
    hi: float
    converged: bool
    force_closure: bool
    marginal: bool
    iterations: int
    points: int
    seconds: float
    direction: np.ndarray = field(repr=False, compare=False, default=None)
    unit: float = 1.0

    def __post_init__(self) -> None:
        if isinstance(self.direction, np.ndarray):  # read-only, as in every certified result
            direction = self.direction.copy()
            direction.flags.writeable = False
            object.__setattr__(self, "direction", direction)

    def __iter__(self):
        yield self.lo
        yield self.hi

    @property
    def gap(self) -> float:
        return self.hi - self.lo


def tolerance_unit(slots: WrenchSlots) -> float:
    """The scale every tolerance of the certificate is relative to.

    The smaller of the scales of the rows' normal forces and of their torques
    (:meth:`WrenchSlots.row_scales`, ``f_max`` for the force part): it follows ``f_max``, the
    length unit and ``torque_scale`` alike, and a set whose torques are 10-100x its forces (long
    lever arms, ``torque_scale`` 1) keeps the precision of its force scale.
    """
    force, torque = slots.row_scales(friction=False)
    positive = [s for s in (force, torque) if s > 0]
    return min(positive) if positive else 1.0


def certified_bounds(
    slots_or_contact_set,
    direction=None,
    *,
    tol: float | None = None,
    options: CertifyOptions = CertifyOptions(),
    tolerances: Tolerances = DEFAULT_TOLERANCES,
    polish=None,
) -> CertifiedBounds:
    """Bounds ``lo <= rho <= hi`` with ``hi - lo <= tol * max(|rho|, unit)``.

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet
    direction : (6,) float, optional
        A direction near the minimiser (e.g. IPOPT's ``u*``): the bounds hold whatever it is; a
        good one only saves work. Without it a batched descent finds a start.
    tol : float, optional
        Relative gap to reach; ``tolerances.certify`` (1e-6) when omitted.
    options : CertifyOptions
    tolerances : Tolerances
    polish : callable, optional
        ``polish(u) -> (6,)``, a local minimiser of this set's support function from ``u``
        (:meth:`~closure_nlp.criterion.support_minimum.SupportMinimizer.polish`): it keeps the
        branch and
        bound's
        incumbent at a minimum (:func:`~closure_nlp.criterion.sphere_branch_bound.sphere_minimum`).
        The
        bounds
        do not depend on it.

    Returns
    -------
    CertifiedBounds
        Valid bounds even when the budget runs out (then ``converged`` is ``False``).
    """
    start_time = time.perf_counter()
    slots = as_slots(slots_or_contact_set)
    if tol is None:
        tol = tolerances.certify
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 < tol < 1:
        raise ValueError(f"tol: must be a number in (0, 1), got {tol!r}")
    if not isinstance(options, CertifyOptions):
        raise TypeError(f"options: expected CertifyOptions, got {type(options).__name__}")
    verdict = _whitened_verdict(slots, tol, options, tolerances)
    budget = options.branch_bound
    if verdict is not None:
        # The set's own bracket would need cells finer than its anisotropy: a small budget
        # (valid, usually unconverged bounds), tightened by the whitened set's bracket.
        cells = min(budget.max_cells, ANISOTROPIC_CELLS)
        budget = replace(budget, max_cells=cells, extended_cells=cells)
    unit = tolerance_unit(slots)
    # Every step below is scale-free; run it on the set scaled to unit size and scale back.
    slots = slots.scaled(1.0 / unit)
    if direction is None:
        U, values = descend(slots, sphere_samples(64), 30)
        u0 = U[int(np.argmin(values))]
    else:
        u0 = as_unit_vector(direction, "direction", 6)
    value0 = float(slots.support(u0[None])[0])

    def gap(value: float) -> float:
        return tol * max(abs(value), 1.0)

    if verdict is not None and verdict[2] is not None:
        u0 = verdict[2] / np.linalg.norm(verdict[2])
        value0 = float(slots.support(u0[None])[0])
    if abs(value0) <= gap(value0):
        # On the boundary, within the gap: a point of W at the origin closes the bracket.
        near = _point_at_origin(slots)
        if near is not None and near <= gap(value0):
            return _result(-value0, near, True, 0, 1, start_time, u0, tol, unit, verdict)
    if value0 >= 0:
        found = sphere_minimum(
            slots, u0, gap=gap(value0), metric=_metric(slots), options=budget, polish=polish
        )
        if found.converged and found.upper - found.lower > gap(found.lower):
            # The gap was the start's value's, above the minimum (a start far from it): again
            # from the incumbent with the bracket's own, rho's gap at most.
            first = found
            again = sphere_minimum(
                slots, first.direction, gap=gap(first.lower), metric=_metric(slots),
                options=budget, polish=polish,
            )  # fmt: skip
            found = replace(
                again if again.converged else first,
                evaluations=first.evaluations + again.evaluations,
                rounds=first.rounds + again.rounds,
            )
        if found.upper >= 0:  # the origin is not outside: rho = -min p
            lo, hi = -found.upper, -found.lower
            return _result(
                lo,
                hi,
                found.converged,
                found.rounds,
                found.evaluations,
                start_time,
                found.direction,
                tol,
                unit,
                verdict,
            )
        u0, value0 = found.direction, found.upper
        evaluations, rounds = found.evaluations, found.rounds
    else:
        evaluations = rounds = 0
    # The origin is outside W: rho = dist(0, W) > 0.
    lo, hi, u, converged, more = nearest_point_bounds(slots, u0, gap(value0), options.max_iter)
    return _result(lo, hi, converged, rounds, evaluations + more, start_time, u, tol, unit, verdict)


def _point_at_origin(slots: WrenchSlots) -> float | None:
    """``|x|`` of a point ``x`` of ``W`` at the origin, for a set without friction (a
    polytope), found by a linear program; None when there is none or the set has friction.

    Any point of ``W`` bounds ``rho = -min p <= |x|`` (``p(u) >= x . u``), so with a direction
    where ``p`` is zero within the gap, the bracket closes at 0: a set without interior (7
    frictionless locators whose wrenches span 5 dimensions) whose branch and bound would
    crawl towards ``p``'s kinks around the direction normal to the span. ``W`` is ``{sum_ij
    lam_ij c_ij : lam >= 0, sum_j lam_ij <= 1 per slot i, sum_ij lam_ij >= 1}`` (``c_ij`` the
    rows' wrenches at ``f_max``). The LP's weights are repaired into that set, and the bound
    pays for what is left of their infeasibility, so it does not rest on the LP's tolerances.
    """
    c = slots._normal_wrenches()  # (K, 6): the rows' wrenches, None with friction
    if c is None:
        return None
    from scipy.optimize import linprog  # here: its import costs a command's start 0.2-0.5 s

    K, m = len(c), slots.m
    slot = np.repeat(np.arange(m), slots.rows_per_slot)
    per_slot = np.zeros((m, K))
    per_slot[slot, np.arange(K)] = 1.0
    found = linprog(
        np.zeros(K),
        A_ub=np.vstack([per_slot, -np.ones((1, K))]),
        b_ub=np.append(np.ones(m), -1.0),
        A_eq=c.T,
        b_eq=np.zeros(6),
        bounds=(0, None),
        method="highs",
    )
    if found.status != 0:
        return None
    lam = np.maximum(found.x, 0.0)
    lam /= np.maximum(1.0, per_slot @ lam)[slot]  # each slot's weights at most 1
    short = max(0.0, 1.0 - lam.sum())  # what the weights miss of the sum of at least 1
    return float(np.linalg.norm(lam @ c)) + short * float(np.linalg.norm(c, axis=1).max())


def _metric(slots: WrenchSlots) -> np.ndarray:
    """The diagonal that partitions the sphere evenly for this set: torque directions scaled by
    the force scale over the torque scale (lever arms of 10-100 units at torque_scale 1 make
    the torque rows 10-100x the force rows)."""
    force, torque = slots.row_scales(friction=False)
    ratio = force / torque if force > 0 and torque > 0 else 1.0
    return np.repeat([1.0, float(np.clip(ratio, 1.0 / WHITEN, WHITEN))], 3)


def _whitened_verdict(slots, tol, options, tolerances):
    """``(lo, hi, separating)`` for a set whose torque rows are more than :data:`WHITEN` times
    larger or smaller than its force rows: bounds on its rho (``-inf``/``inf`` where none
    follows) from the set with torques rescaled to the forces' size, a linear map, which keeps
    the origin inside or outside, while the set's own bracket would need cells finer than the
    anisotropy; ``separating`` a direction where ``p < 0``, or None. None for other sets."""
    force, torque = slots.row_scales(friction=False)
    if not (force > 0 and torque > 0) or max(force, torque) <= WHITEN * min(force, torque):
        return None
    G = slots.G.copy()
    G[:, 3:, :] *= force / torque
    whitened = WrenchSlots(G, slots.starts, slots.f_max, slots.pieces, slots.types, slots.n_pieces)
    bounds = certified_bounds(whitened, tol=tol, options=options, tolerances=tolerances)
    # A direction separating the whitened set from the origin separates the set itself once
    # mapped back (p_W(D u) = p_{DW}(u) with D = diag(1, 1, 1, f/t, f/t, f/t)).
    separating = None
    if bounds.lo > 0 and not bounds.marginal:
        separating = bounds.direction * np.repeat([1.0, force / torque], 3)
    # The whitened bracket bounds the set's own: every unit v is D u / |D u| for a unit u, and
    # p_W(v) = p_{DW}(u) / |D u| with |D u| <= max(1, f/t); so a whitened hi < 0 gives
    # hi / max(1, f/t) for the set, a whitened lo > 0 likewise lo / max(1, f/t).
    stretch = max(1.0, force / torque)
    hi = bounds.hi / stretch if bounds.hi < 0 else np.inf
    lo = bounds.lo / stretch if bounds.lo > 0 else -np.inf
    return lo, hi, separating


def verdicts(lo: float, hi: float, zero: float) -> tuple[bool, bool]:
    """``(force_closure, marginal)`` of a certified bracket ``lo <= rho <= hi``: the only place
    they are decided, so no verdict ever contradicts the bounds it is reported with.

    Force closure (eligible) only when ``hi < -zero``: below zero beyond the numerical accuracy
    ``zero``. Marginal when the bracket reaches within ``zero`` of zero (``hi >= -zero`` and
    ``lo <= zero``): within that accuracy of a set without interior, never force closure. A
    bracket with ``lo > zero`` is neither: certainly not force closure."""
    closure = bool(hi < -zero)
    return closure, bool(not closure and lo <= zero)


def _result(lo, hi, converged, iterations, points, start_time, direction, tol, unit, verdict):
    """Bounds of the unit-size set scaled back by ``unit``, tightened by the whitened set's
    (``verdict``) when there is one, with the verdicts of that bracket."""
    hi = max(hi, lo)  # roundoff of two exact bounds of the same number
    lo, hi = lo * unit, hi * unit
    if verdict:
        lo, hi = max(lo, verdict[0]), min(hi, verdict[1])
        hi = max(hi, lo)
        converged = converged or hi - lo <= tol * max(abs(lo), unit)
    closure, marginal = verdicts(lo, hi, tol * unit)
    return CertifiedBounds(
        float(lo),
        float(hi),
        bool(converged),
        closure,
        marginal,
        int(iterations),
        int(points),
        time.perf_counter() - start_time,
        direction,
        unit,
    )


__all__ = [
    "CertifiedBounds",
    "CertifyOptions",
    "certified_bounds",
    "min_norm_point",
    "tolerance_unit",
    "verdicts",
]
