"""Closed part surfaces from meshes as datasets ship them.

Robotics datasets ship open handles glued into bodies, convex decompositions (VHACD pieces that
overlap or touch face to face), texture seams and stray triangles. :func:`repair_mesh` makes one
closed, consistently wound surface with outward normals, or says why it cannot:

1. the mesh with its vertices merged, when that is closed (most files);
2. else its bodies: connected pieces as the file gives them (or, when those do not close, as
   the merged vertices join them), each closed on its own once its holes are filled (trimesh's
   repair for 3-4 edges, then a cap of each remaining boundary loop: ear-cut on the loop's
   best-fit plane, or a fan from its centroid when that projection folds over), kept only when
   the piece is then closed and consistently wound; stray open sheets with almost no area are
   dropped. A hole whose boundary is longer than the part's radius is an opening (a cup's
   mouth), not a defect: capping it makes another part, so it is capped only when the caller
   says so (``close_holes``);
3. several closed bodies are merged by a boolean union (manifold3d), so no element lies inside
   the part. Bodies that stay apart after the union (200 separate boxes in one file) are one
   part only when the caller says so (``merge_bodies``): a file of several objects is refused,
   naming how many there are.

Every repair is described in the ``repairs`` list the caller passes, as a :class:`Repair`: its
words, and the facts a report counts (the edge counts of the holes filled, the bodies held as
one part). Every threshold (merging
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
# A hole whose boundary is longer than this many part radii is an opening of the part, not a
# defect of its mesh (a unit-free rule: the radius is the largest distance from the bounding
# box's centre to a vertex).
LARGE_HOLE = 1.0


class Repair(str):
    """One repair in words (it is a ``str``: JSON and text take it as one), with the facts a
    report counts: ``holes`` (edge counts of the holes filled) and ``bodies`` (separate bodies
    held as one rigid part, 0 when none are)."""

    holes: tuple[int, ...] = ()
    bodies: int = 0

    def __new__(cls, text: str, holes=(), bodies: int = 0):
        self = super().__new__(cls, text)
        self.holes = tuple(int(h) for h in holes)
        self.bodies = int(bodies)
        return self


def holes_filled(repairs) -> list[int]:
    """Edge counts of every hole the ``repairs`` filled, smallest first."""
    return sorted(h for r in repairs for h in getattr(r, "holes", ()))


def bodies_held(repairs) -> int:
    """How many separate bodies the ``repairs`` hold as one rigid part (0: one body)."""
    return max((getattr(r, "bodies", 0) for r in repairs), default=0)


def load_mesh(
    mesh_or_path,
    source: str | None = None,
    repairs: list | None = None,
    merge_bodies: bool = False,
    close_holes: bool = False,
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
    close_holes : bool
        Cap openings too: holes whose boundary is longer than the part's radius (default:
        refuse them; smaller holes are always filled).

    Raises
    ------
    ValueError
        Unreadable file, no triangles, a mesh that stays open (the message names the holes'
        sizes) or inconsistently wound, an opening without ``close_holes``, or several disjoint
        bodies without ``merge_bodies``.
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
    return repair_mesh(mesh, source, repairs, merge_bodies, close_holes)


def _read_unmerged(path: Path):
    """The file's triangles with its own vertex indices (read_mesh merges them), or None."""
    import trimesh

    try:
        raw = trimesh.load(str(path), force="mesh", process=False)
    except Exception:  # read_mesh has already read it: this is only a better start
        return None
    return raw if isinstance(raw, trimesh.Trimesh) else None


def repair_mesh(
    mesh,
    source: str = "mesh",
    repairs: list | None = None,
    merge_bodies: bool = False,
    close_holes: bool = False,
):
    """One closed, consistently wound surface with outward normals (see the module's steps).

    Raises
    ------
    ValueError
        When the mesh stays open, inconsistently wound or encloses no volume, has an opening
        (a hole longer than the part's radius) and ``close_holes`` is not set, or has several
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
    out = _repair_unit(unit, source, repairs, merge_bodies, close_holes)
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


def _repair_unit(mesh, source: str, repairs: list, merge_bodies: bool, close_holes: bool):
    """:func:`repair_mesh` on a mesh at unit size."""
    import trimesh

    faces = np.asarray(mesh.faces)
    vertices = np.asarray(mesh.vertices, dtype=float)
    merged = _clean(trimesh.Trimesh(vertices, faces, process=True))
    if len(merged.faces) == 0:
        raise ValueError(f"{source}: every triangle of the mesh is degenerate")
    if merged.is_watertight and merged.body_count == 1:
        return _oriented(merged, source, repairs)
    # The unit frame's centre is the bounding box's: openings are judged against this radius.
    hole = _Holes(float(np.linalg.norm(vertices[np.unique(faces)], axis=1).max()), close_holes)
    # Pieces as the file gives them first (vertices shared between touching pieces would join
    # them); when one of those does not close (a file of loose triangles whose vertices only
    # meet once merged), the pieces of the merged mesh.
    raw = trimesh.Trimesh(vertices, faces, process=False)
    found = _bodies(raw, repairs, hole)
    if isinstance(found, _Refused) and len(raw.vertices) != len(merged.vertices):
        found = _bodies(merged, repairs, hole)
    if isinstance(found, _Refused):
        raise ValueError(f"{source}: {found.message}")
    if not found:
        raise ValueError(f"{source}: the mesh encloses no volume")
    if len(found) == 1:
        return _oriented(found[0], source, repairs)
    return _union(found, source, repairs, merge_bodies)


class _Holes:
    """What may be filled: holes up to ``LARGE_HOLE`` x ``radius`` long, any with ``close``."""

    def __init__(self, radius: float, close: bool):
        self.radius, self.close = radius, close

    def opening(self, mesh, loops) -> tuple[int, float] | None:
        """(edges, length / radius) of the longest loop that is an opening, or None."""
        if self.close or not loops or not self.radius > 0:
            return None
        lengths = [_loop_length(mesh, loop) for loop in loops]
        k = int(np.argmax(lengths))
        ratio = lengths[k] / self.radius
        return (len(loops[k]), ratio) if ratio > LARGE_HOLE else None


class _Opening(Exception):
    """A hole to fill is an opening: (edges, length / radius)."""


class _Refused:
    """Why a mesh's pieces do not make closed bodies."""

    def __init__(self, message: str):
        self.message = message


def _bodies(mesh, repairs: list, hole: _Holes):
    """The closed bodies of ``mesh``'s connected pieces (debris dropped), their repairs added to
    ``repairs``; or a :class:`_Refused` (``repairs`` unchanged)."""
    # repair=False: trimesh's split would fill small holes silently, and every fill is reported.
    pieces = [_clean(p) for p in mesh.split(only_watertight=False, repair=False)]
    bodies, problems, made = [], [], []
    total = sum(p.area for p in pieces)
    for piece in pieces:
        try:
            closed = _closed(piece.copy(), made, hole)
        except _Opening as opening:
            if piece.area >= STRAY_AREA * total:
                return _Refused(_opening_message(*opening.args))
            closed = None
        if closed is not None:
            bodies.append(closed)
        elif piece.area < STRAY_AREA * total:
            debris = Repair(f"dropped a stray open piece of {len(piece.faces)} triangle(s)")
            debris.stray = len(piece.faces)
            made.append(debris)
        else:
            problems.append(piece)
    if problems:
        return _Refused(_open_message(problems))
    repairs += _merged_fills(made)
    return bodies


def _merged_fills(made: list) -> list:
    """``made`` with every hole filling as one line, every debris piece as one line, each other
    line once (a file of 600 pieces gives a few lines, not 600)."""
    holes = holes_filled(made)
    stray = [r.stray for r in made if getattr(r, "stray", 0)]
    rest = [r for r in dict.fromkeys(made) if not r.holes and not getattr(r, "stray", 0)]
    lines = [_filled(holes)] if holes else []
    if stray:
        dropped = Repair(
            f"dropped {len(stray)} stray open piece(s) of {_sizes(sorted(stray))} triangle(s)"
        )
        lines.append(dropped)
    return lines + rest


def _filled(holes) -> Repair:
    return Repair(f"filled {len(holes)} hole(s) bounded by {_sizes(sorted(holes))} edges", holes)


def _clean(mesh):
    """Merged vertices, no degenerate or repeated triangles, no unused vertices."""
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def _closed(piece, repairs: list, hole: _Holes | None = None):
    """The piece closed and consistently wound (holes filled), or None."""
    # trimesh divides by the zero areas of degenerate caps while it tries: the outcome is judged
    # by the checks below, not by its warnings.
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return _close(piece, repairs, hole)


def _close(piece, repairs: list, hole: _Holes | None):
    import trimesh

    opening = None
    if not piece.is_watertight and _split_t_junctions(piece):
        repairs.append(Repair("closed cracks at T-junctions (a vertex on another triangle's edge)"))
    if not piece.is_watertight:
        loops = _boundary_loops(piece)
        # After the cracks: a T-junction crack is as long as the edge it runs along.
        opening = hole.opening(piece, loops) if hole is not None else None
        trimesh.repair.fill_holes(piece)
        if not piece.is_watertight:
            _cap_holes(piece)
        if not piece.is_watertight:
            return None
        repairs.append(_filled([len(loop) for loop in loops]))
    if not piece.is_winding_consistent:
        trimesh.repair.fix_winding(piece)
        if not piece.is_winding_consistent:
            return None
        repairs.append(Repair("made the triangles' winding consistent"))
    trimesh.repair.fix_normals(piece)
    if not piece.volume > MIN_VOLUME:
        return None
    # Judged once the caps close a body: a sheet that no cap closes (a fin) is not an opening.
    if opening is not None:
        raise _Opening(*opening)
    return piece


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
        Repair(
            f"merged {len(bodies)} bodies by boolean union (manifold3d)"
            + (f": {pieces} disjoint pieces remain, held as one rigid part" if pieces > 1 else ""),
            bodies=pieces if pieces > 1 else 0,
        )
    )
    return union


def _boundary_loops(mesh) -> list[list[int]]:
    """Simple vertex loops of the mesh's boundary (edges used by one triangle), in their
    direction; a boundary that passes a vertex twice (two holes meeting at a corner) is cut
    there into simple loops. [] when an edge has more than two triangles (not holes)."""
    edges = mesh.edges  # directed, from the faces' winding
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts > 2):
        return []  # non-manifold: not holes
    return boundary_cycles(edges[counts[inverse.ravel()] == 1])


def boundary_cycles(directed_edges: np.ndarray) -> list[list[int]]:
    """Simple vertex loops covering a set of directed boundary edges: closed walks along them,
    each cut at a vertex it passes twice ([] if an edge leads nowhere)."""
    out: dict[int, list[int]] = {}
    for a, b in directed_edges.tolist():
        out.setdefault(a, []).append(b)
    loops: list[list[int]] = []
    for start in list(out):
        while out.get(start):
            path, where = [start], {start: 0}
            v = start
            while True:
                if not out.get(v):
                    return []  # an open chain: not a boundary of holes
                v = out[v].pop()
                if v in where:  # a loop closes: cut it off the walk
                    k = where[v]
                    loops.append(path[k:])
                    for u in path[k + 1 :]:
                        del where[u]
                    del path[k + 1 :]
                    if v == start and len(path) == 1 and not out.get(start):
                        break
                    continue
                where[v] = len(path)
                path.append(v)
            if len(path) > 1:
                return []
    return loops


def _loop_length(mesh, loop) -> float:
    pts = mesh.vertices[loop]
    return float(np.linalg.norm(pts - np.roll(pts, -1, axis=0), axis=1).sum())


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
    """Cap every boundary loop, each on its own: an ear-cut triangulation of its projection on
    its best-fit plane (mapbox_earcut), or, where that projection folds over (a hole around a
    corner), a fan from a new vertex at the loop's centroid; wound against the boundary so that
    the result is consistent."""
    import mapbox_earcut

    vertices = np.asarray(mesh.vertices, dtype=float)
    new_vertices, new_faces = [], []
    for loop in _boundary_loops(mesh):
        pts = vertices[loop]
        centred = pts - pts.mean(axis=0)
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        xy = centred @ vt[:2].T
        tri = mapbox_earcut.triangulate_float64(xy, np.array([len(loop)], dtype=np.uint32))
        tri = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        if len(tri) == len(loop) - 2:
            faces = np.asarray(loop)[tri]
        else:  # not a simple polygon in that plane
            centre = len(vertices) + len(new_vertices)
            new_vertices.append(pts.mean(axis=0))
            faces = np.array([[a, b, centre] for a, b in zip(loop, loop[1:] + loop[:1])])
        # The boundary runs a -> b in the mesh; the cap must run b -> a.
        a, b = loop[0], loop[1]
        runs = [(f[k], f[(k + 1) % 3]) for f in faces.tolist() for k in range(3)]
        if (a, b) in runs:
            faces = faces[:, ::-1]
        new_faces.append(faces)
    if new_faces:
        if new_vertices:
            mesh.vertices = np.vstack([vertices, new_vertices])
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


def _opening_message(edges: int, ratio: float) -> str:
    return (
        f"the mesh is open: a hole bounded by {edges} edges, its boundary {ratio:.2g} x the "
        "part's radius long, is an opening of the part (a cup's mouth), not a defect of its "
        "mesh; capping it makes another part: --close-holes (close_holes=True) caps it, or close "
        "it in a mesh editor"
    )


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
