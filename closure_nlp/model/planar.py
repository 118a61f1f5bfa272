"""Convex facets of a planar patch (paper section 2.1): the patch's triangles, retriangulated
from its boundary, are merged greedily into convex polygons (Hertel-Mehlhorn)."""

from __future__ import annotations

import numpy as np

from closure_nlp.model.drafts import Draft
from closure_nlp.model.elements import Element, ElementKind
from closure_nlp.model.meshes import simple_loops


def facets(mesh, faces: np.ndarray) -> list[Draft]:
    """Convex facets covering one planar patch (faces: (k,) int)."""
    areas = mesh.area_faces[faces]
    # Twice the area-weighted normal, from the triangles themselves: trimesh gives a zero normal
    # to a triangle whose area is below its absolute tolerance, however large the part.
    tri = mesh.triangles[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(0)
    length = float(np.linalg.norm(normal))
    if not length > 0:
        return []  # a patch of zero-area slivers
    normal /= length
    centre = (mesh.triangles_center[faces] * areas[:, None]).sum(0) / areas.sum()
    # The patch's own vertices, numbered 0..k-1 here (the mesh's ids: ``ids``): the work is
    # linear in the patch's size, not the mesh's.
    ids, local = np.unique(mesh.faces[faces], return_inverse=True)
    verts = mesh.vertices[ids]
    flat = verts - np.outer((verts - centre) @ normal, normal)  # onto the plane
    frame = _plane_frame(normal)
    xy = (flat - centre) @ frame
    triangles = _remove_interior_vertices(local.reshape(-1, 3), xy)
    drafts = []
    for loop, owned in _convex_pieces(triangles, xy):
        loop = _drop_straight(loop, xy)
        if _area(xy[loop]) <= 1e-9 * areas.sum():
            continue  # a sliver left by collinear boundary vertices
        try:
            element = Element(ElementKind.FACET, flat[loop], -normal)
        except ValueError:
            continue  # a sliver too thin to be a facet (boolean unions leave some)
        drafts.append(Draft(element, {int(ids[v]) for v in owned}, -1))
    return drafts


def _plane_frame(normal: np.ndarray) -> np.ndarray:
    """(3, 2) float: orthonormal in-plane axes with ``x, y, normal`` right-handed."""
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(normal)))] = 1.0
    x = np.cross(helper, normal)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(normal, x)])


def _area(xy: np.ndarray) -> float:
    """Signed area of a polygon (k, 2), positive when counter-clockwise."""
    x, y = xy[:, 0], xy[:, 1]
    return float(0.5 * (x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def _remove_interior_vertices(triangles: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Retriangulate a planar patch (t, 3) from its boundary alone (mapbox_earcut, holes
    included), so that convex merging is not blocked by a vertex no piece can drop.

    The patch's triangles are kept as they are when its boundary is not simple loops (a vertex
    where two boundary loops touch) or the triangulation does not cover the same area.
    """
    import mapbox_earcut

    directed = np.vstack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = directed[counts[inverse.ravel()] == 1]
    loops = simple_loops(boundary)
    if not loops or len(np.unique(boundary[:, 0])) == len(np.unique(triangles)):
        return triangles  # no interior vertex (or a boundary that is not simple loops)
    areas = [_area(xy[loop]) for loop in loops]
    outer = int(np.argmax(areas))
    if areas[outer] <= 0 or sum(a > 0 for a in areas) != 1:
        return triangles
    rings = [loops[outer]] + [loop for k, loop in enumerate(loops) if k != outer]
    ids = np.concatenate(rings)
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    local = np.asarray(mapbox_earcut.triangulate_float64(xy[ids], ends), dtype=np.int64)
    out = ids[local.reshape(-1, 3)]
    if len(out) == 0:
        return triangles
    signed = np.array([_area(xy[t]) for t in out])
    out[signed < 0] = out[signed < 0][:, ::-1]  # counter-clockwise, like the patch's faces
    total = sum(_area(xy[t]) for t in triangles)
    if not np.isclose(np.abs(signed).sum(), total, rtol=1e-9, atol=0.0):
        return triangles  # earcut did not cover the patch (a boundary it reads differently)
    return out


def _convex_pieces(triangles: np.ndarray, xy: np.ndarray) -> list[tuple[list[int], set[int]]]:
    """Merge counter-clockwise triangles (t, 3) into convex polygons (Hertel-Mehlhorn).

    Returns a list of (vertex loop, vertex ids of the merged triangles).
    """
    parent = list(range(len(triangles)))
    loops = {i: [int(v) for v in tri] for i, tri in enumerate(triangles)}
    owned = {i: set(loops[i]) for i in loops}

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    edge_face = {}
    for f, tri in enumerate(triangles.tolist()):
        for k in range(3):
            edge_face[(tri[k], tri[(k + 1) % 3])] = f
    shared = [(a, b) for (a, b) in edge_face if a < b and (b, a) in edge_face]
    shared.sort(key=lambda e: -float(np.linalg.norm(xy[e[0]] - xy[e[1]])))
    for a, b in shared:
        p, q = find(edge_face[(a, b)]), find(edge_face[(b, a)])
        if p == q:
            continue
        merged = _merge_loops(loops[p], loops[q], a, b)
        if merged is None or not _is_convex(xy[merged]):
            continue
        parent[q] = p
        loops[p] = merged
        owned[p] |= owned.pop(q)
        del loops[q]
    return [(loops[i], owned[i]) for i in sorted(loops)]


def _merge_loops(p: list[int], q: list[int], a: int, b: int) -> list[int] | None:
    """Union of loop ``p`` (with edge a->b) and loop ``q`` (with edge b->a) across that edge."""
    try:
        i, j = p.index(b), q.index(a)
    except ValueError:
        return None
    p_rot = p[i:] + p[:i]  # b ... a
    q_rot = q[j:] + q[:j]  # a ... b
    if p_rot[-1] != a or q_rot[-1] != b:
        return None
    merged = p_rot + q_rot[1:-1]
    return merged if len(set(merged)) == len(merged) else None


def _is_convex(xy: np.ndarray, eps: float = 1e-9) -> bool:
    """Whether the counter-clockwise polygon (k, 2) is convex (straight corners allowed)."""
    edges = np.roll(xy, -1, axis=0) - xy
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    scale = np.linalg.norm(edges, axis=1) * np.linalg.norm(nxt, axis=1)
    return bool(np.all(cross >= -eps * scale))


def _drop_straight(loop: list[int], xy: np.ndarray, eps: float = 1e-9) -> list[int]:
    """Remove corners where the boundary goes straight on."""
    keep = []
    k = len(loop)
    for i in range(k):
        u = xy[loop[i]] - xy[loop[i - 1]]
        w = xy[loop[(i + 1) % k]] - xy[loop[i]]
        cross = u[0] * w[1] - u[1] * w[0]
        if abs(cross) > eps * np.linalg.norm(u) * np.linalg.norm(w) or u @ w < 0:
            keep.append(loop[i])
    return keep if len(keep) >= 3 else loop
