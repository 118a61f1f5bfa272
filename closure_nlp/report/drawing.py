"""Pictures of element models and contacts (matplotlib, headless) and 3-D scenes (trimesh).

:func:`draw_model` draws into any 3-D axes, so a caller can draw a model once and then add
contacts in several sizes (initial contacts small, final ones large) with :func:`draw_contacts`.
:func:`render_model` writes a picture file; :func:`export_scene` writes an interactive GLB or HTML.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from closure_nlp.base.files import write_atomic
from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.model.elements import ElementKind, Model

FACET_COLOUR = np.array([0.62, 0.74, 0.88])
SEGMENT_COLOUR = np.array([0.12, 0.31, 0.47])
POINT_COLOUR = np.array([0.16, 0.5, 0.38])
HIGHLIGHT_COLOUR = np.array([0.95, 0.55, 0.15])
MARKED_COLOUR = np.array([0.85, 0.1, 0.55])  # elements a check refused (shown, not hidden)
FIXED_COLOUR = "black"  # contacts already in place
UNUSABLE_COLOUR = np.array([0.6, 0.6, 0.6])  # elements no contact may use (excluded, margins)
CONTACT_COLOUR = "#c0392b"
LIGHT = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
PICTURE_SUFFIXES = {".png", ".pdf", ".svg", ".jpg", ".jpeg"}
SCENE_SUFFIXES = {".glb", ".html"}


# pyplot keeps its figures in one global registry: figures are drawn by one thread at a time.
PLOT_LOCK = threading.RLock()


def pyplot():
    """matplotlib.pyplot on the headless Agg backend (draw while holding :data:`PLOT_LOCK`
    when other threads may draw too)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def counts_text(model: Model) -> str:
    """``"57 facets, 0 segments, 0 points"``."""
    return ", ".join(f"{n} {kind}s" for kind, n in model.counts().items())


def contact_arrays(contacts) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m, 3) and inward normals (m, 3) of a ContactSet, Contacts or (pos, normals)."""
    if contacts is None:
        return np.zeros((0, 3)), np.zeros((0, 3))
    if isinstance(contacts, ContactSet):
        contacts = contacts.contacts
    if isinstance(contacts, tuple) and len(contacts) == 2 and not isinstance(contacts[0], Contact):
        pos, nrm = (np.atleast_2d(np.asarray(a, dtype=float)) for a in contacts)
    else:
        items = list(contacts)
        if not all(isinstance(c, Contact) for c in items):
            raise TypeError("contacts: expected a ContactSet, Contacts or (positions, normals)")
        pos = np.array([c.position for c in items]).reshape(-1, 3)
        nrm = np.array([c.inward_normal for c in items]).reshape(-1, 3)
    if pos.shape != nrm.shape or pos.shape[1:] != (3,):
        raise ValueError(f"contacts: positions {pos.shape} and normals {nrm.shape} do not match")
    return pos, nrm


def model_extent(model: Model) -> float:
    """Largest side of the axis-aligned box around every element vertex."""
    pts = np.vstack([e.vertices for e in model.elements])
    return float(np.ptp(pts, axis=0).max()) or 1.0


def _shade(normals: np.ndarray, base: np.ndarray) -> np.ndarray:
    """(k, 3) RGB: ``base`` lit by a fixed light from the outward normals (-inward)."""
    lit = 0.68 + 0.32 * np.clip(-normals @ LIGHT, -1.0, 1.0)
    return np.clip(base[None, :] * lit[:, None], 0.0, 1.0)


def draw_model(
    model: Model,
    contacts=None,
    ax=None,
    *,
    highlight: Sequence[int] = (),
    marked: Sequence[int] = (),
    contact_sizes: float | Sequence[float] = 80.0,
    contact_colour: str = CONTACT_COLOUR,
    show_mesh: bool = True,
    title: str | None = None,
    view: tuple[float, float] = (22.0, -58.0),
    up: str | None = None,
    ids: bool = False,
    legend: bool = True,
    contact_label: str = "contacts",
    fixed: int = 0,
):
    """Draw a model's elements (and contacts) into 3-D axes.

    Parameters
    ----------
    model : Model
    contacts : ContactSet or sequence of Contact or (positions (m, 3), normals (m, 3)), optional
        Drawn as balls with arrows along their inward normals (pushing into the object).
    ax : mpl_toolkits.mplot3d.Axes3D, optional
        Axes to draw into; a new figure is made when omitted.
    highlight : sequence of int
        Element ids drawn in the highlight colour (e.g. the selected elements).
    marked : sequence of int
        Element ids drawn in the marking colour: elements a check refused (e.g. an inward
        normal that points out of the mesh), shown where they are.
    contact_sizes : float or (m,) float
        Marker areas of the contact balls (points^2).
    show_mesh : bool
        Also draw the model's mesh, faintly, when the model has one and it can be read.
    title : str, optional
        Default: the model's name and its element counts.
    view : (float, float)
        Elevation and azimuth in degrees.
    up : {"x", "y", "z"}, optional
        The model's axis drawn upwards (default: the model's ``up``).
    ids : bool
        Write each element's id beside it.
    legend : bool
        A legend of what is drawn (elements, chosen elements, contacts, reference point).
    contact_label : str
        Legend entry of ``contacts``.
    fixed : int
        The first ``fixed`` contacts were already in place (a plan's ``contacts.json`` lists
        them first): drawn black, as "fixed contacts".

    Contacts are drawn last and above everything else, so no facet hides them; a contact whose
    surface faces away from the viewer (on the far side of the part) is drawn hollow, with a
    dashed arrow. The chosen elements are outlined (facets), drawn thick (segments) or ringed
    (points) in the highlight colour, so the part stays visible under them.

    Returns
    -------
    ax : Axes3D
    """
    if ax is None:
        plt = pyplot()
        fig = plt.figure(figsize=(7.0, 6.0))
        ax = fig.add_subplot(projection="3d")
    up = model.up if up is None else up
    if up not in UP_AXES:
        raise ValueError(f"up: expected x, y or z, got {up!r}")
    ax._closure_axes = UP_AXES[up]  # every later drawing call on ax shows the same axis up
    ax.computed_zorder = False  # draw in call order: contacts last, on top
    ax._closure_view = view  # contacts drawn on ax later tell front from back by it
    chosen = {model.check_id(i, "highlight") for i in highlight}
    bad = {model.check_id(i, "marked") for i in marked}
    if show_mesh:
        _draw_mesh(ax, model)
    _draw_facets(ax, model, chosen, bad)
    _draw_segments(ax, model, chosen, bad)
    _draw_points(ax, model, chosen)
    if ids:
        for i, e in enumerate(model.elements):
            x, y, z = _shown(ax, e.centroid)
            ax.text(x, y, z, str(i), fontsize=6, color="#222222", zorder=20)
    p = _shown(ax, model.reference_point)
    ax.scatter(*p, marker="x", s=40, c="black", depthshade=False, zorder=5)
    draw_with_fixed(
        ax,
        contacts,
        fixed,
        sizes=contact_sizes,
        colour=contact_colour,
        scale=model_extent(model),
        label=contact_label,
    )
    _equal_aspect(ax, model, contacts)
    ax.view_init(*view)
    ax.set_title(title if title is not None else f"{model.name}: {counts_text(model)}")
    unit = f" [{model.units}]" if model.units else ""
    for axis, k in zip(("x", "y", "z"), ax._closure_axes):
        getattr(ax, f"set_{axis}label")("xyz"[k] + unit)
    if legend:
        update_legend(ax, model, chosen, bad)
    return ax


# Model axes shown as the picture's x, y, z (right-handed: a cyclic permutation).
UP_AXES = {"z": (0, 1, 2), "y": (2, 0, 1), "x": (1, 2, 0)}


def _shown(ax, points) -> np.ndarray:
    """Model coordinates (..., 3) as drawn on ``ax`` (its up axis last)."""
    return np.asarray(points, dtype=float)[..., list(getattr(ax, "_closure_axes", (0, 1, 2)))]


def update_legend(ax, model: Model | None = None, chosen=(), marked=()) -> None:
    """A legend of the element kinds present, the chosen elements, the reference point and
    every contact set drawn (by its label)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = list(getattr(ax, "_closure_legend", {}).values())
    if model is not None:
        counts = model.counts()
        kinds = [
            (counts["facet"], Patch(facecolor=FACET_COLOUR, edgecolor="#33415c", label="facets")),
            (counts["segment"], Line2D([], [], color=SEGMENT_COLOUR, lw=1.4, label="segments")),
            (
                counts["point"],
                Line2D([], [], color=POINT_COLOUR, marker="o", ls="", ms=3, label="points"),
            ),
            (
                len(chosen),
                Patch(facecolor="none", edgecolor=HIGHLIGHT_COLOUR, lw=2, label="chosen elements"),
            ),
            (len(marked), Patch(facecolor=MARKED_COLOUR, label="normal out of the mesh")),
            (len(model.unusable), Patch(facecolor=UNUSABLE_COLOUR, label="no contact here")),
            (1, Line2D([], [], color="black", marker="x", ls="", label="reference point")),
        ]
        ax._closure_model_legend = [h for n, h in kinds if n]
    handles = getattr(ax, "_closure_model_legend", []) + handles
    if handles:
        ax.legend(handles=handles, loc="upper left", fontsize=7, framealpha=0.85)


def _ids(model: Model, kind: ElementKind) -> list[int]:
    return [i for i, e in enumerate(model.elements) if e.kind is kind]


def _draw_mesh(ax, model: Model) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from closure_nlp.model.model_mesh import read_model_mesh

    mesh = read_model_mesh(model)  # a drawing aid only: missing or broken is one warning
    if mesh is None:
        return
    colours = _shade(-mesh.face_normals, np.array([0.85, 0.85, 0.85]))
    ax.add_collection3d(
        Poly3DCollection(
            _shown(ax, mesh.triangles),
            facecolors=np.c_[colours, np.full(len(colours), 0.12)],
            linewidths=0,
        )
    )


def _colour(i: int, base, chosen: set[int], marked: set[int], unusable=frozenset()):
    if i in marked:
        return MARKED_COLOUR
    if i in chosen:
        return HIGHLIGHT_COLOUR
    return UNUSABLE_COLOUR if i in unusable else base


def _eye(elev: float, azim: float) -> np.ndarray:
    """Unit direction from the part to matplotlib's eye for (elev, azim), in drawn axes."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _draw_facets(ax, model: Model, chosen: set[int], marked: set[int] = frozenset()) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ids = _ids(model, ElementKind.FACET)
    if not ids:
        return
    normals = np.array([model.elements[i].inward_normal for i in ids])
    unusable = set(model.unusable)
    # chosen facets keep their fill and get a thick outline: a filled highlight hid the part
    colours = np.array(
        [
            _shade(n[None], _colour(i, FACET_COLOUR, set(), marked, unusable))[0]
            for i, n in zip(ids, normals)
        ]
    )
    polygons = [_shown(ax, model.elements[i].vertices) for i in ids]
    picked = [i in chosen and i not in marked for i in ids]
    ax.add_collection3d(
        Poly3DCollection(
            polygons,
            facecolors=np.c_[colours, np.full(len(ids), 0.9)],
            edgecolors=[HIGHLIGHT_COLOUR if p else "#33415c" for p in picked],
            linewidths=[2.4 if p else 0.5 for p in picked],
        )
    )


def _draw_segments(ax, model: Model, chosen: set[int], marked: set[int] = frozenset()) -> None:
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    ids = _ids(model, ElementKind.SEGMENT)
    if not ids:
        return
    lines = [_shown(ax, model.elements[i].vertices) for i in ids]
    unusable = set(model.unusable)
    colours = np.array([_colour(i, SEGMENT_COLOUR, chosen, marked, unusable) for i in ids])
    widths = [3.0 if i in chosen or i in marked else 1.4 for i in ids]
    ax.add_collection3d(Line3DCollection(lines, colors=colours, linewidths=widths))


def _draw_points(ax, model: Model, chosen: set[int]) -> None:
    ids = _ids(model, ElementKind.POINT)
    if not ids:
        return
    pts = _shown(ax, np.array([model.elements[i].vertices[0] for i in ids]))
    picked = np.array([i in chosen for i in ids])
    plain = ~picked
    unusable = set(model.unusable)
    colours = np.array([_colour(i, POINT_COLOUR, set(), set(), unusable) for i in ids])
    if plain.any():
        ax.scatter(*pts[plain].T, c=colours[plain], s=6.0, depthshade=False)
    if picked.any():  # a ring around each chosen point
        ax.scatter(
            *pts[picked].T,
            s=30.0,
            facecolors="none",
            edgecolors=HIGHLIGHT_COLOUR,
            linewidths=1.6,
            depthshade=False,
        )


def draw_with_fixed(ax, contacts, fixed: int, *, sizes=80.0, colour=CONTACT_COLOUR, **options):
    """:func:`draw_contacts` of ``contacts`` whose first ``fixed`` were already in place: those
    black, as "fixed contacts" (``options``: ``scale``, ``label``... of the others)."""
    pos, nrm = contact_arrays(contacts)
    sizes = np.broadcast_to(np.asarray(sizes, dtype=float), (len(pos),))
    if fixed:
        scale = options.get("scale", 1.0)
        kept = (pos[:fixed], nrm[:fixed])
        draw_contacts(
            ax, kept, sizes=sizes[:fixed], colour=FIXED_COLOUR, scale=scale, label="fixed contacts"
        )
    draw_contacts(ax, (pos[fixed:], nrm[fixed:]), sizes=sizes[fixed:], colour=colour, **options)


def draw_contacts(
    ax,
    contacts,
    *,
    sizes: float | Sequence[float] = 80.0,
    colour: str = CONTACT_COLOUR,
    scale: float = 1.0,
    arrow_length: float | None = None,
    label: str | None = None,
) -> None:
    """Contacts as balls with arrows that end at the contact and point along its inward normal.

    Parameters
    ----------
    ax : Axes3D
    contacts : ContactSet or sequence of Contact or (positions (m, 3), normals (m, 3))
    sizes : float or (m,) float
        Marker areas in points^2 (small for initial contacts, large for final ones).
    scale : float
        Size of the object; arrows are ``0.15 * scale`` long unless ``arrow_length`` is given.
    label : str, optional
        Legend entry (the legend is redrawn with it); drawn above everything drawn before.

    On axes from :func:`draw_model`, a contact whose inward normal points towards the viewer
    (its surface faces away: the far side of the part) is drawn hollow with a dashed arrow,
    before the near ones.
    """
    pos, nrm = contact_arrays(contacts)
    if len(pos) == 0:
        return
    pos, nrm = _shown(ax, pos), _shown(ax, nrm)
    sizes = np.broadcast_to(np.asarray(sizes, dtype=float), (len(pos),))
    length = 0.15 * scale if arrow_length is None else arrow_length
    tails = pos - length * nrm
    view = getattr(ax, "_closure_view", None)
    far = np.zeros(len(pos), bool) if view is None else nrm @ _eye(*view) > 0.0
    for side in (far, ~far):  # the far side first, the near side over it
        if not side.any():
            continue
        back = side is far
        ax.quiver(
            *tails[side].T,
            *nrm[side].T,
            length=length,
            normalize=True,
            color=colour,
            linewidth=1.2 if back else 1.6,
            linestyle="--" if back else "-",
            alpha=0.6 if back else 1.0,
            arrow_length_ratio=0.3,
            zorder=30,
        )
        ax.scatter(
            *pos[side].T,
            s=sizes[side],
            c="white" if back else colour,
            edgecolors=colour if back else "black",
            linewidths=1.4 if back else 0.5,
            depthshade=False,
            alpha=1.0,
            zorder=31,
        )
    if label:
        from matplotlib.lines import Line2D

        entries = getattr(ax, "_closure_legend", {})
        size = float(np.sqrt(sizes.max()))
        entries[label] = Line2D(
            [],
            [],
            color=colour,
            marker="o",
            markeredgecolor="black",
            ms=size / 1.6,
            ls="-",
            lw=1.2,
            label=f"{label} (arrow: inward normal" + ("; hollow: far side)" if far.any() else ")"),
        )
        ax._closure_legend = entries
        if ax.get_legend() is not None:
            update_legend(ax)


def _equal_aspect(ax, model: Model, contacts) -> None:
    pts = [e.vertices for e in model.elements]
    pos, nrm = contact_arrays(contacts)
    if len(pos):
        pts += [pos, pos - 0.15 * model_extent(model) * nrm]
    pts = _shown(ax, np.vstack(pts))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))


def render_model(
    model: Model, path, contacts=None, *, loads=None, load_factors=None, **options
) -> Path:
    """Draw ``model`` (see :func:`draw_model` for ``options``) and write a picture, atomically.

    The format follows the suffix of ``path`` (.png, .pdf, .svg, .jpg). ``loads`` and
    ``load_factors``: load arrows (:func:`draw_loads`).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in PICTURE_SUFFIXES:
        raise ValueError(
            f"out: unsupported picture type {suffix or path.name!r} (use .png, .svg, .pdf)"
        )
    plt = pyplot()
    fig = plt.figure(figsize=(7.0, 6.0))
    try:
        ax = fig.add_subplot(projection="3d")
        draw_model(model, contacts, ax, **options)
        if loads is not None:
            draw_loads(ax, loads, model, load_factors)
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def save_figure(fig, path, dpi: int = 130) -> Path:
    """Write a matplotlib figure atomically, in the format of ``path``'s suffix."""
    path = Path(path)
    buffer = io.BytesIO()
    fig.savefig(
        buffer,
        format=path.suffix.lower().lstrip(".").replace("jpg", "jpeg"),
        dpi=dpi,
        bbox_inches="tight",
    )
    return write_atomic(path, buffer.getvalue())


# --- interactive scenes ----------------------------------------------------------------------


def build_scene(
    model: Model,
    contacts=None,
    *,
    highlight: Sequence[int] = (),
    marked: Sequence[int] = (),
    up: str | None = None,
):
    """A ``trimesh.Scene`` of the model: mesh, facets, segments (thin rods), points, contacts.

    The scene is turned so that the model's ``up`` axis (default: the model's) is the viewer's
    up (three.js: +y), as in the pictures, and its camera looks from the side where most
    contacts face it (:func:`scene_view`), framing the model and the contacts.
    """
    import trimesh

    chosen = {model.check_id(i, "highlight") for i in highlight}
    bad = {model.check_id(i, "marked") for i in marked}
    turn = _scene_turn(model.up if up is None else up)
    scene = trimesh.Scene()
    size = model_extent(model)
    from closure_nlp.model.model_mesh import read_model_mesh

    mesh = read_model_mesh(model)
    if mesh is not None:
        mesh.visual.face_colors = [200, 200, 200, 60]
        scene.add_geometry(mesh, geom_name="mesh")
    base = {
        ElementKind.FACET: FACET_COLOUR,
        ElementKind.SEGMENT: SEGMENT_COLOUR,
        ElementKind.POINT: POINT_COLOUR,
    }
    for i, element in enumerate(model.elements):
        colour = _colour(i, base[element.kind], chosen, bad) * 255
        part = _element_mesh(element, size, chosen=i in chosen)
        part.visual.face_colors = [*colour.astype(int).tolist(), 255]
        scene.add_geometry(part, geom_name=f"element_{i}")
    pos, nrm = contact_arrays(contacts)
    radius = 0.02 * size
    for k, (p, n) in enumerate(zip(pos, nrm)):
        ball = trimesh.creation.icosphere(2, radius=radius)
        ball.apply_translation(p - radius * n)  # above the surface: n points into the part
        arrow = trimesh.creation.cylinder(radius=0.005 * size, segment=[p - 0.15 * size * n, p])
        for name, part in (("contact", ball), ("normal", arrow)):
            part.visual.face_colors = [192, 57, 43, 255]
            scene.add_geometry(part, geom_name=f"{name}_{k}")
    rotation = np.eye(4)
    rotation[:3, :3] = turn
    for name in list(scene.geometry):
        scene.geometry[name].apply_transform(rotation)
    scene.camera.fov = (45.0, 45.0)
    scene.camera_transform = scene_view(scene.bounds, pos @ turn.T, nrm @ turn.T)
    return scene


def _scene_turn(up: str) -> np.ndarray:
    """(3, 3) rotation from model coordinates to the viewer's (three.js: y up), the axes as in
    the pictures (:data:`UP_AXES`: drawn x, y, then up)."""
    if up not in UP_AXES:
        raise ValueError(f"up: expected x, y or z, got {up!r}")
    a, b, c = UP_AXES[up]
    eye = np.eye(3)
    return np.array([eye[a], eye[c], -eye[b]])  # drawn (x, y, up) -> viewer (x, up, -y)


def _direction(elev: float, azim: float) -> np.ndarray:
    """Unit direction to the eye for matplotlib's (elev, azim), in the viewer's frame."""
    e, a = np.radians(elev), np.radians(azim)
    x, y, z = np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)
    return np.array([x, z, -y])


def scene_view(bounds: np.ndarray, positions: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(4, 4) camera transform (looking down its -z, y up) at the scene's centre, from the
    direction of the pictures' default view unless another shows more contacts from outside.

    A contact is seen when its outward normal (``-normals``) points towards the eye; among the
    views (elevations 22, 45, 10, 60 degrees, azimuths every 30 degrees) the one that sees the
    most contacts wins, the default first on a tie, then the one that sees them most squarely.
    """
    centre = bounds.mean(axis=0)
    radius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0])) or 1.0
    views = [(22.0, -58.0)] + [
        (e, a) for e in (22.0, 45.0, 10.0, 60.0) for a in range(-180, 180, 30)
    ]
    best, best_key = None, None
    for elev, azim in views:
        d = _direction(elev, azim)
        facing = -np.asarray(normals, dtype=float).reshape(-1, 3) @ d
        key = (int(np.sum(facing > 0.05)), float(np.sum(np.clip(facing, 0, None))))
        if best_key is None or key[0] > best_key[0]:
            best, best_key = d, key
    distance = 1.15 * radius / np.sin(np.radians(22.5))  # the sphere fills the 45 degree view
    z = best
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(z, x)
    transform = np.eye(4)
    transform[:3, :3] = np.column_stack([x, y, z])
    transform[:3, 3] = centre + distance * z
    return transform


def _element_mesh(element, size: float, chosen: bool = False):
    import trimesh

    v = element.vertices
    if element.kind is ElementKind.FACET:
        faces = [[0, j, j + 1] for j in range(1, len(v) - 1)]
        lifted = v - 0.002 * size * element.inward_normal  # just outside the object's surface
        both = np.vstack([lifted, lifted])
        faces = faces + [[len(v) + a, len(v) + c, len(v) + b] for a, b, c in faces]
        return trimesh.Trimesh(both, faces, process=False)
    if element.kind is ElementKind.SEGMENT:
        radius = (0.008 if chosen else 0.004) * size
        return trimesh.creation.cylinder(radius=radius, segment=v, sections=8)
    ball = trimesh.creation.icosphere(1, radius=(0.012 if chosen else 0.006) * size)
    ball.apply_translation(v[0])
    return ball


def export_scene(
    model: Model,
    contacts,
    path,
    *,
    highlight: Sequence[int] = (),
    marked: Sequence[int] = (),
    up: str | None = None,
    title: str | None = None,
) -> Path:
    """Write an interactive scene, atomically: ``.glb`` (binary glTF) or ``.html`` (three.js,
    with ``title`` (default: the model's name and counts) and a legend above the view)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SCENE_SUFFIXES:
        raise ValueError(f"out: unsupported scene type {suffix or path.name!r} (use .glb or .html)")
    scene = build_scene(model, contacts, highlight=highlight, marked=marked, up=up)
    if suffix == ".glb":
        data = scene.export(file_type="glb")
    else:
        from trimesh.viewer.notebook import scene_to_html

        title = title if title is not None else f"{model.name}: {counts_text(model)}"
        legend = _legend_entries(model, contacts, highlight, marked, "mesh" in scene.geometry)
        data = _with_overlay(scene_to_html(scene), title, legend)
    return write_atomic(path, data)


def _legend_entries(model: Model, contacts, highlight, marked, mesh: bool) -> list[tuple]:
    """``(label, css colour)`` of what the scene shows, as the pictures' legend names it."""
    kinds = {e.kind for e in model.elements}

    def hexed(colour) -> str:
        return "#" + "".join(f"{int(round(255 * v)):02x}" for v in colour)

    entries = [("mesh", "#c8c8c8")] if mesh else []
    for kind, label, colour in (
        (ElementKind.FACET, "facets", FACET_COLOUR),
        (ElementKind.SEGMENT, "segments", SEGMENT_COLOUR),
        (ElementKind.POINT, "points", POINT_COLOUR),
    ):
        if kind in kinds:
            entries.append((label, hexed(colour)))
    if len(highlight):
        entries.append(("chosen elements", hexed(HIGHLIGHT_COLOUR)))
    if len(marked):
        entries.append(("refused elements", hexed(MARKED_COLOUR)))
    if len(contact_arrays(contacts)[0]):
        entries.append(("contacts (rod: inward normal)", CONTACT_COLOUR))
    return entries


def _with_overlay(page: str, title: str, legend: list[tuple]) -> str:
    """The viewer's page with ``title`` (also the tab's) and the legend drawn over the view."""
    from html import escape

    rows = "".join(
        f'<div><span style="display:inline-block;width:11px;height:11px;margin-right:5px;'
        f'background:{colour}"></span>{escape(label)}</div>'
        for label, colour in legend
    )
    overlay = (
        '<div id="title" style="position:absolute;z-index:1;top:8px;width:100%;'
        f'text-align:center;font:16px sans-serif">{escape(title)}</div>'
        '<div id="legend" style="position:absolute;z-index:1;top:36px;left:10px;'
        "font:12px sans-serif;background:rgba(255,255,255,0.85);padding:6px;"
        f'border:1px solid #bbb">{rows}</div>'
    )
    page = page.replace("<title>trimesh: threejs viewer</title>", f"<title>{escape(title)}</title>")
    return page.replace('<div id="container"></div>', overlay + '<div id="container"></div>', 1)


def save_view(
    model: Model,
    path,
    contacts=None,
    *,
    highlight: Sequence[int] = (),
    marked: Sequence[int] = (),
    **options,
) -> Path:
    """Picture or interactive scene, chosen by the suffix of ``path``."""
    suffix = Path(path).suffix.lower()
    if suffix in SCENE_SUFFIXES:
        scene_options = {k: options[k] for k in ("up", "title") if k in options}
        return export_scene(
            model, contacts, path, highlight=highlight, marked=marked, **scene_options
        )
    return render_model(model, path, contacts, highlight=highlight, marked=marked, **options)


LOAD_ARROW = 0.3  # the largest load force's arrow, as a share of the part's size
LOAD_COLOURS = (4, 2, 9, 6, 5, 8, 7, 1, 0)  # tab10 but its red (contacts); orange, blue last


def draw_loads(ax, loads, model: Model, factors=None) -> int:
    """Each load case's forces as arrows ending at their points (a colour per case), and a
    legend entry per case: its name and, with ``factors``
    (:class:`~closure_nlp.criterion.load_factor.LoadFactors` of the same cases), its certified
    load factor. The largest force is drawn :data:`LOAD_ARROW` times the part's size, the others
    in proportion; a component without a point acts at the reference point, and a case of
    torques alone is a ring there. Returns the number of arrows drawn."""
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    from closure_nlp.contact.loads import as_loads

    loads = as_loads(loads)
    largest = max(np.linalg.norm(p.force) for case in loads.cases for p in case.components)
    length = LOAD_ARROW * model_extent(model) / (largest or 1.0)
    colours = colormaps["tab10"].colors
    entries = getattr(ax, "_closure_legend", {})
    arrows = 0
    for k, case in enumerate(loads.cases):
        colour = colours[LOAD_COLOURS[k % len(LOAD_COLOURS)]]
        for part in case.components:
            point = model.reference_point if part.point is None else part.point
            if not np.any(part.force):
                p = _shown(ax, point)
                ax.scatter(*p, marker="o", s=120, facecolors="none", edgecolors=[colour])
                continue
            tip, force = _shown(ax, point), _shown(ax, part.force) * length
            tail = tip - force
            ax.quiver(
                *tail,
                *force,
                color=colour,
                linewidth=2.2,
                arrow_length_ratio=0.25,
                zorder=32,
                gid=f"load:{case.name}",
            )
            arrows += 1
        name = case.name
        if factors is not None:
            factor = dict(zip(factors.names, factors.factors))[case.name]
            name += f" (load factor {factor.load_factor:.4g})"
        entries[f"load:{case.name}"] = Line2D([], [], color=colour, lw=2.2, label=name)
    ax._closure_legend = entries
    if ax.get_legend() is not None:
        update_legend(ax)
    return arrows


__all__ = [
    "build_scene",
    "scene_view",
    "counts_text",
    "draw_contacts",
    "draw_loads",
    "draw_model",
    "export_scene",
    "render_model",
    "save_view",
]
