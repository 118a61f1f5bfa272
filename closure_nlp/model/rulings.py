"""Line segments of a ruled patch (paper section 2.2): the rulings of a cylinder or a circular
cone, the mesh edges along its axis or through its apex, merged when collinear and thinned."""

from __future__ import annotations

import numpy as np

from closure_nlp.model.drafts import Draft, thin
from closure_nlp.model.elements import Element, ElementKind


def rulings(mesh, faces: np.ndarray, tol: float) -> list[np.ndarray] | None:
    """Rulings of a cylindrical or circular-conical patch, or None if it is not one.

    Returns
    -------
    rulings : list of (k,) int
        Each a chain of mesh vertices along one straight ruling, in order.
    """
    normals = mesh.face_normals[faces]
    axis, offset, residual = _normal_circle(normals)
    if residual > np.sin(tol):
        return None
    edges = _patch_edges(mesh, faces)
    a, b = mesh.vertices[edges[:, 0]], mesh.vertices[edges[:, 1]]
    d = b - a
    length = np.linalg.norm(d, axis=1)
    d = d / length[:, None]
    if abs(offset) < np.sin(tol):  # cylinder: rulings parallel to the axis
        along = np.abs(d @ axis) > np.cos(tol)
    else:  # cone: rulings through the apex
        apex = _apex(mesh, faces)
        if apex is None:
            return None
        to_apex = apex - a
        off = np.linalg.norm(np.cross(to_apex, d), axis=1)
        along = off < np.tan(tol) * np.maximum(np.linalg.norm(to_apex, axis=1), length)
    ruling_edges = edges[along]
    if not _faces_with_edge(mesh.faces[faces], ruling_edges).all():
        return None
    return _chains(mesh.vertices, ruling_edges, tol)


def _normal_circle(normals: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Fit ``n . axis = offset`` to unit normals (k, 3): a circle on the Gauss sphere."""
    centre = normals.mean(axis=0)
    _, sing, vt = np.linalg.svd(normals - centre, full_matrices=False)  # (k, 3): no k x k U
    axis = vt[2]
    offset = float(centre @ axis)
    residual = float(np.abs(normals @ axis - offset).max())
    if sing[1] < 1e-9:  # all normals on one line: a plane, not a ruled curved patch
        return axis, offset, np.inf
    return axis, offset, residual


def _apex(mesh, faces: np.ndarray) -> np.ndarray | None:
    """Least-squares common point of the faces' planes (the cone's apex)."""
    n = mesh.face_normals[faces]
    rhs = (n * mesh.triangles_center[faces]).sum(1)
    sol, _, rank, _ = np.linalg.lstsq(n, rhs, rcond=None)
    return sol if rank == 3 else None


def _patch_edges(mesh, faces: np.ndarray) -> np.ndarray:
    """(e, 2) int: unique undirected edges of the faces."""
    tri = mesh.faces[faces]
    edges = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return np.unique(np.sort(edges, axis=1), axis=0)


def _faces_with_edge(tri: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(t,) bool: whether each triangle (t, 3) has one of the undirected ``edges`` (e, 2)."""
    keys = {(int(a), int(b)) for a, b in np.sort(edges, axis=1)}
    hit = np.zeros(len(tri), bool)
    for i, (x, y, z) in enumerate(tri.tolist()):
        for a, b in ((x, y), (y, z), (z, x)):
            if (min(a, b), max(a, b)) in keys:
                hit[i] = True
                break
    return hit


def _chains(vertices: np.ndarray, edges: np.ndarray, tol: float) -> list[np.ndarray]:
    """Join collinear edges (e, 2) that share a vertex into chains of vertices."""
    parent = list(range(len(edges)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    d = vertices[edges[:, 1]] - vertices[edges[:, 0]]
    d /= np.linalg.norm(d, axis=1)[:, None]
    at_vertex: dict[int, list[int]] = {}
    for k, (a, b) in enumerate(edges.tolist()):
        at_vertex.setdefault(a, []).append(k)
        at_vertex.setdefault(b, []).append(k)
    for ks in at_vertex.values():
        for i in ks:
            for j in ks:
                if i < j and abs(d[i] @ d[j]) > np.cos(tol):
                    parent[find(j)] = find(i)
    groups: dict[int, set[int]] = {}
    for k, (a, b) in enumerate(edges.tolist()):
        groups.setdefault(find(k), set()).update((a, b))
    chains = []
    for ids in groups.values():
        ids = np.array(sorted(ids))
        pts = vertices[ids]
        direction = pts[np.argmax(np.linalg.norm(pts - pts[0], axis=1))] - pts[0]
        chains.append(ids[np.argsort((pts - pts[0]) @ direction)])
    return chains


def segments(mesh, faces, rulings, region, spacing) -> list[Draft]:
    """One segment per ruling (thinned to ``spacing``), normal from the faces along it."""
    verts = mesh.vertices
    face_set = set(faces.tolist())
    vertex_faces = mesh.vertex_faces
    uses = np.bincount(np.concatenate(rulings), minlength=len(verts))
    drafts: list[Draft] = []
    for chain in rulings:
        ends = verts[[chain[0], chain[-1]]]
        direction = (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0])
        touching = {f for v in chain for f in vertex_faces[v] if f >= 0 and f in face_set}
        near = [f for f in touching if sum(v in chain for v in mesh.faces[f]) >= 2]
        outward = mesh.face_normals[near or list(touching)].sum(axis=0)
        outward -= (outward @ direction) * direction
        element = Element(ElementKind.SEGMENT, ends, -outward)
        owned = {int(v) for v in chain if uses[v] <= 2}  # not a cone's apex, shared by all
        drafts.append(Draft(element, owned or {int(chain[-1])}, region))
    midpoints = np.array([d.element.centroid for d in drafts])
    keep = thin(midpoints, spacing, _ruling_order(midpoints))
    return [drafts[i] for i in keep]


def _ruling_order(midpoints: np.ndarray) -> np.ndarray:
    """Order rulings by angle around their common centre (so thinning keeps every k-th)."""
    centred = midpoints - midpoints.mean(axis=0)
    if len(midpoints) < 3:
        return np.arange(len(midpoints))
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    xy = centred @ vt[:2].T
    return np.argsort(np.arctan2(xy[:, 1], xy[:, 0]), kind="stable")
