"""Closed part surfaces from meshes as datasets ship them.

Robotics datasets ship open handles glued into bodies, convex decompositions (VHACD pieces that
overlap or touch face to face), texture seams and stray triangles. :func:`repair_mesh` makes one
closed, consistently wound surface with outward normals, or says why it cannot:

1. the mesh with its vertices merged, when that is closed (most files);
2. else its bodies: connected pieces, each closed on its own once its holes of any size are
   filled (trimesh's repair for 3-4 edges, an ear-cut cap of the hole's boundary for larger
   ones, kept only when the piece is then closed and consistently wound); stray open sheets
   with almost no area are dropped;
3. several closed bodies are merged by a boolean union (manifold3d), so no element lies inside
   the part. Bodies that stay apart after the union (200 separate boxes in one file) are one
   part only when the caller says so (``merge_bodies``): a file of several objects is refused,
   naming how many there are.

Every repair is described in the ``repairs`` list the caller passes. Every threshold (merging
vertices, degenerate triangles) is relative to the part's size: the repairs run on a copy moved
and scaled to unit size, and the result is scaled back, so the same part at 1e-3, 1 and 1e11
is repaired alike.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from closure_nlp.base.files import MAX_MESH_BYTES, check_input
from closure_nlp.base.validation import MAX_COORDINATE

STRAY_AREA = 1e-3  # an open piece with less than this share of the area is dropped as debris
# A body at unit size (the repairs run there) enclosing less is flat: two faces back to back.
MIN_VOLUME = 1e-12


def load_mesh(
    mesh_or_path,
    source: str | None = None,
    repairs: list | None = None,
    merge_bodies: bool = False,
):
    """A closed, consistently wound ``trimesh.Trimesh`` with outward normals.

    Parameters
    ----------
    mesh_or_path : trimesh.Trimesh or str or Path
        A mesh, or a file trimesh can read (STL, OBJ, PLY, GLB, OFF...).
    source : str, optional
        How errors name the input (default: the path, or ``"mesh"``).
    repairs : list, optional
        Receives one line per repair made.
    merge_bodies : bool
        Hold bodies that stay apart after the union as one rigid part (default: refuse them).

    Raises
    ------
    ValueError
        Unreadable file, no triangles, a mesh that stays open (the message names the holes'
        sizes) or inconsistently wound, or several disjoint bodies without ``merge_bodies``.
    """
    import trimesh

    if isinstance(mesh_or_path, trimesh.Trimesh):
        mesh = mesh_or_path.copy()
        source = source or "mesh"
    elif isinstance(mesh_or_path, (str, Path)):
        path = Path(mesh_or_path)
        source = source or str(path)
        mesh = read_mesh(path, source)
        raw = _read_unmerged(path)
        if raw is not None and 0 < len(raw.vertices) < 3 * len(raw.faces):  # indexed, not soup
            mesh = raw  # the file's own vertices: touching pieces stay apart until merged
    else:
        raise TypeError(f"mesh: expected a trimesh.Trimesh or a path, got {mesh_or_path!r}")
    return repair_mesh(mesh, source, repairs, merge_bodies)


def _read_unmerged(path: Path):
    """The file's triangles with its own vertex indices (read_mesh merges them), or None."""
    import trimesh

    try:
        raw = trimesh.load(str(path), force="mesh", process=False)
    except Exception:  # read_mesh has already read it: this is only a better start
        return None
    return raw if isinstance(raw, trimesh.Trimesh) else None


def repair_mesh(
    mesh, source: str = "mesh", repairs: list | None = None, merge_bodies: bool = False
):
    """One closed, consistently wound surface with outward normals (see the module's steps).

    Raises
    ------
    ValueError
        When the mesh stays open, inconsistently wound or encloses no volume, or has several
        disjoint bodies and ``merge_bodies`` is not set.
    """
    import trimesh

    repairs = [] if repairs is None else repairs
    faces = np.asarray(mesh.faces)
    vertices = np.asarray(mesh.vertices, dtype=float)
    if len(faces) == 0:
        raise ValueError(f"{source}: the mesh has no triangles")
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"{source}: vertices must be finite")
    centre, size = unit_frame(vertices)
    if not size > 0:
        raise ValueError(f"{source}: every vertex of the mesh is at one point")
    unit = trimesh.Trimesh((vertices - centre) / size, faces, process=False)
    out = _repair_unit(unit, source, repairs, merge_bodies)
    out.vertices = out.vertices * size + centre
    return out


def unit_frame(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) of the bounding box and its largest side: ``(v - centre) / size`` is the part
    at unit size, where trimesh's absolute tolerances (1e-8) become relative ones."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return (lo + hi) / 2, float((hi - lo).max())


def process_at_unit_scale(mesh):
    """trimesh's ``process()`` (merge duplicate vertices, drop degenerate triangles) with its
    tolerances relative to the part's size; ``mesh`` is changed in place and returned."""
    vertices = np.asarray(mesh.vertices, dtype=float)
    centre, size = unit_frame(vertices)
    if not size > 0:
        return mesh
    mesh.vertices = (vertices - centre) / size
    mesh.process()
    mesh.vertices = mesh.vertices * size + centre
    return mesh


def _repair_unit(mesh, source: str, repairs: list, merge_bodies: bool):
    """:func:`repair_mesh` on a mesh at unit size."""
    import trimesh

    faces = np.asarray(mesh.faces)
    vertices = np.asarray(mesh.vertices, dtype=float)
    merged = _clean(trimesh.Trimesh(vertices, faces, process=True))
    if len(merged.faces) == 0:
        raise ValueError(f"{source}: every triangle of the mesh is degenerate")
    if merged.is_watertight and merged.body_count == 1:
        return _oriented(merged, source, repairs)
    # Pieces as the file gives them (vertices shared between touching pieces would join them).
    raw = trimesh.Trimesh(vertices, faces, process=False)
    pieces = [_clean(p) for p in raw.split(only_watertight=False)]
    bodies, problems = [], []
    total = sum(p.area for p in pieces)
    for piece in pieces:
        closed = _closed(piece.copy(), repairs)
        if closed is not None:
            bodies.append(closed)
        elif piece.area < STRAY_AREA * total:
            repairs.append(f"dropped a stray open piece of {len(piece.faces)} triangle(s)")
        else:
            problems.append(piece)
    if problems:
        raise ValueError(f"{source}: {_open_message(problems)}")
    if not bodies:
        raise ValueError(f"{source}: the mesh encloses no volume")
    if len(bodies) == 1:
        return _oriented(bodies[0], source, repairs)
    return _union(bodies, source, repairs, merge_bodies)


def _clean(mesh):
    """Merged vertices, no degenerate or repeated triangles, no unused vertices."""
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def _closed(piece, repairs: list):
    """The piece closed and consistently wound (holes filled), or None."""
    # trimesh divides by the zero areas of degenerate caps while it tries: the outcome is judged
    # by the checks below, not by its warnings.
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return _close(piece, repairs)


def _close(piece, repairs: list):
    import trimesh

    if not piece.is_watertight and _split_t_junctions(piece):
        repairs.append("closed cracks at T-junctions (a vertex on another triangle's edge)")
    if not piece.is_watertight:
        loops = _boundary_loops(piece)
        trimesh.repair.fill_holes(piece)
        if not piece.is_watertight:
            _cap_holes(piece)
        if not piece.is_watertight:
            return None
        sizes = sorted(len(loop) for loop in loops) if loops else []
        repairs.append(f"filled {len(sizes)} hole(s) bounded by {_sizes(sizes)} edges")
    if not piece.is_winding_consistent:
        trimesh.repair.fix_winding(piece)
        if not piece.is_winding_consistent:
            return None
        repairs.append("made the triangles' winding consistent")
    trimesh.repair.fix_normals(piece)
    return piece if piece.volume > MIN_VOLUME else None


def _oriented(mesh, source: str, repairs: list):
    closed = _closed(mesh.copy(), repairs)
    if closed is None:
        if not mesh.is_watertight:
            raise ValueError(f"{source}: {_open_message([mesh])}")
        raise ValueError(
            f"{source}: the mesh's triangles are inconsistently wound (not orientable)"
        )
    return closed


def _union(bodies, source: str, repairs: list, merge_bodies: bool):
    """Boolean union of closed bodies (manifold3d): overlapping pieces become one surface;
    pieces that stay apart are one part only with ``merge_bodies``."""
    import trimesh

    try:
        union = trimesh.boolean.union(bodies, engine="manifold")
    except Exception as exc:  # manifold3d refuses a body it does not find manifold
        raise ValueError(
            f"{source}: the mesh has {len(bodies)} separate closed bodies and their union "
            f"failed ({exc.__class__.__name__}: {exc}); merge them into one part first"
        ) from None
    if not (union.is_watertight and union.is_winding_consistent and union.volume > MIN_VOLUME):
        raise ValueError(
            f"{source}: the union of its {len(bodies)} bodies is not a closed surface; merge "
            "them into one part first"
        )
    trimesh.repair.fix_normals(union)
    pieces = union.body_count
    if pieces > 1 and not merge_bodies:
        raise ValueError(
            f"{source}: the mesh is {pieces} separate bodies (after merging those that overlap "
            "or touch), not one part; --merge-bodies (merge_bodies=True) holds them as one "
            "rigid part, or split the file"
        )
    repairs.append(
        f"merged {len(bodies)} bodies by boolean union (manifold3d)"
        + (f": {pieces} disjoint pieces remain, held as one rigid part" if pieces > 1 else "")
    )
    return union


def _boundary_loops(mesh) -> list[list[int]]:
    """Vertex loops of the mesh's boundary (edges used by one triangle), in their direction."""
    edges = mesh.edges  # directed, from the faces' winding
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts > 2):
        return []  # non-manifold: not holes
    return simple_loops(edges[counts[inverse.ravel()] == 1])


def _split_t_junctions(mesh) -> bool:
    """Close 3-edge cracks of zero area: a vertex m lying on the edge p-q of a triangle on the
    other side of the crack. That triangle is split at m (capping would add a triangle of no
    area). Returns whether any crack was closed."""
    faces = np.asarray(mesh.faces).tolist()
    split = False
    for loop in _boundary_loops(mesh):
        if len(loop) != 3:
            continue
        v = mesh.vertices[loop]
        sides = [np.linalg.norm(v[(k + 1) % 3] - v[k]) for k in range(3)]
        area = np.linalg.norm(np.cross(v[1] - v[0], v[2] - v[0])) / 2
        if not area <= 1e-9 * max(sides) ** 2:
            continue
        k = int(np.argmax(sides))
        p, q, m = loop[k], loop[(k + 1) % 3], loop[(k + 2) % 3]
        for i, face in enumerate(faces):  # the triangle whose edge p -> q is the long side
            j = next((j for j in range(3) if face[j] == p and face[(j + 1) % 3] == q), None)
            if j is not None:
                x = face[(j + 2) % 3]
                faces[i] = [p, m, x]
                faces.append([m, q, x])
                split = True
                break
    if split:
        mesh.faces = np.asarray(faces, dtype=np.int64)
    return split


def _cap_holes(mesh) -> None:
    """Cap every boundary loop by an ear-cut triangulation of its projection on its best-fit
    plane (mapbox_earcut), wound against the boundary so that the result is consistent."""
    import mapbox_earcut

    loops = _boundary_loops(mesh)
    if not loops:
        return
    new_faces = []
    for loop in loops:
        pts = mesh.vertices[loop]
        centred = pts - pts.mean(axis=0)
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        xy = centred @ vt[:2].T
        tri = mapbox_earcut.triangulate_float64(xy, np.array([len(loop)], dtype=np.uint32))
        tri = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        if len(tri) != len(loop) - 2:
            return  # not a simple polygon in that plane: leave the hole
        faces = np.asarray(loop)[tri]
        # The boundary runs a -> b in the mesh; the cap must run b -> a.
        a, b = loop[0], loop[1]
        runs = [(f[k], f[(k + 1) % 3]) for f in faces.tolist() for k in range(3)]
        if (a, b) in runs:
            faces = faces[:, ::-1]
        new_faces.append(faces)
    mesh.faces = np.vstack([mesh.faces, *new_faces])


def simple_loops(directed_edges: np.ndarray) -> list[list[int]]:
    """Simple vertex loops of a set of directed boundary edges ([] if one is not simple)."""
    nxt: dict[int, int] = {}
    for a, b in directed_edges.tolist():
        if a in nxt:
            return []
        nxt[a] = b
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            if v not in nxt:
                return []
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        if v != start:
            return []
        loops.append(loop)
    return loops


def _sizes(sizes: list[int]) -> str:
    values, counts = np.unique(sizes, return_counts=True)
    return ", ".join(f"{v}" + (f" (x{c})" if c > 1 else "") for v, c in zip(values, counts))


def _open_message(pieces) -> str:
    """What is open, and what the user can do."""
    open_edges, sizes = 0, []
    for p in pieces:
        key = np.sort(p.edges, axis=1)
        _, counts = np.unique(key, axis=0, return_counts=True)
        open_edges += int((counts != 2).sum())
        sizes += [len(loop) for loop in _boundary_loops(p)]
    holes = f"; holes bounded by {_sizes(sorted(sizes))} edges" if sizes else ""
    return (
        f"the mesh is not closed ({open_edges} open or non-manifold edges{holes}) and filling "
        "its holes did not close it (a hole that is not flat enough to cap, or edges shared by "
        "more than two triangles); a closed surface is needed to tell inside from outside: "
        "close it in a mesh editor (e.g. Blender's 3D-Print toolbox or MeshLab's 'close holes')"
    )


def read_mesh(path, source: str | None = None):
    """A ``trimesh.Trimesh`` from a mesh file (STL, OBJ, PLY, GLB, OFF...).

    Every way a file can fail is a ``ValueError`` that names it: missing, a format trimesh does
    not read, bytes that are not a mesh of that format (trimesh's own errors for those are
    ``ModuleNotFoundError`` or ``NotImplementedError``), no triangles, coordinates out of range.
    """
    import trimesh

    path = Path(path)
    source = source or str(path)
    try:
        check_input(path, MAX_MESH_BYTES)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in trimesh.available_formats():
        raise ValueError(
            f"{source}: not a mesh file (unknown suffix {path.suffix!r}; "
            "use .stl, .obj, .ply, .glb, .off...)"
        )
    if suffix == "stl":
        _check_stl(path, source)
    try:  # unprocessed first: processing silently drops non-finite vertices
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds for a bad file
        # A text format that is not text ends in trimesh's search for a charset module.
        detail = "bytes that are not text" if isinstance(exc, ImportError) else str(exc)
        raise ValueError(
            f"{source}: not a valid {suffix.upper()} mesh: {detail[:100] or type(exc).__name__}"
        ) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError(f"{source}: no triangles found (not a mesh file, or an empty mesh)")
    vertices = np.asarray(loaded.vertices)
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"{source}: vertices: numbers must be finite")
    if float(np.abs(vertices).max()) > MAX_COORDINATE:
        raise ValueError(
            f"{source}: vertices: |coordinate| {float(np.abs(vertices).max()):.3g} is beyond "
            f"the accepted range [-{MAX_COORDINATE:g}, {MAX_COORDINATE:g}]"
        )
    # Merge duplicate vertices, drop degenerate faces (as process=True would), with tolerances
    # relative to the part's size (trimesh's are absolute: at 1e11 they overflow).
    return process_at_unit_scale(loaded)


def _check_stl(path: Path, source: str) -> None:
    """Binary STL: 80-byte header, triangle count, 50 bytes per triangle; or ASCII 'solid'."""
    size = path.stat().st_size
    with path.open("rb") as handle:
        head = handle.read(84)
    if size >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little"):
        return
    if head.lstrip().lower().startswith(b"solid"):
        try:
            head.decode("ascii")
            return
        except UnicodeDecodeError:
            pass
    raise ValueError(
        f"{source}: not an STL file (neither ASCII 'solid ...' nor a binary STL whose "
        f"triangle count matches its {size} bytes)"
    )


__all__ = [
    "load_mesh",
    "process_at_unit_scale",
    "read_mesh",
    "repair_mesh",
    "unit_frame",
]
