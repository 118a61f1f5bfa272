"""Small element models built in code for tests: a box and random elements of every kind."""

from __future__ import annotations

import numpy as np

from closure_nlp.model.elements import Element, Model


def box_facets(half=1.0) -> list[Element]:
    """The six faces of a box of half-sides ``half`` (a number: a cube; or 3 numbers), as
    square facets with inward normals, in the order -x, +x, -y, +y, -z, +z."""
    half = np.broadcast_to(np.asarray(half, float), 3)
    elements = []
    for axis in range(3):
        others = [k for k in range(3) if k != axis]
        for sign in (-1.0, 1.0):
            corners = []
            for p, q in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
                v = np.zeros(3)
                v[axis], v[others[0]], v[others[1]] = sign, p, q
                corners.append(v * half)
            normal = np.zeros(3)
            normal[axis] = -sign
            elements.append(Element("facet", corners, normal, name=f"elements[{len(elements)}]"))
    return elements


def box_model(half: float = 1.0) -> Model:
    """A cube of side ``2 * half``: 6 square facets, neighbours across its 12 edges."""
    adjacency = [(i, j) for i in range(6) for j in range(i + 1, 6) if i // 2 != j // 2]
    return Model(tuple(box_facets(half)), tuple(adjacency), "box", "")


def corner_model(half: float = 1.0) -> Model:
    """Three facets of the box meeting at one corner (normals +x, +y, +z): no set of contacts
    on it is force closure or eligible, whatever their number, since none pushes along -x."""
    box = box_model(half)
    elements = tuple(box.elements[i] for i in (0, 2, 4))
    return Model(elements, ((0, 1), (0, 2), (1, 2)), "corner", "")


def random_element(rng, kind: str, radius: float = 1.0) -> Element:
    """An element near the sphere of ``radius``, its normal pointing roughly at the centre."""
    centre = rng.standard_normal(3)
    centre *= radius / np.linalg.norm(centre)
    normal = -centre / radius + 0.3 * rng.standard_normal(3)
    normal /= np.linalg.norm(normal)
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    a = np.cross(normal, helper)
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    size = 0.2 * radius
    if kind == "point":
        vertices = [centre]
    elif kind == "segment":
        vertices = [centre - size * a, centre + size * a]
    else:
        k = int(rng.integers(3, 7))
        angles = np.sort(rng.uniform(0, 2 * np.pi, k))
        angles = 2 * np.pi * np.arange(k) / k + 0.3 * (angles - angles.mean()) / k
        vertices = [centre + size * (np.cos(t) * a + np.sin(t) * b) for t in angles]
    return Element(kind, vertices, normal)


def random_model(rng, kinds) -> Model:
    """One random element of each kind in ``kinds``, no adjacency."""
    return Model(tuple(random_element(rng, k) for k in kinds), (), "random")


# Load cases on the lamp (models/lamp.model.json, mm): its weight below the centre, a side push
# above it and a twist about its axis.
LAMP_LOADS = {
    "units": {"force": "N"},
    "loads": [
        {"name": "gravity", "force": [0, 0, -1], "point": [0, 0, -20]},
        {"name": "push_x", "force": [0.5, 0, 0], "point": [0, 0, 10]},
        {"name": "twist", "force": [0, 0, 0], "torque": [0, 0, 5]},
    ],
}
