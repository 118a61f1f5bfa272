"""Element models from triangle meshes (paper section 2: facets, line segments, discrete points).

The surface is cut along sharp edges (dihedral angle above ``sharp_angle``) into smooth regions.
Inside each region:

- a planar patch (coplanar connected triangles) becomes convex facets: its triangles are merged
  greedily into convex polygons (Hertel-Mehlhorn: drop a diagonal while the union stays convex),
  projected exactly onto the patch's plane. A planar patch much larger than the region's other
  patches (a flat face that runs smoothly into a fillet) is a facet too;
- a ruled patch (cylinder: face normals perpendicular to one axis; circular cone: face normals at
  one angle to an axis, rulings through the apex) becomes line segments along its rulings, the
  mesh edges that run along the axis (or through the apex), merged when collinear and thinned to
  ``segment_spacing``;
- any other curved patch becomes discrete points at its vertices, thinned to ``point_spacing``.

The mesh is read and repaired by :mod:`closure_nlp.model.meshes`; facets come from
:mod:`closure_nlp.model.planar`, segments from :mod:`closure_nlp.model.rulings`; points and
neighbours are
made here.

Every normal is an inward normal: the mesh's outward normal negated. Two elements are neighbours
when they share a mesh vertex; a segment or a point is also a neighbour of the elements across a
mesh edge from the vertices it stands for (its own, and the dropped ones nearest to it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from closure_nlp.base.tolerances import DEFAULT_TOLERANCES
from closure_nlp.base.validation import UNITS
from closure_nlp.contact.accuracy import ModelTolerance
from closure_nlp.contact.contact_set import as_reference_point
from closure_nlp.model.drafts import Draft, thin
from closure_nlp.model.elements import Element, ElementKind, Model, part_radius, part_size
from closure_nlp.model.meshes import load_mesh, repair_mesh
from closure_nlp.model.model_mesh import outward_elements
from closure_nlp.model.planar import facets
from closure_nlp.model.rulings import rulings, segments


@dataclass(frozen=True)
class CharacterizeOptions:
    """Thresholds of :func:`characterize`.

    Attributes
    ----------
    sharp_angle : float
        Degrees. Mesh edges whose dihedral angle exceeds it separate smooth regions.
    flat_angle : float
        Degrees. Adjacent triangles whose normals differ by less are coplanar; also the
        tolerance of the ruled-surface tests.
    facet_area_ratio : float
        A planar patch inside a curved region is a facet when its area is at least this many
        times the median patch area of the region.
    faceted_limit : int
        A curved, non-ruled part made of at most this many planar patches is a faceted solid
        (a cut gem, a coarse polyhedron) and becomes facets; a finer one is a tessellated smooth
        surface and becomes points.
    segment_spacing : float or None
        Rulings closer than this to a kept ruling are dropped (None keeps all).
    point_spacing : float or None
        Vertices closer than this to a kept point are dropped (None keeps all).
    """

    sharp_angle: float = 30.0
    flat_angle: float = 0.5
    facet_area_ratio: float = 4.0
    segment_spacing: float | None = None
    point_spacing: float | None = None
    faceted_limit: int = 100

    def __post_init__(self) -> None:
        if isinstance(self.faceted_limit, bool) or not isinstance(self.faceted_limit, int):
            raise TypeError(f"faceted_limit: expected an integer, got {self.faceted_limit!r}")
        if self.faceted_limit < 0:
            raise ValueError(f"faceted_limit: must be >= 0, got {self.faceted_limit!r}")
        for key in ("sharp_angle", "flat_angle", "facet_area_ratio"):
            value = getattr(self, key)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
                raise ValueError(f"{key}: must be a positive number, got {value!r}")
        if not self.flat_angle < self.sharp_angle < 180:
            raise ValueError(
                f"sharp_angle: must lie between flat_angle ({self.flat_angle}) and 180, "
                f"got {self.sharp_angle!r}"
            )
        for key in ("segment_spacing", "point_spacing"):
            value = getattr(self, key)
            if value is None:
                continue
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not np.isfinite(value)
                or value < 0
            ):
                raise ValueError(f"{key}: must be a number >= 0, got {value!r}")


# --- characterization ------------------------------------------------------------------------


SPACING_FRACTION = 0.2  # default point and ruling spacing: this fraction of the mesh's radius
AUTO = "auto"
DEFAULT_UNITS = "m"  # a mesh file carries no unit; glTF's, and robotics datasets', is the metre


@dataclass(frozen=True)
class Characterization:
    """A model and the settings that made it (what ``characterize`` prints and records).

    ``radius`` is the model's (:attr:`Model.radius`), the one every model command scales by;
    ``dropped`` says which elements were left out of the model and why.
    """

    model: Model
    reference_point: np.ndarray
    radius: float
    segment_spacing: float
    point_spacing: float
    repairs: tuple[str, ...]
    reference_source: str = "given"
    mesh: object = field(default=None, repr=False)  # the closed mesh the elements come from
    dropped: tuple[str, ...] = ()
    units_source: str = "given"

    def text(self) -> str:
        unit = f" {self.model.units}"
        point = ", ".join(f"{x:.6g}" for x in self.reference_point)
        return (
            f"units {self.model.units} ({self.units_source}); torques about [{point}]{unit} "
            f"({self.reference_source}); radius {self.radius:.6g}{unit}; spacing of points "
            f"{self.point_spacing:.6g}{unit}, of rulings {self.segment_spacing:.6g}{unit}"
            + "".join(f"\n  repaired: {r}" for r in self.repairs)
        )


def characterize(mesh_or_path, **options) -> Model:
    """Describe a closed mesh by convex facets, line segments and discrete points.

    Parameters are those of :func:`characterize_mesh`, which also returns the settings used.
    """
    return characterize_mesh(mesh_or_path, **options).model


def characterize_mesh(
    mesh_or_path,
    *,
    segment_spacing: float | str | None = AUTO,
    point_spacing: float | str | None = AUTO,
    sharp_angle: float = 30.0,
    flat_angle: float = 0.5,
    facet_area_ratio: float = 4.0,
    faceted_limit: int = 100,
    name: str | None = None,
    units: str | None = None,
    mesh_ref: str | None = None,
    reference_point=None,
    up: str = "z",
    merge_bodies: bool = False,
    close_holes: bool = False,
) -> Characterization:
    """Describe a closed mesh by convex facets, line segments and discrete points.

    Parameters
    ----------
    mesh_or_path : trimesh.Trimesh or str or Path
        The object's surface.
    segment_spacing, point_spacing : float or "auto", optional
        Thinning distances for rulings and points (in the mesh's unit); ``"auto"`` (default) is
        ``SPACING_FRACTION`` times the radius of the mesh's vertices about the reference point
        (:func:`closure_nlp.model.scale.part_radius`); None or 0 keeps them all (exact duplicates
        are
        always dropped).
    sharp_angle, flat_angle, facet_area_ratio, faceted_limit
        See :class:`CharacterizeOptions`.
    name : str, optional
        Model name (default: the file's stem, or ``"mesh"``).
    units : {"m", "cm", "mm", "in"}, optional
        The mesh's length unit, recorded in the model; default ``DEFAULT_UNITS`` (metres).
    mesh_ref : str, optional
        Stored as the model's ``mesh`` (a path relative to where the model file will go).
    reference_point : [x, y, z], optional
        The point torques are taken about; default the centre of mass of the closed mesh.
    up : str
        The model's up axis for pictures (x, y or z).
    merge_bodies : bool
        Hold several disjoint bodies as one rigid part (default: refuse such a mesh).
    close_holes : bool
        Cap openings too (holes whose boundary is longer than the part's radius, such as a cup's
        mouth; default: refuse such a mesh). Smaller holes are always filled and reported.

    Returns
    -------
    Characterization
        The model (facets first, then segments, then points; adjacency from the mesh topology)
        and the reference point, radius, spacings and repairs used. Facets and segments too
        small for a model against the part's size are left out and counted in ``dropped``.
        The normals are judged against the mesh file a model will read
        (:func:`drop_outward`, which ``closure-nlp characterize`` applies once it is written).
    """
    units_source = "given"
    if units is None:
        units, units_source = DEFAULT_UNITS, "default: --units sets it"
    if units not in UNITS:
        raise ValueError(f"units: expected one of {', '.join(UNITS)}, got {units!r}")
    repairs: list[str] = []
    mesh = load_mesh(mesh_or_path, None, repairs, merge_bodies, close_holes)
    if reference_point is not None:
        point, source = as_reference_point(reference_point, "reference_point"), "given"
    elif mesh.is_volume:
        point, source = np.asarray(mesh.center_mass), "the part's centre of mass"
    else:
        point, source = mesh.vertices.mean(axis=0), "the centroid of the mesh's vertices"
    spread = part_radius(mesh.vertices, point)
    spacings = [
        SPACING_FRACTION * spread if _is_auto(v) else (0.0 if v is None else v)
        for v in (segment_spacing, point_spacing)
    ]
    options = CharacterizeOptions(
        sharp_angle, flat_angle, facet_area_ratio, *spacings, faceted_limit
    )
    if name is None:
        name = Path(mesh_or_path).stem if isinstance(mesh_or_path, (str, Path)) else "mesh"
    arrays = MeshArrays(mesh)
    drafts, curved = _characterize_mesh(arrays, options)
    order = sorted(
        range(len(drafts)), key=lambda i: list(ElementKind).index(drafts[i].element.kind)
    )
    drafts = [drafts[i] for i in order]
    drafts, dropped = _without_tiny(drafts)
    measured = measured_tolerances(mesh, drafts, options)
    folded = [d for d, t in zip(drafts, measured) if t is None]
    if folded:
        dropped.append(
            f"{len(folded)} element(s) turned 90 degrees or more from the mesh faces they stood "
            "for (folds or wrongly wound patches)"
        )
        kept = [(d, t) for d, t in zip(drafts, measured) if t is not None]
        if not kept:
            raise ValueError("every element turned 90 degrees or more from its mesh faces")
        drafts, measured = (list(column) for column in zip(*kept))
    elements = tuple(
        Element(
            d.element.kind,
            d.element.vertices,
            d.element.inward_normal,
            name=f"elements[{i}]",
            tolerance=t,
        )
        for i, (d, t) in enumerate(zip(drafts, measured))
    )
    adjacency = _adjacency(arrays, drafts, curved)
    model = Model(
        elements,
        adjacency,
        name=name,
        units=units,
        mesh=mesh_ref,
        reference_point=point,
        up=up,
    )
    return Characterization(
        model,
        model.reference_point,
        model.radius,
        *spacings,
        tuple(repairs),
        source,
        mesh,
        tuple(dropped),
        units_source,
    )


def _without_tiny(drafts: list[Draft]) -> tuple[list[Draft], list[str]]:
    """Drafts without the facets and segments a model refuses as degenerate against the part's
    size (slivers a boolean union leaves), and a line saying how many went."""
    tol = DEFAULT_TOLERANCES.geometry
    gone = {ElementKind.FACET: 0, ElementKind.SEGMENT: 0}
    while drafts:
        size = part_size([d.element for d in drafts])
        small = [
            d.element.kind is not ElementKind.POINT
            and not float(np.ptp(d.element.vertices, axis=0).max()) > tol * size
            for d in drafts
        ]
        if not any(small):
            break
        for d in (d for d, s in zip(drafts, small) if s):
            gone[d.element.kind] += 1
        drafts = [d for d, s in zip(drafts, small) if not s]
    lines = [
        f"{n} {kind.value}(s) smaller than {tol:g} x the part's size (slivers)"
        for kind, n in gone.items()
        if n
    ]
    return drafts, lines


def drop_outward(model: Model, mesh) -> tuple[Model, list[str]]:
    """``model`` without the elements whose inward normal points out of ``mesh`` (the check every
    model command applies, :func:`closure_nlp.model.model_mesh.outward_elements`), and one line
    naming
    each. Such an element is a small facet on a fold or at a thin edge of the mesh, where the
    faces around its corners outweigh its own and face the other way."""
    bad = outward_elements(model, mesh)
    if not bad:
        return model, []
    lines = [
        f"the {model.elements[i].kind.value} at "
        f"[{', '.join(f'{x:.6g}' for x in model.elements[i].centroid)}] "
        f"({model.elements[i].size:.3g} across): its inward normal points out of the mesh "
        "around it (the faces at its corners face the other way: a fold or a thin edge)"
        for i in bad
    ]
    return without_elements(model, bad), lines


def drop_outward_as_read(model: Model, base_dir) -> tuple[Model, list[str]]:
    """:func:`drop_outward` against the model's mesh file (``model.mesh`` in ``base_dir``) as
    every model command reads it (:func:`closure_nlp.model.model_mesh.read_model_mesh`: an STL holds
    32-bit coordinates), so that they accept the model returned. No mesh: nothing is judged."""
    from closure_nlp.model.model_mesh import read_model_mesh

    placed = replace(model, base_dir=Path(base_dir))
    kept, lines = drop_outward(placed, read_model_mesh(placed))
    return replace(kept, base_dir=model.base_dir), lines


def without_elements(model: Model, ids) -> Model:
    """``model`` without the elements ``ids``: the others renumbered in order, and the neighbours
    of a removed element made neighbours of each other (the iterative selection still moves
    across it)."""
    gone = set(ids)
    new_id, elements = {}, []
    for i, e in enumerate(model.elements):
        if i not in gone:
            new_id[i] = len(elements)
            elements.append(replace(e, name=f"elements[{len(elements)}]"))
    if not elements:
        raise ValueError(f"{model.name}: every element was dropped")
    pairs = {(new_id[a], new_id[b]) for a, b in model.adjacency if a in new_id and b in new_id}
    for i in gone:
        around = sorted(new_id[j] for j in _reach(model, i, gone))
        pairs |= {(a, b) for a in around for b in around if a < b}
    return replace(model, elements=tuple(elements), adjacency=tuple(sorted(pairs)))


def _reach(model: Model, start: int, gone: set[int]) -> set[int]:
    """Kept elements reached from ``start`` through removed ones."""
    seen, todo, out = {start}, [start], set()
    while todo:
        for j in model.neighbours(todo.pop()):
            if j in gone and j not in seen:
                seen.add(j)
                todo.append(j)
            elif j not in gone:
                out.add(j)
    return out


class MeshArrays:
    """A mesh's arrays, each read from trimesh once and kept as a plain array.

    trimesh checks its cache on every property access by hashing the mesh's arrays (O(F)), so
    reading ``mesh.area_faces`` once per patch costs O(F x patches); this reads each property
    on first use and keeps it (``mesh.vertices`` etc. as attributes, like the mesh's own).
    """

    def __init__(self, mesh):
        self._mesh = mesh

    @property
    def pairs_of_faces(self) -> np.ndarray:
        """(F, w) int: the rows of ``face_adjacency`` each face is in, padded with -1."""
        if "_pairs_of_faces" not in self.__dict__:
            adjacency = self.face_adjacency
            ends = adjacency.ravel()
            width = max(int(np.bincount(ends, minlength=1).max()), 1)
            out = np.full((len(self.faces), width), -1, dtype=np.int64)
            order = np.argsort(ends, kind="stable")
            first = np.searchsorted(ends[order], ends[order], side="left")
            slot = np.arange(len(ends)) - first  # 0, 1, 2... within each face's run
            out[ends[order], slot] = order // 2
            self._pairs_of_faces = out
        return self._pairs_of_faces

    def __getattr__(self, name: str):
        value = getattr(self._mesh, name)
        if isinstance(value, np.ndarray):
            value = value.view(np.ndarray)
        setattr(self, name, value)  # an instance attribute: not looked up here again
        return value


# Relative deviation (of the part's radius; radians for normals) a mesh file's round-off makes.
ROUND_OFF = 1e-6


def measured_tolerances(mesh, drafts: list[Draft], options: CharacterizeOptions) -> list:
    """How far each element deviates from the mesh it stands for: a :class:`ModelTolerance`
    per draft, or None where the mesh faces it stands for turn 90 degrees or more from its
    normal (it does not stand for them: a fold or a wrongly wound patch).

    ``normal_deg``: the largest angle between an element's normal and the (inward) normals of
    the mesh faces it stands for: a facet's own triangles; for a segment or a point, the faces
    around its vertices within its smooth region (normals within ``sharp_angle``), the span of
    normals the real surface may have there. ``position``: the largest distance of a facet's
    mesh vertices from its plane (segments and points sit on mesh vertices). A flat face is
    exact (0, 0) however faceted the rest of the part is.
    """
    from scipy.spatial import cKDTree

    inward = -np.asarray(mesh.face_normals)
    vertex_faces = np.asarray(mesh.vertex_faces)  # padded with -1
    tree = cKDTree(mesh.vertices)
    sharp = np.cos(np.radians(options.sharp_angle))
    # below these, a deviation is the round-off of the mesh file (32-bit STL), not of the surface
    noise = ROUND_OFF * part_radius(mesh.vertices, mesh.vertices.mean(axis=0))
    out = []
    for draft in drafts:
        e = draft.element
        n = e.inward_normal
        position = 0.0
        if e.kind is ElementKind.FACET:
            owned = np.fromiter(draft.owned, int)
            mask = np.zeros(len(mesh.vertices), bool)
            mask[owned] = True
            faces = np.flatnonzero(mask[mesh.faces].all(axis=1))
            if len(owned):
                position = float(np.abs((mesh.vertices[owned] - e.vertices[0]) @ n).max())
        else:
            faces = vertex_faces[tree.query(e.vertices)[1]].ravel()
            faces = faces[faces >= 0]
            faces = faces[inward[faces] @ n >= sharp]
        worst = float(np.clip(inward[faces] @ n, -1.0, 1.0).min()) if len(faces) else 1.0
        angle = float(np.arccos(worst))
        if angle >= np.pi / 2:
            out.append(None)
            continue
        out.append(
            ModelTolerance(
                position if position > noise else 0.0,
                float(np.degrees(angle)) if angle > ROUND_OFF else 0.0,
            )
        )
    return out


def worst_tolerance(tolerances) -> ModelTolerance:
    """The largest position and normal deviation over elements' tolerances."""
    tolerances = list(tolerances)
    position = max((t.position for t in tolerances), default=0.0)
    return ModelTolerance(position, max((t.normal_deg for t in tolerances), default=0.0))


def _is_auto(value) -> bool:
    return isinstance(value, str) and value.strip().lower() == AUTO


def _characterize_mesh(mesh, options: CharacterizeOptions):
    """Drafts of every element, and per curved patch its faces and singular vertices."""
    sharp = np.radians(options.sharp_angle)
    flat = np.radians(options.flat_angle)
    regions = _face_components(mesh, mesh.face_adjacency_angles < sharp)
    patches = _planar_patches(mesh, flat)
    drafts: list[Draft] = []
    curved: list[np.ndarray] = []
    for faces in _groups(regions):
        drafts += _characterize_region(mesh, faces, patches, curved, options)
    return drafts, curved


def _groups(labels: np.ndarray, among: np.ndarray | None = None) -> list[np.ndarray]:
    """Ids (of ``among``, default all) sharing each label, by ascending label: O(n log n)."""
    ids = np.arange(len(labels)) if among is None else among
    keys = labels[ids]
    order = np.argsort(keys, kind="stable")
    cuts = np.flatnonzero(np.diff(keys[order])) + 1
    return np.split(ids[order], cuts)


def _planar_patches(mesh, flat: float) -> np.ndarray:
    """(F,) int: planar patch of each face.

    Faces join across edges flatter than ``flat``; a component whose normals then spread wider
    than ``flat`` from its mean (a fine tessellation of a curved surface, where every edge is
    nearly flat) is regrown from its largest faces, each patch keeping the faces within ``flat``
    of its seed's normal.
    """
    keep = mesh.face_adjacency_angles < flat
    labels = _face_components(mesh, keep)
    normals, areas = mesh.face_normals, mesh.area_faces
    mean = np.zeros((labels.max() + 1, 3))
    np.add.at(mean, labels, normals * areas[:, None])
    mean /= np.maximum(np.linalg.norm(mean, axis=1), 1e-300)[:, None]
    bent = np.flatnonzero((normals * mean[labels]).sum(1) < np.cos(flat))
    if len(bent) == 0:
        return labels
    spread = np.isin(labels, np.unique(labels[bent]))
    pairs = mesh.face_adjacency[keep & spread[mesh.face_adjacency].all(axis=1)]
    n = len(mesh.faces)
    graph = coo_matrix((np.ones(2 * len(pairs)), (pairs.ravel(), pairs[:, ::-1].ravel())), (n, n))
    graph = graph.tocsr()
    out = labels.copy()
    next_label = int(labels.max()) + 1
    cos_flat = float(np.cos(flat))
    # Plain Python lists: this loop visits every face of the spread components once, and a
    # numpy scalar operation costs ~1 us where a float's costs ~0.05 us.
    indptr, indices = graph.indptr.tolist(), graph.indices.tolist()
    nx, ny, nz = (normals[:, k].tolist() for k in range(3))
    done = (~spread).tolist()
    label = out.tolist()
    for seed in np.flatnonzero(spread)[np.argsort(-areas[spread], kind="stable")].tolist():
        if done[seed]:
            continue
        done[seed] = True
        label[seed] = next_label
        sx, sy, sz = nx[seed], ny[seed], nz[seed]
        stack = [seed]
        while stack:
            f = stack.pop()
            for g in indices[indptr[f] : indptr[f + 1]]:
                if not done[g] and nx[g] * sx + ny[g] * sy + nz[g] * sz >= cos_flat:
                    done[g] = True
                    label[g] = next_label
                    stack.append(g)
        next_label += 1
    return np.asarray(label, dtype=out.dtype)


def _face_components(mesh, keep: np.ndarray) -> np.ndarray:
    """(F,) int: component label of each face, joining faces across the ``keep`` edges."""
    pairs = mesh.face_adjacency[keep]
    n = len(mesh.faces)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _characterize_region(mesh, faces, patches, curved, options) -> list[Draft]:
    """Facets, segments or points for one smooth region (faces: (k,) int).

    Planar patches much larger than the region's median patch are taken apart from the rest:
    alone (a flat face running into a fillet) they are facets; several joined (the flat strips
    of a coarsely tessellated cylinder) they are tested like any curved patch. ``curved``
    collects the faces of each curved patch; drafts refer to it by index.
    """
    groups = _groups(patches, faces)
    if len(groups) <= 2:
        return [d for g in groups for d in facets(mesh, g)]
    areas = np.array([a.sum() for a in (mesh.area_faces[g] for g in groups)])
    big = areas >= options.facet_area_ratio * np.median(areas)
    drafts: list[Draft] = []
    for chosen, fallback in ((big, "facets"), (~big, "points")):
        part = np.concatenate([g for g, b in zip(groups, chosen) if b] or [np.zeros(0, int)])
        for component in _split(mesh, part, np.radians(options.sharp_angle)):
            drafts += _curved(mesh, component, patches, curved, options, fallback)
    return drafts


def _split(mesh, faces: np.ndarray, sharp: float) -> list[np.ndarray]:
    """Connected components (across smooth edges) of a set of faces."""
    if len(faces) == 0:
        return []
    # Only the adjacency pairs touching these faces (a (F,) lookup, not a scan of every pair):
    # linear in the size of the set, however many sets the mesh is cut into.
    pairs = np.unique(mesh.pairs_of_faces[faces].ravel())
    pairs = pairs[pairs >= 0]
    local = np.full(len(mesh.faces), -1, dtype=np.int64)
    local[faces] = np.arange(len(faces))
    ends = local[mesh.face_adjacency[pairs]]
    ends = ends[(ends >= 0).all(axis=1) & (mesh.face_adjacency_angles[pairs] < sharp)]
    k = len(faces)
    graph = coo_matrix((np.ones(len(ends)), (ends[:, 0], ends[:, 1])), shape=(k, k))
    labels = connected_components(graph, directed=False)[1]
    components = [faces[g] for g in _groups(labels)]
    return sorted(components, key=lambda c: int(c.min()))  # by their lowest face id


def _curved(mesh, faces, patches, curved, options, fallback: str = "points") -> list[Draft]:
    """Elements of a patch: segments if it is ruled; facets if it has at most 2 planes, or
    few planes (see ``faceted_limit``), or ``fallback`` says so; points otherwise."""
    groups = np.unique(patches[faces])
    flat = np.radians(options.flat_angle)
    chains = None if len(groups) <= 2 else rulings(mesh, faces, flat)
    faceted = fallback == "facets" or len(groups) <= options.faceted_limit
    if len(groups) <= 2 or (chains is None and faceted):
        return [d for g in _groups(patches, faces) for d in facets(mesh, g)]
    region = len(curved)
    singular = np.zeros(0, np.int64)
    if chains is not None:  # a cone's apex ends every ruling: it stands for none of them
        uses = np.bincount(np.concatenate(chains))
        singular = np.flatnonzero(uses >= 3)
    curved.append((faces, singular))
    if chains is not None:
        return segments(mesh, faces, chains, region, options.segment_spacing)
    return _points(mesh, faces, region, options.point_spacing)


# --- points ----------------------------------------------------------------------------------


def _points(mesh, faces, region, spacing) -> list[Draft]:
    """One point per vertex of the patch (thinned), normal from the patch's faces only.

    The normal is the angle-weighted mean of the normals of the faces around the vertex.
    """
    tri = mesh.faces[faces]
    with np.errstate(invalid="ignore", divide="ignore"):  # zero-area slivers weigh nothing
        angles = np.nan_to_num(mesh.face_angles[faces])  # (k, 3): corner angles weigh normals
    outward = np.zeros_like(mesh.vertices)
    for k in range(3):
        np.add.at(outward, tri[:, k], mesh.face_normals[faces] * angles[:, k, None])
    ids = np.unique(tri)
    keep = thin(mesh.vertices[ids], spacing)
    drafts = []
    for v in ids[keep]:
        element = Element(ElementKind.POINT, mesh.vertices[[v]], -outward[v])
        drafts.append(Draft(element, {int(v)}, region))
    return drafts


# --- adjacency -------------------------------------------------------------------------------


def _adjacency(mesh, drafts: list[Draft], curved: list) -> tuple[tuple[int, int], ...]:
    """Neighbour pairs: a shared mesh vertex, or (unless both are facets) a mesh edge between.

    With A the (vertex x element) incidence of :func:`_owners` and M the mesh's edges, the
    pairs are the nonzeros of A^T A and A^T M A: sparse products, linear in the mesh's size.
    """
    from scipy.sparse import csr_matrix

    vertices, elements = _owners(mesh, drafts, curved)
    n, m = len(mesh.vertices), len(drafts)
    A = csr_matrix((np.ones(len(vertices)), (vertices, elements)), shape=(n, m))
    e = np.asarray(mesh.edges_unique)
    M = csr_matrix((np.ones(2 * len(e)), (e.ravel(), e[:, ::-1].ravel())), shape=(n, n))
    facet = np.array([d.element.kind is ElementKind.FACET for d in drafts], dtype=bool)
    shared = (A.T @ A).tocoo()
    across = (A.T @ (M @ A)).tocoo()
    keep = ~(facet[across.row] & facet[across.col])
    i = np.concatenate([shared.row, across.row[keep]])
    j = np.concatenate([shared.col, across.col[keep]])
    pairs = np.unique(np.column_stack([i, j])[i < j], axis=0)
    return tuple((int(a), int(b)) for a, b in pairs)


def _owners(mesh, drafts: list[Draft], curved: list) -> tuple[np.ndarray, np.ndarray]:
    """Which element stands for which mesh vertex: (k,) vertex ids and (k,) element ids.

    A segment or a point also stands for the vertices of its curved patch nearest to it along
    the mesh (those of dropped rulings or points), so thinning keeps neighbours connected. Each
    patch is searched on its own vertices only (local indices), so the cost is linear in the
    mesh's size however many patches it has.
    """
    n = len(mesh.vertices)
    owned = [(v, i) for i, d in enumerate(drafts) for v in d.owned]
    vertices = [np.array([v for v, _ in owned], dtype=np.int64)]
    elements = [np.array([i for _, i in owned], dtype=np.int64)]
    by_region: dict[int, dict[int, int]] = {}
    for i, d in enumerate(drafts):
        if d.region >= 0:
            by_region.setdefault(d.region, {}).update({v: i for v in d.owned})
    edges, lengths = np.asarray(mesh.edges_unique), np.asarray(mesh.edges_unique_length)
    # Edges incident to each vertex (CSR), to find a patch's edges without scanning them all.
    ends = edges.ravel()
    order = np.argsort(ends, kind="stable")
    start = np.searchsorted(ends[order], np.arange(n + 1))
    local = np.full(n, -1, dtype=np.int64)
    for region, (faces, singular) in enumerate(curved):
        source_owner = by_region.get(region)
        if not source_owner:
            continue
        patch = np.unique(mesh.faces[faces])
        local[patch] = np.arange(len(patch))
        incident = np.concatenate([order[start[v] : start[v + 1]] for v in patch]) // 2
        incident = np.unique(incident)
        ends_local = local[edges[incident]]
        sub = (ends_local >= 0).all(axis=1)
        k = len(patch)
        graph = coo_matrix(
            (lengths[incident[sub]], (ends_local[sub, 0], ends_local[sub, 1])), shape=(k, k)
        ).tocsr()
        sources = np.array(sorted(source_owner))
        _, _, nearest = dijkstra(
            graph, directed=False, indices=local[sources], min_only=True, return_predecessors=True
        )
        free = np.ones(k, dtype=bool)
        free[local[sources]] = False
        inside = local[singular]
        free[inside[inside >= 0]] = False
        free &= nearest >= 0
        owner_of = np.array([source_owner[int(v)] for v in patch[nearest[free]]], dtype=np.int64)
        vertices.append(patch[free])
        elements.append(owner_of)
        local[patch] = -1
    return np.concatenate(vertices), np.concatenate(elements)


__all__ = [
    "DEFAULT_UNITS",
    "Characterization",
    "CharacterizeOptions",
    "characterize",
    "characterize_mesh",
    "drop_outward",
    "drop_outward_as_read",
    "without_elements",
    "load_mesh",
    "repair_mesh",
    "winding_number",
]


def winding_number(mesh, points) -> np.ndarray:
    """Generalised winding number of a closed triangle mesh at points (exact inside test).

    Needs no spatial index (``trimesh``'s ``contains`` needs ``rtree``); meshes whose closed parts
    overlap give the number of parts around a point.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Outward-wound triangles.
    points : (p, 3) float

    Returns
    -------
    w : (p,) float
        About 1 inside, 0 outside, 1/2 on a face.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    out = np.empty(len(pts))
    tri = np.asarray(mesh.triangles)
    for start in range(0, len(pts), 64):
        rel = tri[None, :, :, :] - pts[start : start + 64, None, None, :]  # (p, F, 3, 3)
        a, b, c = rel[..., 0, :], rel[..., 1, :], rel[..., 2, :]
        la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        dot = lambda u, v: np.einsum("pfi,pfi->pf", u, v)  # noqa: E731
        denom = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
        out[start : start + 64] = np.arctan2(det, denom).sum(axis=1) / (2 * np.pi)
    return out
