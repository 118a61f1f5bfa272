"""Surface elements and element models (paper section 2, docs/formats.md ``*.model.json``).

An element is a convex facet, a line segment or a discrete point with one unit inward normal. A
contact on it sits at a convex combination of its vertices (eq 7); the vertex grasp matrices
``G_ij`` (eq 19) span every grasp matrix the element allows, which is what the eligibility
criterion needs. A :class:`Model` is the elements of one object and which of them are neighbours.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from closure_nlp.base.files import load_json, write_json
from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.base.validation import (
    as_points,
    as_unit_vector,
    as_units,
    as_vector,
    check_keys,
    is_whole,
    parse_choice,
)
from closure_nlp.contact.accuracy import NO_TOLERANCE, ModelTolerance, tolerance_from_dict
from closure_nlp.contact.contact_set import as_reference_point, cross, grasp_matrices, local_frame


# The same shape as contact_set.ContactType by choice: each string enum names its own field and
# kind in parse errors; parse_choice holds the logic they share.
class ElementKind(str, Enum):
    """The kind of a surface element, spelled as in a model file's ``kind``: ``"facet"`` (a
    planar convex polygon), ``"segment"`` (a line segment) or ``"point"``."""

    FACET = "facet"
    SEGMENT = "segment"
    POINT = "point"

    @classmethod
    def parse(cls, value, field: str = "kind") -> ElementKind:
        return parse_choice(cls, value, field, "element kind")


@dataclass(frozen=True, eq=False)
class Element:
    """One surface element.

    Attributes
    ----------
    kind : ElementKind
    vertices : (k, 3) float
        A facet's vertices in order around its boundary (k >= 3), a segment's two ends, a point.
    inward_normal : (3,) float
        Unit normal pointing into the object; normalised on creation.
    label : str
        Free text (e.g. ``"crown"``), kept through save and load.
    name : str
        How errors refer to this element, e.g. ``"elements[12]"``.
    tolerance : ModelTolerance
        How far the surface this element stands for leaves it (position and normal): 0 for a
        flat face, about half the angle between neighbours for a facet of a faceted cylinder
        (``characterize`` measures it). A contact on the element inherits it.
    """

    kind: ElementKind
    vertices: np.ndarray
    inward_normal: np.ndarray
    label: str = ""
    name: str = field(default="element", compare=False)
    tolerance: ModelTolerance = NO_TOLERANCE
    tolerances: Tolerances = field(default=DEFAULT_TOLERANCES, repr=False, compare=False)
    # The point torques are taken about (None: the origin); a Model gives its own to each element.
    reference_point: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        kind = ElementKind.parse(self.kind, f"{self.name}.kind")
        set_(self, "kind", kind)
        set_(self, "vertices", as_points(self.vertices, f"{self.name}.vertices"))
        set_(
            self, "inward_normal", as_unit_vector(self.inward_normal, f"{self.name}.inward_normal")
        )
        if not isinstance(self.label, str):
            raise TypeError(f"{self.name}.label: expected text, got {self.label!r}")
        if not isinstance(self.tolerance, ModelTolerance):
            raise TypeError(
                f"{self.name}.tolerance: expected a ModelTolerance, got {self.tolerance!r}"
            )
        {
            ElementKind.FACET: _check_facet,
            ElementKind.SEGMENT: _check_segment,
            ElementKind.POINT: _check_point,
        }[kind](self.vertices, self.inward_normal, self.name, self.tolerances.geometry)
        self.vertices.flags.writeable = False

    @property
    def centroid(self) -> np.ndarray:
        """(3,) float: the position at equal weights (for a facet, not its area centre)."""
        return self.vertices.mean(axis=0)

    @property
    def size(self) -> float:
        """Largest distance between two vertices (0 for a point)."""
        return _diameter(self.vertices)

    def position(self, weights) -> np.ndarray:
        """Contact position ``sum_j c_j v_j`` (eq 7) for barycentric ``weights`` (k,)."""
        return simplex_weights(weights, len(self.vertices), f"{self.name}.weights") @ self.vertices

    def grasp_matrices(self, torque_scale: float = 1.0) -> np.ndarray:
        """(k, 6, 4) float: the vertex grasp matrices ``G_ij`` (eq 19)."""
        r = self.vertices if self.reference_point is None else self.vertices - self.reference_point
        return grasp_matrices(r, self.inward_normal, torque_scale)

    def to_dict(self) -> dict:
        out = {
            "kind": self.kind.value,
            "vertices": self.vertices.tolist(),
            "inward_normal": self.inward_normal.tolist(),
        }
        if self.label:
            out["label"] = self.label
        if self.tolerance:
            out["tolerance"] = self.tolerance.to_dict()
        return out


def simplex_weights(weights, count: int, field: str, slack: float = 1e-9) -> np.ndarray:
    """Validate barycentric weights: ``count`` finite numbers ``>= 0`` summing to 1.

    Round-off up to ``slack`` (a solver's ``-1e-12``) is accepted and removed by clipping and
    renormalising.
    """
    c = as_vector(weights, field, count)
    if c.min() < -slack or abs(c.sum() - 1.0) > slack * count:
        raise ValueError(f"{field}: weights must be >= 0 and sum to 1, got {c.tolist()!r}")
    c = np.maximum(c, 0.0)
    return c / c.sum()


def _diameter(vertices: np.ndarray, block: int = 256) -> float:
    """Largest distance between two vertices, in O(k log k) time and O(k) memory for a planar
    set (rotating calipers on its convex hull), else by pairwise blocks of ``block`` rows."""
    v = np.asarray(vertices, dtype=float)
    if len(v) > block:
        hull = _planar_hull(v)
        if hull is not None:
            return _caliper_diameter(hull)
    best = 0.0
    for start in range(0, len(v), block):
        diff = v[start : start + block, None, :] - v[None, :, :]
        best = max(best, float((diff**2).sum(-1).max()))
    return float(np.sqrt(best))


def _planar_hull(v: np.ndarray) -> np.ndarray | None:
    """Counter-clockwise 2-D hull vertices of points that lie in one plane, else None."""
    from scipy.spatial import ConvexHull, QhullError

    centred = v - v.mean(axis=0)
    _, sing, vt = np.linalg.svd(centred, full_matrices=False)
    if not sing[2] <= 1e-12 * sing[0] * np.sqrt(len(v)):
        return None
    xy = centred @ vt[:2].T
    try:
        return xy[ConvexHull(xy).vertices]
    except (QhullError, ValueError):
        return None


def _caliper_diameter(xy: np.ndarray) -> float:
    """Diameter of a convex polygon (h, 2), counter-clockwise: for each edge, the vertex
    farthest from its line (advanced monotonically) is a candidate for both of its ends."""
    h = len(xy)
    if h <= 3:
        diff = xy[:, None, :] - xy[None, :, :]
        return float(np.sqrt((diff**2).sum(-1).max()))

    def area(a, b, c):
        return abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    best, j = 0.0, 1
    for i in range(h):
        a, b = xy[i], xy[(i + 1) % h]
        while area(a, b, xy[(j + 1) % h]) > area(a, b, xy[j]):
            j = (j + 1) % h
        for end in (a, b):
            best = max(best, float(((end - xy[j]) ** 2).sum()))
    return float(np.sqrt(best))


COINCIDENT = 1e-12  # two coordinates closer than this relative to their size are one point


def _check_point(vertices, normal, name, tol) -> None:
    if len(vertices) != 1:
        raise ValueError(f"{name}: a point has exactly 1 vertex, got {len(vertices)}")


def _check_segment(vertices, normal, name, tol) -> None:
    if len(vertices) != 2:
        raise ValueError(f"{name}: a segment has exactly 2 vertices, got {len(vertices)}")
    span = vertices[1] - vertices[0]
    length = float(np.linalg.norm(span))
    # Distinct within the precision of its coordinates; small against the part: Model's check.
    if not length > COINCIDENT * float(np.abs(vertices).max()):
        raise ValueError(f"{name}: the segment's two vertices coincide ({vertices[0].tolist()})")
    off = abs(float(normal @ span)) / length
    if off > tol:
        raise ValueError(
            f"{name}.inward_normal: not perpendicular to the segment (|cos| = {off:.3g} > {tol:g})"
        )


def _check_facet(vertices, normal, name, tol) -> None:
    k = len(vertices)
    if k < 3:
        raise ValueError(f"{name}: a facet needs at least 3 vertices, got {k}")
    size = _diameter(vertices)
    centred = vertices - vertices.mean(axis=0)
    _, sing, vt = np.linalg.svd(centred, full_matrices=False)
    if not sing[1] > tol * size * np.sqrt(k):
        raise ValueError(f"{name}: the facet's vertices are collinear (no area)")
    plane = vt[2]
    deviation = float(np.abs(centred @ plane).max())
    if deviation > tol * size:
        raise ValueError(
            f"{name}: facet is not planar: a vertex is {deviation:.3g} off its plane "
            f"(allowed {tol:g} x size {size:.3g})"
        )
    off = float(np.linalg.norm(cross(normal, plane)))
    if off > tol:
        raise ValueError(
            f"{name}.inward_normal: not perpendicular to the facet (|sin| = {off:.3g} > {tol:g})"
        )
    # In the facet's plane: every turn has the same sign and the turns add up to one revolution
    # (a star polygon turns the same way at every corner too, but twice round).
    frame = local_frame(plane)[:, 1:]
    xy = centred @ frame
    edges = np.roll(xy, -1, axis=0) - xy
    lengths = np.linalg.norm(edges, axis=1)
    if lengths.min() <= tol * size:
        j = int(np.argmin(lengths))
        raise ValueError(f"{name}: facet vertices {j} and {(j + 1) % k} coincide")
    nxt = np.roll(edges, -1, axis=0)
    turns = np.arctan2(edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0], (edges * nxt).sum(1))
    straight = np.abs(turns) <= tol
    signs = np.sign(turns[~straight])
    if len(set(signs.tolist())) > 1 or abs(abs(turns.sum()) - 2 * np.pi) > 1e-6:
        raise ValueError(f"{name}: facet is not convex, or its vertices are not in boundary order")


# --- models ----------------------------------------------------------------------------------

MODEL_KEYS = {
    "name",
    "units",
    "reference_point",
    "elements",
    "adjacency",
    "mesh",
    "description",
    "source",
    "up",
    "tolerance",
}
ELEMENT_KEYS = {"kind", "vertices", "inward_normal", "label", "tolerance"}


@dataclass(frozen=True, eq=False)
class Model:
    """The elements of one object and their neighbourhoods.

    Attributes
    ----------
    elements : tuple of Element
        Element ids are positions in this tuple.
    adjacency : tuple of (int, int)
        Undirected neighbour pairs, kept as given.
    name : str
    units : str
        Length unit of every coordinate: ``m``, ``cm``, ``mm``, ``in``, or ``""`` (not said);
        any other is refused.
    mesh : str or None
        Path of a mesh for drawing, relative to ``base_dir``.
    base_dir : Path or None
        Directory of the model file, if it came from one.
    allow_outside_mesh : bool
        Let ``mesh`` resolve outside ``base_dir`` (refused by default: a model file from
        elsewhere must not make ``show`` read and embed any file of the machine).
    reference_point : (3,) float
        The point torques are taken about (None or absent in a file: the origin). Every element
        of the model gets it, so its vertex grasp matrices take moments about it.
    up : str
        The model's up axis for pictures: ``x``, ``y`` or ``z``.
    tolerance : ModelTolerance
        How far the real part's contact points and normals may lie from the elements'
        (``characterize`` measures it against the mesh; none by default).
    unusable : tuple of int
        Ids of elements no contact may sit on (too small for a margin, see
        :func:`closure_nlp.placement.margin.with_margin`): they keep their ids, but selection never
        picks
        them, they are nobody's neighbour, and a contact set naming one is refused.
    """

    elements: tuple[Element, ...]
    adjacency: tuple[tuple[int, int], ...] = ()
    name: str = "model"
    units: str = ""
    mesh: str | None = None
    description: str = ""
    base_dir: Path | None = field(default=None, compare=False)
    allow_outside_mesh: bool = field(default=False, compare=False, repr=False)
    reference_point: np.ndarray | None = None
    up: str = "z"
    tolerance: ModelTolerance = NO_TOLERANCE
    unusable: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.tolerance, ModelTolerance):
            raise TypeError(f"tolerance: expected a ModelTolerance, got {self.tolerance!r}")
        elements = tuple(self.elements)
        if not elements:
            raise ValueError("elements: a model needs at least one element, got none")
        for i, e in enumerate(elements):
            if not isinstance(e, Element):
                raise TypeError(f"elements[{i}]: expected an Element, got {type(e).__name__}")
        if self.up not in ("x", "y", "z"):
            raise ValueError(f"up: expected x, y or z, got {self.up!r}")
        as_units(self.units)
        point = as_reference_point(self.reference_point, "reference_point")
        object.__setattr__(self, "reference_point", point)
        elements = tuple(_about(e, point) for e in elements)
        _check_sizes(elements)
        object.__setattr__(self, "elements", elements)
        pairs = _as_pairs(self.adjacency, len(elements))
        object.__setattr__(self, "adjacency", pairs)
        ids = {_as_id(e, f"unusable[{k}]", len(elements)) for k, e in enumerate(self.unusable)}
        unusable = tuple(sorted(ids))
        object.__setattr__(self, "unusable", unusable)
        neighbours: list[set[int]] = [set() for _ in elements]
        for a, b in pairs:
            if a in unusable or b in unusable:
                continue
            neighbours[a].add(b)
            neighbours[b].add(a)
        object.__setattr__(self, "_neighbours", tuple(tuple(sorted(s)) for s in neighbours))

    def __len__(self) -> int:
        return len(self.elements)

    @property
    def usable(self) -> np.ndarray:
        """(n,) bool: the elements a contact may sit on."""
        mask = np.ones(len(self.elements), bool)
        mask[list(self.unusable)] = False
        return mask

    def neighbours(self, element_id: int) -> tuple[int, ...]:
        """Ids of the elements adjacent to ``element_id``, ascending."""
        return self._neighbours[self.check_id(element_id, "element")]

    def check_id(self, element_id, field: str) -> int:
        """``element_id`` as an int, or a ``ValueError`` naming ``field`` if it is not an id."""
        if not is_whole(element_id):
            raise TypeError(f"{field}: expected an element id, got {element_id!r}")
        if not 0 <= element_id < len(self.elements):
            raise ValueError(
                f"{field}: element id {element_id} out of range 0..{len(self.elements) - 1}"
            )
        return int(element_id)

    def counts(self) -> dict[str, int]:
        """Number of elements of each kind, e.g. ``{"facet": 9, "segment": 16, "point": 224}``."""
        return {k.value: sum(e.kind is k for e in self.elements) for k in ElementKind}

    @property
    def radius(self) -> float:
        """The part's radius about the reference point (:func:`closure_nlp.model.scale.part_radius`
        of the element vertices): the part's characteristic length."""
        return part_radius(np.vstack([e.vertices for e in self.elements]), self.reference_point)

    @property
    def mesh_path(self) -> Path | None:
        """The mesh's path, resolved; ``ValueError`` if it leaves the model's folder (symbolic
        links and ``..`` included) and ``allow_outside_mesh`` is not set."""
        if self.mesh is None:
            return None
        base = (self.base_dir or Path(".")).resolve()
        path = (base / self.mesh).resolve()
        if not self.allow_outside_mesh and not path.is_relative_to(base):
            raise ValueError(
                f"mesh: {self.mesh!r} resolves outside the model's folder {base} "
                "(refused; --allow-outside-mesh reads it)"
            )
        return path

    def to_dict(self) -> dict:
        out = {"name": self.name, "units": self.units}
        out["reference_point"] = self.reference_point.tolist()
        if self.up != "z":
            out["up"] = self.up
        if self.description:
            out["description"] = self.description
        out["elements"] = [e.to_dict() for e in self.elements]
        out["adjacency"] = [list(p) for p in self.adjacency]
        if self.mesh is not None:
            out["mesh"] = self.mesh
        if self.tolerance:
            out["tolerance"] = self.tolerance.to_dict()
        return out


def part_size(elements) -> float:
    """The part's size: the largest side of the bounding box of its elements' vertices."""
    lo = np.min([e.vertices.min(axis=0) for e in elements], axis=0)
    hi = np.max([e.vertices.max(axis=0) for e in elements], axis=0)
    return float((hi - lo).max())


def _check_sizes(elements) -> None:
    """Refuse a facet or segment too small to tell from a point against the part's size (the
    element's own checks judge its shape at any scale: a sliver is refused there)."""
    size = part_size(elements)
    for e in elements:
        if e.kind is ElementKind.POINT:
            continue
        extent = float(np.ptp(e.vertices, axis=0).max())
        if not extent > e.tolerances.geometry * size:
            raise ValueError(
                f"{e.name}: the {e.kind.value} is {extent:.3g} across, degenerate against the "
                f"part's size {size:.3g} (at least {e.tolerances.geometry:g} x size)"
            )


def _about(element: Element, point: np.ndarray) -> Element:
    """``element`` taking moments about ``point`` (a shallow copy: nothing is validated again)."""
    if element.reference_point is not None and np.array_equal(element.reference_point, point):
        return element
    if element.reference_point is None and not point.any():
        return element
    out = copy.copy(element)
    object.__setattr__(out, "reference_point", point)
    return out


def _as_id(value, field: str, count: int) -> int:
    if not is_whole(value):
        raise TypeError(f"{field}: expected an element id, got {value!r}")
    if not 0 <= value < count:
        raise ValueError(f"{field}: element id {value} out of range 0..{count - 1}")
    return int(value)


def _as_pair(pair, field: str, count: int) -> tuple[int, int]:
    if not isinstance(pair, (list, tuple)) or len(pair) != 2:
        raise ValueError(f"{field}: expected a pair of element ids, got {pair!r}")
    if not all(is_whole(v) for v in pair):
        raise TypeError(f"{field}: expected a pair of element ids, got {pair!r}")
    ids = [_as_id(v, field, count) for v in pair]
    if ids[0] == ids[1]:
        raise ValueError(f"{field}: an element is not its own neighbour ({ids[0]})")
    return ids[0], ids[1]


def _as_pairs(adjacency, count: int) -> tuple[tuple[int, int], ...]:
    """Every adjacency pair checked: at once when they are all pairs of plain ints (a model
    read from a file or copied: thousands of pairs on a real mesh, checked one by one each time
    a model is built, cost more than a one-seed plan's selection); otherwise, or when one is
    bad, pair by pair, so that the error names it."""
    pairs = list(adjacency)
    plain = all(
        type(p) in (list, tuple) and len(p) == 2 and type(p[0]) is int and type(p[1]) is int
        for p in pairs
    )
    if plain and pairs:
        try:
            ids = np.array(pairs, dtype=np.int64)
        except OverflowError:
            ids = None
        if (
            ids is not None
            and ids.min() >= 0
            and ids.max() < count
            and (ids[:, 0] != ids[:, 1]).all()
        ):
            return tuple((a, b) for a, b in pairs)
    return tuple(_as_pair(pair, f"adjacency[{k}]", count) for k, pair in enumerate(pairs))


def model_from_dict(data, base_dir=None, tolerances: Tolerances = DEFAULT_TOLERANCES) -> Model:
    """Build a :class:`Model` from the ``*.model.json`` layout of docs/formats.md."""
    check_keys(data, "file", MODEL_KEYS, required={"elements"})
    entries = data["elements"]
    if not isinstance(entries, list):
        raise TypeError(f"elements: expected a list, got {type(entries).__name__}")
    elements = []
    for i, entry in enumerate(entries):
        name = f"elements[{i}]"
        check_keys(entry, name, ELEMENT_KEYS, required={"kind", "vertices", "inward_normal"})
        elements.append(
            Element(
                entry["kind"],
                entry["vertices"],
                entry["inward_normal"],
                entry.get("label", ""),
                name=name,
                tolerance=tolerance_from_dict(entry.get("tolerance"), f"{name}.tolerance"),
                tolerances=tolerances,
            )
        )
    adjacency = data.get("adjacency", [])
    if not isinstance(adjacency, list):
        raise TypeError(f"adjacency: expected a list of pairs, got {type(adjacency).__name__}")
    for key in ("name", "units", "mesh", "description", "up"):
        if key in data and not isinstance(data[key], str):
            raise TypeError(f"{key}: expected text, got {data[key]!r}")
    return Model(
        tuple(elements),
        tuple(adjacency),
        data.get("name", "model"),
        data.get("units", ""),
        data.get("mesh"),
        data.get("description", ""),
        Path(base_dir) if base_dir is not None else None,
        reference_point=data.get("reference_point"),
        up=data.get("up", "z"),
        tolerance=tolerance_from_dict(data.get("tolerance")),
    )


def load_model(path, tolerances: Tolerances = DEFAULT_TOLERANCES) -> Model:
    """Read and validate a ``*.model.json`` file."""
    path = Path(path)
    return model_from_dict(load_json(path), path.parent, tolerances)


def save_model(model: Model, path) -> Path:
    """Write ``model`` as ``*.model.json``, atomically."""
    return write_json(path, model.to_dict())


def part_radius(points, reference_point) -> float:
    """Radius of the part's bounding sphere about the reference point: the largest distance from
    ``reference_point`` (3,) to ``points`` (n, 3) (a model's element vertices). The one
    definition of the radius every command prints and scales by."""
    pts = np.asarray(points, dtype=float) - np.asarray(reference_point, dtype=float)
    return float(np.sqrt((pts**2).sum(axis=1).max()))


def nearest_weights(vertices: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Barycentric weights of the point of ``conv(vertices)`` nearest to ``point``: (k,)."""
    k = len(vertices)
    if k == 1:
        return np.ones(1)
    # about the centroid, over the element's size: the same weights in any unit and anywhere
    centre = vertices.mean(axis=0)
    size = float(np.max(np.linalg.norm(vertices - centre, axis=1)))
    size = size if size > 0.0 else 1.0
    A = np.vstack([(vertices - centre).T / size, 1e3 * np.ones((1, k))])  # sum-to-one, stiff
    b = np.concatenate([(point - centre) / size, [1e3]])
    from scipy.optimize import nnls  # here: scipy.optimize costs 0.2 s of every start

    w, _ = nnls(A, b)
    return w / w.sum()


__all__ = [
    "Element",
    "ElementKind",
    "Model",
    "load_model",
    "model_from_dict",
    "nearest_weights",
    "part_radius",
    "save_model",
    "simplex_weights",
]
