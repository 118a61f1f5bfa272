"""The least load factor as the exchange method's objective (``objective="loads"``).

The exchange method maximises ``r`` subject to ``p(u_k; c) >= r`` over a working set of
directions. A load case ``w`` (the wrench the contacts must produce) is held ``k`` times iff
``h(u) >= k u.w`` for every ``u``; the support function is positively homogeneous, so that is
``h(u / u.w) >= k`` for every ``u`` with ``u.w > 0``: the same restricted problems, fed with the
directions ``u / u.w`` of every case, maximise the least load factor over the working set, and the
load factor's own dual direction (the weakest case's, scaled so) is the next one to add. The
restricted model sums the pushing contacts' values (the largest alone when none pushes): at most
``h(u)``, so whatever it promises the contacts hold.

The exchange compares values as it compares rho, lower better, with gaps relative to
``max(1, |rho|)``: a result here carries ``rho = -k * unit``, the least certified factor in
units of the largest case over the largest ``f_max`` (a factor of about 1 when the contacts can
hold about their own capacity), so that loads of any size in any force unit steer alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from closure_nlp.contact.loads import as_loads
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.load_factor import LoadFactors, load_factor
from closure_nlp.criterion.sphere_search import sphere_samples


@dataclass(frozen=True, eq=False)
class LoadFound:
    """One evaluation of the objective, shaped as the exchange reads a rho search's answer.

    Attributes
    ----------
    rho : float
        Minus the least certified load factor, times the objective's ``unit`` (lower is
        better).
    direction : (6,) float
        The weakest case's dual direction ``u / u.w`` (``w`` over ``unit``): ``p(direction) >=
        -rho`` is its constraint.
    force_closure : bool
        The least factor is positive (every case is held to some degree).
    factors : LoadFactors
    """

    rho: float
    direction: np.ndarray
    force_closure: bool
    factors: LoadFactors


class LoadObjective:
    """The least load factor of the cases ``loads`` on slots of contacts or elements, the torques
    taken about ``reference_point`` times ``torque_scale`` (the eligibility's); ``f_max`` the
    contacts' largest."""

    def __init__(self, loads, reference_point, torque_scale: float, f_max: float = 1.0):
        self.loads = as_loads(loads)
        # the wrenches the contacts must produce, one per case
        self.targets = -self.loads.wrenches(reference_point, torque_scale)
        self.unit = float(np.linalg.norm(self.targets, axis=1).max()) / f_max

    @classmethod
    def of(cls, eligibility, loads) -> LoadObjective:
        """The objective of ``loads`` on contacts or elements of ``eligibility``: torques about
        its model's reference point times its torque scale, ``f_max`` its specs' largest."""
        f_max = max(spec.f_max for spec in eligibility.specs)
        return cls(loads, eligibility.model.reference_point, eligibility.torque_scale, f_max)

    def __call__(self, slots: WrenchSlots) -> LoadFound:
        factors = tuple(load_factor(slots, -w) for w in self.targets)
        weakest = int(np.argmin([f.load_factor for f in factors]))
        u, w = factors[weakest].direction, self.targets[weakest] / self.unit
        found = LoadFactors(tuple(c.name for c in self.loads.cases), factors)
        least = found.load_factor
        return LoadFound(-least * self.unit, u / float(u @ w), least > 0, found)

    def upper_bound(self, slots: WrenchSlots) -> float:
        """The least certified upper bound over the cases on ``slots``, times ``unit``: of
        elements, no placement on them holds more (their wrench set holds every placement's)."""
        return self.unit * min(load_factor(slots, -w).bounds[1] for w in self.targets)

    def directions(self, count: int) -> list:
        """A first working set: ``+-e_k`` and ``count`` pseudo-random directions, each case's
        ``u / u.w`` where ``u.w > 0``."""
        out = []
        for w in self.targets / self.unit:
            unit = w / np.linalg.norm(w)
            U = sphere_samples(count, seed=1)
            dots = U @ unit
            keep = dots > 0.05
            out += list(U[keep] / (dots[keep, None] * np.linalg.norm(w)))
            out.append(unit / np.linalg.norm(w))
        return out
