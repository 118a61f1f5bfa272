"""A minimum distance between contacts (new or fixed): which pairs of contacts can come closer
than it on their elements, whether a placement keeps it, and why it cannot be kept.

Contacts are indexed as in a placement's contact set: the fixed ones first, then one per
element. A pair needs a constraint only when its two elements' bounding boxes lie closer than
the distance (a lower bound of the elements' own distance: never a pair missed); it cannot be
kept when the two elements lie wholly within the distance of each other (their farthest
vertices closer than it).
"""

from __future__ import annotations

import numpy as np

from closure_nlp.base.errors import MethodError
from closure_nlp.model.elements import part_size

# Relative share of the distance a placement may fall short of it by (the NLP keeps it to its
# constraint tolerance, far below): closer than this, the distance is not kept.
KEPT_SHARE = 1e-6


class SpacingError(MethodError):
    """No placement found on the elements keeps the minimum spacing."""


class Spacing:
    """The spacing ``distance`` (model units, > 0) of contacts on ``elements`` of
    ``eligibility`` (with its fixed contacts).

    Attributes
    ----------
    pairs : tuple of (int, int)
        The pairs of contacts that can come closer than the distance (fixed pairs excluded:
        they never move).
    length : float
        The part's size: positions enter the NLP over it.
    """

    def __init__(self, eligibility, elements, distance: float):
        model = eligibility.model
        self.distance = float(distance)
        self.length = part_size(model.elements)
        fixed = [e.vertices for e in eligibility.fixed.elements]
        self.vertices = fixed + [model.elements[e].vertices for e in elements]
        self.fixed = len(fixed)
        lows = [v.min(axis=0) for v in self.vertices]
        highs = [v.max(axis=0) for v in self.vertices]
        pairs = []
        for j in range(self.fixed, len(self.vertices)):
            for i in range(j):
                gap = np.maximum(0.0, np.maximum(lows[i] - highs[j], lows[j] - highs[i]))
                if float(np.linalg.norm(gap)) < self.distance:
                    pairs.append((i, j))
        self.pairs = tuple(pairs)

    def impossible(self) -> str | None:
        """Why no placement on the elements keeps the distance (a pair's elements wholly
        within it of each other), or None."""
        for i, j in self.pairs:
            a, b = self.vertices[i], self.vertices[j]
            farthest = float(np.max(np.linalg.norm(a[:, None] - b[None], axis=2)))
            if farthest < self.distance:
                return (
                    f"{self._name(i)} and {self._name(j)} are at most {farthest:.6g} apart "
                    f"wherever they sit, less than the minimum spacing {self.distance:g}"
                )
        return None

    def closest(self, positions) -> tuple[int, int, float]:
        """The pair of ``positions`` (one per contact, fixed first) closest together of those
        that can come closer than the distance, and their distance (inf without pairs)."""
        x = np.asarray(positions, float)
        best = (-1, -1, np.inf)
        for i, j in self.pairs:
            d = float(np.linalg.norm(x[i] - x[j]))
            if d < best[2]:
                best = (i, j, d)
        return best

    def kept(self, positions) -> bool:
        return self.closest(positions)[2] >= self.distance * (1.0 - KEPT_SHARE)

    def check(self, positions) -> None:
        """``MethodError`` saying which contacts are too close when ``positions`` do not keep
        the distance."""
        i, j, d = self.closest(positions)
        if d < self.distance * (1.0 - KEPT_SHARE):
            raise SpacingError(
                f"min_spacing: no placement found that keeps {self.distance:g}: "
                f"{self._name(i)} and {self._name(j)} end {d:.6g} apart"
            )

    def _name(self, i: int) -> str:
        if i < self.fixed:
            return f"fixed contact {i}"
        return f"contact {i - self.fixed}"


def check_fixed_spacing(eligibility, distance: float) -> None:
    """``ValueError`` when two fixed contacts lie closer than ``distance`` (nothing can move
    them apart)."""
    x = eligibility.fixed.positions
    for j in range(len(x)):
        for i in range(j):
            d = float(np.linalg.norm(x[i] - x[j]))
            if d < distance * (1.0 - KEPT_SHARE):
                raise ValueError(
                    f"min_spacing: fixed contacts {i} and {j} are {d:.6g} apart, closer than "
                    f"{distance:g}"
                )


__all__ = ["KEPT_SHARE", "Spacing", "SpacingError", "check_fixed_spacing"]
