"""Contacts a fingertip can hold: every contact at least a margin D from its element's boundary.

A facet shrinks inward (each edge moved in by D within the facet's plane: the polygon of points
at least D from every edge line, which for a convex polygon is the set of its points at least D
from its boundary); a segment is shortened by D at both ends; a point has no boundary and stays.
An element too small for D (nothing left, or a sliver thinner than the geometry tolerance) is
left out and named. The shrunk elements keep their ids, normals and neighbours, so selection,
placement and the certified ceiling all work on the usable region alone.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from closure_nlp.model.elements import Element, ElementKind, Model


def shrunk(element: Element, margin: float) -> Element | None:
    """``element`` with every point closer than ``margin`` to its boundary removed, or None
    when nothing (of positive size) is left."""
    if margin == 0.0 or element.kind is ElementKind.POINT:
        return element
    v = element.vertices
    if element.kind is ElementKind.SEGMENT:
        length = float(np.linalg.norm(v[1] - v[0]))
        if length <= 2.0 * margin * (1.0 + 1e-9):
            return None
        step = (v[1] - v[0]) * (margin / length)
        return replace(element, vertices=np.array([v[0] + step, v[1] - step]))
    n = element.inward_normal
    centre = v.mean(axis=0)
    lines = []  # (point on the moved edge, edge direction), in order
    for j in range(len(v)):
        a, b = v[j], v[(j + 1) % len(v)]
        d = (b - a) / np.linalg.norm(b - a)
        inside = np.cross(n, d)
        if inside @ (centre - a) < 0:
            inside = -inside
        lines.append((a + margin * inside, d, inside))
    points = []
    for j in range(len(lines)):
        (p, d, _), (q, e, _) = lines[j - 1], lines[j]
        # p + s d = q + t e within the plane: least squares on the two directions
        st, *_ = np.linalg.lstsq(np.column_stack([d, -e]), q - p, rcond=None)
        points.append(p + st[0] * d)
    points = np.array(points)
    # a vertex of the offset polygon must be at least margin inside every edge (else an edge
    # vanished: the polygon is too small, or the offset changed its combinatorics)
    size = max(element.size, 1e-300)
    for p, _, inside in lines:
        if np.any((points - p) @ inside < -1e-9 * size):
            return None
    area = 0.5 * np.linalg.norm(
        sum(np.cross(points[j], points[(j + 1) % len(points)]) for j in range(len(points)))
    )
    if area <= (1e-6 * size) ** 2:
        return None
    try:
        return replace(element, vertices=points)
    except ValueError:  # degenerate after the offset (the element's own checks)
        return None


def with_margin(model: Model, margin: float) -> tuple[Model, tuple[int, ...]]:
    """``model`` with every element shrunk by ``margin`` (model units), and the ids of the
    elements too small for it (kept as they are, and marked ``unusable``: no contact may use
    them, selection never picks them, they are nobody's neighbour)."""
    if isinstance(margin, bool) or not isinstance(margin, (int, float)):
        raise TypeError(f"margin: expected a length, got {margin!r}")
    if not (0.0 <= margin < np.inf):
        raise ValueError(f"margin: expected a length >= 0, got {margin!r}")
    elements, dropped = [], []
    for i, e in enumerate(model.elements):
        s = shrunk(e, float(margin))
        if s is None:
            dropped.append(i)
            s = e
        elements.append(s)
    unusable = tuple(sorted(set(model.unusable) | set(dropped)))
    return replace(model, elements=tuple(elements), unusable=unusable), tuple(dropped)


def on_original(result, model: Model):
    """A placement made on the shrunk model with each contact's weights on its element in
    ``model`` (the file's element): the same positions."""
    from closure_nlp.model.elements import nearest_weights

    contacts = tuple(
        replace(c, weights=nearest_weights(model.elements[c.element].vertices, c.position))
        for c in result.contacts
    )
    return replace(result, contacts=contacts)


__all__ = ["on_original", "shrunk", "with_margin"]
