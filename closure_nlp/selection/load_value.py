"""The least load factor as the selection's value (``objective="loads"``).

The heuristic and iterative algorithms rank element sets by a value, lower better: rho_hat by
default. :class:`LoadValue` gives them instead minus the least load factor of the element set's
wrench set (the Minkowski sum of each element's slot: the same ray-shooting as a contact set's,
:mod:`~closure_nlp.criterion.load_factor`), in the load objective's unit (the largest case over
``f_max``), so the algorithms' descent margin, relative to ``max(1, |value|)``, reads it as it
reads rho_hat. A placement on the elements holds a wrench set inside theirs: the element set's
factor bounds every placement's on it from above.

A set that cannot push against some case at all (a marginal factor, within the bracket's
accuracy of zero) is worth 0, never below, and is not "eligible": so sets that hold nothing tie
at 0, as rho_hat's marginal sets do. The direction that steers the heuristic is the weakest
case's dual direction (the wrench direction its load exhausts): the next element added is the one
reaching furthest along it, as along rho_hat's ``u*``. Every value is certified (both ends of the
bracket), so :meth:`certify` has nothing to add and the light screen is the value itself.
"""

from __future__ import annotations

import time

import numpy as np

from closure_nlp.criterion.rho_hat import Eligibility, EligibilityResult
from closure_nlp.criterion.support_minimum import SolverStats


class LoadValue:
    """Minus the least load factor of element sets of ``eligibility``, by ``objective`` (called
    on an element set's slots; ``rho`` minus the least factor times ``unit``, ``factors`` the
    certified :class:`~closure_nlp.criterion.load_factor.LoadFactors`): e.g.
    :class:`~closure_nlp.placement.load_objective.LoadObjective` on the eligibility's reference
    point, torque scale and largest ``f_max``. Called like the eligibility itself."""

    def __init__(self, eligibility: Eligibility, objective):
        self.eligibility, self.objective = eligibility, objective
        self.unit = float(objective.unit)
        self.evaluations = 0
        self._seen: dict[tuple, EligibilityResult] = {}  # the screen's values, asked again

    def __call__(
        self, elements, warm_start=None, partial: bool = False, certify: bool = True, **_
    ) -> EligibilityResult:
        """The element set's value as an :class:`EligibilityResult` (``rho_hat`` minus its least
        factor times ``unit``, ``bounds`` the bracket's, ``eligible``: every case held)."""
        t0 = time.perf_counter()
        elements = self.eligibility.check_elements(elements, partial=partial)
        if elements in self._seen:
            return self._seen[elements]
        self.evaluations += 1
        factors = self.objective(self.eligibility.slots(elements)).factors
        weakest = min(factors.factors, key=lambda f: f.load_factor)
        marginal = any(f.marginal for f in factors.factors)
        lo, hi = (0.0, 0.0) if marginal else factors.bounds
        stats = SolverStats(
            0, weakest.iterations, "certified", True, time.perf_counter() - t0, "load_factor"
        )
        self._seen[elements] = EligibilityResult(
            elements,
            -lo * self.unit,
            lo > 0 and not marginal,
            np.asarray(weakest.direction, float),
            stats,
            bounds=(-hi * self.unit, -lo * self.unit),
            marginal=marginal,
            converged=all(f.converged for f in factors.factors),
        )
        return self._seen[elements]

    def certify(self, result: EligibilityResult) -> EligibilityResult:
        return result

    def light(self, elements, warm, stop_below=None):
        """The screen's value and direction: the value itself (never above it)."""
        found = self(elements, warm)
        return found.rho_hat, found.direction

    def factor(self, value: float) -> float:
        """The least load factor a value stands for."""
        return -value / self.unit if value else 0.0
