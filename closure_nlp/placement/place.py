"""Placement with its certified ceiling: the exchange method's placement, then the ceiling
that bounds every placement on the same elements (and may find a better one)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from closure_nlp.base.progress import Progress
from closure_nlp.contact.wrenches import WrenchSlots
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
        if weights is None and self.objective is not None:
            elements, weights = self._holding_start(elements, progress)
        result = super().__call__(elements, weights, progress)
        if self.objective is not None:  # the ceiling bounds rho, not load factors
            return dataclasses.replace(result, seconds=time.perf_counter() - t0)
        if not (self.options.bound and ceiling):
            return result
        start = tuple(self.eligibility.check_elements(elements))
        return bounded(self, start, result, t0, progress)

    def _holding_start(self, elements, progress):
        """Where the load exchange starts: the element centroids, or, when they hold some case
        not at all, the rho placement on the same elements: the least factor is 0 all around
        such a start, so the exchange would have no direction to go, and a force-closure
        placement holds every case some (the exchange then never ends below it)."""
        ids = list(self.eligibility.check_elements(elements))
        vertices = [len(self.eligibility.model.elements[e].vertices) for e in ids]
        centroids = [np.full(k, 1.0 / k) for k in vertices]
        slots = WrenchSlots.from_contacts(self.contact_set(ids, centroids))
        if self.objective(slots).force_closure:
            return ids, centroids
        placed = ExchangePlacer(self.eligibility, self.options, self._caches)(ids, None, progress)
        return list(placed.elements), [c.weights for c in placed.contacts]


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
