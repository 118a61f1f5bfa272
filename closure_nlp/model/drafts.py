"""Elements on their way to a model, and the thinning of points and rulings to a spacing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from closure_nlp.model.elements import Element


@dataclass
class Draft:
    """An element on its way to the model, with the mesh vertices it stands for."""

    element: Element
    owned: set[int]
    region: int  # index of the curved patch a segment or point belongs to; -1 for facets


def thin(points: np.ndarray, spacing: float | None, order=None) -> list[int]:
    """Greedy Poisson-disc thinning: ids (ascending) of points kept at least ``spacing`` apart.

    Points are taken in ``order`` (default: as given); one is kept unless a point kept before it
    lies closer than ``spacing``. Equivalently, and so it runs: the first point not yet ruled
    out is kept and rules out every later point within ``spacing`` of it (one k-d tree query per
    kept point: O(n log n + kept x neighbours), where a loop over points was O(n) Python steps).
    """
    from scipy.spatial import cKDTree

    if spacing is None or spacing <= 0 or len(points) == 0:  # keep all, but once each
        return sorted(np.unique(points, axis=0, return_index=True)[1].tolist())
    points = np.asarray(points, dtype=float)
    order = np.arange(len(points)) if order is None else np.asarray(order)
    rank = np.empty(len(points), dtype=np.int64)
    rank[order] = np.arange(len(order))
    tree = cKDTree(points)
    flags = bytearray(len(order))  # by rank: 1 once ruled out (bytes.find scans at C speed)
    out = np.frombuffer(flags, dtype=np.uint8)
    kept = []
    k = flags.find(0)
    while k >= 0:
        i = int(order[k])
        kept.append(i)
        near = np.asarray(tree.query_ball_point(points[i], spacing), dtype=np.int64)
        # Strictly closer than spacing (the ball query includes its boundary).
        near = near[np.linalg.norm(points[near] - points[i], axis=1) < spacing]
        out[rank[near]] = 1
        out[k] = 1
        k = flags.find(0, k)
    return sorted(kept)
