"""Choices among equal values that round-off cannot flip.

The same part in metres and in millimetres gives grasp matrices equal only to round-off (a
factor of 1000 is not exact in binary), so a choice among values equal in exact arithmetic (a
symmetric part's equally weak directions, contacts on one facet pushing alike) would fall one
way in one unit and the other way in the other, and a local method would then follow two
different paths. Values within ``TIE`` of each other, relative to the scale of the data, count
as equal here, and equal values are taken in index order.
"""

from __future__ import annotations

import numpy as np

# Relative width of a tie: far above round-off (1e-16 of the scale, amplified by a few
# operations), far below any difference a placement cares about.
TIE = 1e-9


def first_largest(values: np.ndarray, scale: float, axis: int = -1) -> np.ndarray:
    """Index of the first entry along ``axis`` within ``TIE * scale`` of the largest: ``values``
    (..., n) -> (...) int (``np.argmax`` with ties at the scale of the data)."""
    values = np.asarray(values, dtype=float)
    top = values.max(axis=axis, keepdims=True)
    return np.argmax(values >= top - TIE * scale, axis=axis)


def lowest_first(values: np.ndarray, scale: float, count: int) -> np.ndarray:
    """Indices of the ``count`` smallest of ``values`` (n,), smallest first, entries within
    ``TIE * scale`` of each other taken in index order: (min(count, n),) int."""
    values = np.asarray(values, dtype=float)
    left = np.ones(len(values), dtype=bool)
    chosen = []
    for _ in range(min(count, len(values))):
        low = values[left].min()
        i = int(np.argmax(left & (values <= low + TIE * scale)))
        chosen.append(i)
        left[i] = False
    return np.array(chosen, dtype=int)


__all__ = ["TIE", "first_largest", "lowest_first"]
