"""Elements on their way to a model, and the thinning of points and rulings to a spacing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elements import Element


@dataclass
class Draft:
    """An element on its way to the model, with the mesh vertices it stands for."""

    element: Element
    owned: set[int]
    region: int  # index of the curved patch a segment or point belongs to; -1 for facets


def thin(points: np.ndarray, spacing: float | None, order=None) -> list[int]:
    """Greedy Poisson-disc thinning: ids (ascending) of points kept at least ``spacing`` apart."""
    if spacing is None or spacing <= 0 or len(points) == 0:  # keep all, but once each
        return sorted(np.unique(points, axis=0, return_index=True)[1].tolist())
    order = np.arange(len(points)) if order is None else order
    cells: dict[tuple[int, ...], list[int]] = {}
    kept = []
    for i in order:
        cell = tuple(np.floor(points[i] / spacing).astype(int))
        near = (
            j
            for dx in (-1, 0, 1)
            for dy in (-1, 0, 1)
            for dz in (-1, 0, 1)
            for j in cells.get((cell[0] + dx, cell[1] + dy, cell[2] + dz), ())
        )
        if any(np.linalg.norm(points[j] - points[i]) < spacing for j in near):
            continue
        cells.setdefault(cell, []).append(int(i))
        kept.append(int(i))
    return sorted(kept)
