"""A model's own mesh: read for drawing (a missing or broken one is one warning, not an error),
and used to check that facet and segment normals point into the part.

The mesh is a drawing aid (docs/formats.md), so only a mesh path that leaves the model's folder
(:attr:`Model.mesh_path`) and a normal that points out of the mesh are errors.
"""

from __future__ import annotations

import warnings

import numpy as np

from closure_nlp.model.elements import ElementKind, Model
from closure_nlp.model.meshes import read_mesh


def read_model_mesh(model: Model):
    """The model's mesh as a ``trimesh.Trimesh``, or None: when the model names none, or (with one
    warning) when the file is missing or not a mesh. A path outside the model's folder raises."""
    path = model.mesh_path
    if path is None:
        return None
    try:
        return read_mesh(path, f"mesh {model.mesh!r} of model {model.name!r}")
    except ValueError as exc:
        warnings.warn(f"{exc}; drawn without it", stacklevel=2)
        return None


def check_normals(model: Model, mesh, source: str | None = None, neighbours: int = 16) -> None:
    """Refuse a facet or segment whose inward normal points out of ``mesh``
    (:func:`outward_elements` says which).

    Raises
    ------
    ValueError
        Naming the first such element, e.g. ``elements[3].inward_normal: points out of the
        model's mesh``, and how many there are when there are several.
    """
    bad = outward_elements(model, mesh, neighbours)
    if bad:
        where = f"{source}: " if source else ""
        more = f" (and {len(bad) - 1} more: {_ids_text(bad[1:])})" if len(bad) > 1 else ""
        raise ValueError(
            f"{where}elements[{bad[0]}].inward_normal: points out of the model's mesh "
            f"({model.mesh}){more}; inward normals point into the part"
        )


def _ids_text(ids, limit: int = 10) -> str:
    shown = ", ".join(str(i) for i in ids[:limit])
    return shown + (", ..." if len(ids) > limit else "")


def outward_elements(model: Model, mesh, neighbours: int = 16) -> tuple[int, ...]:
    """Ids of the facets and segments whose inward normal points out of ``mesh``, ascending.

    The mesh faces an element lies on give its outward direction: faces around the mesh vertices
    that coincide with the element's vertices (``characterize`` builds elements from them), and
    faces touching its centroid (candidates from a k-d tree of face centroids), within 1e-6 of
    the part's size, kept when nearly parallel to the element (|cos| > 0.7, which leaves out the
    caps at a segment's ends). An inward normal within 60 degrees of their area-weighted outward
    normal is wrong. All in O((n + F) log F). Elements on no face of this mesh, and meshes that
    are not closed and consistently wound, are not judged.

    Parameters
    ----------
    model : Model
    mesh : trimesh.Trimesh or None
        None judges nothing.
    neighbours : int
        Face centroids tried per element centroid.

    Returns
    -------
    ids : tuple of int
    """
    import trimesh
    from scipy.spatial import cKDTree

    if mesh is None or not (mesh.is_watertight and mesh.is_winding_consistent):
        return ()
    ids = [i for i, e in enumerate(model.elements) if e.kind is not ElementKind.POINT]
    if not ids:
        return ()
    sign = 1.0 if mesh.volume > 0 else -1.0  # outward-wound (as trimesh reads most files)
    triangles = np.asarray(mesh.triangles)
    normals = sign * np.asarray(mesh.face_normals)
    areas = np.asarray(mesh.area_faces)
    tol = 1e-6 * float(np.ptp(mesh.vertices, axis=0).max())
    vertex_faces = np.asarray(mesh.vertex_faces)  # (V, d), padded with -1
    vertex_tree = cKDTree(mesh.vertices)
    k = min(neighbours, len(triangles))
    centroids = np.array([model.elements[i].centroid for i in ids])
    _, near = cKDTree(triangles.mean(axis=1)).query(centroids, k=k)
    near = np.asarray(near).reshape(len(ids), k)
    closest = trimesh.triangles.closest_point(
        triangles[near.ravel()], np.repeat(centroids, k, axis=0)
    ).reshape(len(ids), k, 3)
    touching = np.linalg.norm(closest - centroids[:, None, :], axis=2) <= tol
    bad = []
    for row, i in enumerate(ids):
        element = model.elements[i]
        distance, vertex = vertex_tree.query(element.vertices)
        around = vertex_faces[vertex[distance <= tol]].ravel()
        faces = np.union1d(around[around >= 0], near[row][touching[row]])
        faces = faces[np.abs(normals[faces] @ element.inward_normal) > 0.7]
        outward = (areas[faces, None] * normals[faces]).sum(axis=0)
        length = float(np.linalg.norm(outward))
        if length > 0 and float(element.inward_normal @ outward) > 0.5 * length:
            bad.append(i)
    return tuple(bad)


__all__ = ["check_normals", "outward_elements", "read_model_mesh"]
