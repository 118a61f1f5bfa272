"""Placement with its certified ceiling: the exchange method's placement, then the ceiling
that bounds every placement on the same elements (and may find a better one)."""

from __future__ import annotations

import time

from closure_nlp.base.progress import Progress
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.placement.ceiling import bounded
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.placer import ExchangePlacer
from closure_nlp.placement.result import PlacementResult


class Placer(ExchangePlacer):
    """:class:`~closure_nlp.placement.placer.ExchangePlacer` whose answers carry the certified
    ceiling when the options ask for one (``bound``)."""

    def __call__(
        self, elements, weights=None, progress: Progress | None = None, ceiling: bool = True
    ) -> PlacementResult:
        """As the exchange placer; ``ceiling=False`` skips the certified ceiling even when the
        options ask for one (a plan computes it once, for the placement it returns)."""
        t0 = time.perf_counter()
        result = super().__call__(elements, weights, progress)
        if not (self.options.bound and ceiling) or self.objective is not None:
            return result  # the ceiling bounds rho, not load factors
        start = tuple(self.eligibility.check_elements(elements))
        return bounded(self, start, result, t0, progress)


def place(
    eligibility: Eligibility,
    elements,
    weights=None,
    options: PlacementOptions = PlacementOptions(),
    loads=None,
) -> PlacementResult:
    """Place one contact on each of ``elements`` (and their neighbours) for the best rho, or,
    with ``loads`` (a LOADS.json's cases, :func:`closure_nlp.load_loads`), for the largest least
    load factor (no certified ceiling then: it bounds rho)."""
    return Placer(eligibility, options, loads=loads)(elements, weights)
