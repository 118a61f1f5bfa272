"""Build the three objects of the paper's Fig. 1 as meshes and element models, in mm.

Run ``python models/build_models.py [OUT_DIR]`` (default: this script's folder). For each object it
writes ``<name>.stl`` and ``<name>.model.json`` whose ``"mesh"`` points at the STL. The element
counts are the paper's:

- ``lamp``: a round-brilliant-cut diamond lamp, 57 convex facets (crown: table, 8 stars,
  8 bezels, 16 upper girdle facets = 33; pavilion: 8 mains, 16 lower girdle facets = 24; no
  girdle band, crown meets pavilion at a 16-gon);
- ``cup``: a mug on an octagonal foot, 9 facets (foot bottom and its 8 sides), 16 line segments
  (rulings of the cylindrical wall), 224 points (192 on the handle, 32 on the rounded lip);
- ``pistol``: 7 facets (5 faces of the receiver block, muzzle, grip butt) and 42 line segments
  (18 rulings of the round barrel, 24 of the elliptic, raked grip).

The elements are built from the known geometry, not by :func:`closure_nlp.model.characterize`, so
the
counts are exact: every element lies on the mesh surface (facets and segments on mesh faces and
edges, points at mesh vertices) with its inward normal pointing into the solid. Parts of a mesh
(handle and body, barrel and receiver) may overlap instead of being fused: the STL is for
drawing and for inside tests, which only need each part closed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

from closure_nlp.model.elements import Element, ElementKind, Model, save_model

HERE = Path(__file__).resolve().parent
FACET, SEGMENT, POINT = ElementKind.FACET, ElementKind.SEGMENT, ElementKind.POINT


# --- small geometric helpers -----------------------------------------------------------------


def facet(vertices, inside, label: str = "") -> Element:
    """A facet whose inward normal points from its plane towards the point ``inside`` (3,)."""
    v = np.asarray(vertices, dtype=float)
    normal = np.zeros(3)
    for a, b in zip(v, np.roll(v, -1, axis=0)):  # Newell's method
        normal += np.cross(a, b)
    if normal @ (np.asarray(inside, float) - v.mean(axis=0)) < 0:
        normal = -normal
    return Element(FACET, v, normal, label)


def ring(angles, radius, z) -> np.ndarray:
    """(k, 3) float: points at ``angles`` (rad) on a horizontal circle."""
    angles = np.asarray(angles, dtype=float)
    return np.column_stack(
        [radius * np.cos(angles), radius * np.sin(angles), np.full_like(angles, z)]
    )


def tube_mesh(centres, tangents, normals, radius, sections) -> trimesh.Trimesh:
    """Closed tube of circular section along a centre line.

    Parameters
    ----------
    centres, tangents, normals : (k, 3) float
        Centre-line points, unit tangents and unit normals (perpendicular to the tangents).
    radius : float
    sections : int
        Vertices around each ring; ring ``i`` vertex ``j`` is at angle ``2 pi j / sections``
        from ``normals[i]`` towards ``tangents[i] x normals[i]``.
    """
    binormals = np.cross(tangents, normals)
    phi = 2 * np.pi * np.arange(sections) / sections
    rings = (
        centres[:, None, :]
        + radius * np.cos(phi)[None, :, None] * normals[:, None, :]
        + radius * np.sin(phi)[None, :, None] * binormals[:, None, :]
    )
    return _loft(rings, centres[0], centres[-1])


def _loft(rings: np.ndarray, first_cap, last_cap) -> trimesh.Trimesh:
    """Closed mesh through rings (k, s, 3) of s vertices, capped by fans at both ends."""
    k, s, _ = rings.shape
    vertices = np.vstack([rings.reshape(-1, 3), first_cap, last_cap])
    faces = []
    for i in range(k - 1):
        for j in range(s):
            a, b = i * s + j, i * s + (j + 1) % s
            faces += [[a, b, b + s], [a, b + s, a + s]]
    c0, c1 = k * s, k * s + 1
    for j in range(s):
        faces.append([c0, (j + 1) % s, j])
        faces.append([c1, (k - 1) * s + j, (k - 1) * s + (j + 1) % s])
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def prism_mesh(bottom: np.ndarray, top: np.ndarray) -> trimesh.Trimesh:
    """Closed prism between two convex polygons (s, 3) with matching vertices."""
    return _loft(np.stack([bottom, top]), bottom.mean(axis=0), top.mean(axis=0))


def revolved(profile, sections: int) -> trimesh.Trimesh:
    """Solid of revolution about z of a closed (r, z) profile starting and ending on the axis."""
    mesh = trimesh.creation.revolve(np.asarray(profile, dtype=float), sections=sections)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _model(name: str, elements, adjacency, description: str) -> Model:
    """An example model in mm, its mesh ``NAME.stl`` beside it."""
    return Model(
        tuple(elements),
        tuple(sorted(adjacency)),
        name=name,
        units="mm",
        mesh=f"{name}.stl",
        description=description,
    )


def adjacency_by_shared_vertices(elements, minimum: int = 1, tol: float = 1e-6) -> set:
    """Pairs of elements with at least ``minimum`` vertices in common (by coordinates)."""
    keys = [{tuple(np.round(v / tol).astype(np.int64)) for v in e.vertices} for e in elements]
    return {
        (i, j)
        for i in range(len(elements))
        for j in range(i + 1, len(elements))
        if len(keys[i] & keys[j]) >= minimum
    }


def cyclic(ids) -> set:
    """Neighbour pairs of consecutive ids around a loop."""
    ids = list(ids)
    return {tuple(sorted((a, b))) for a, b in zip(ids, ids[1:] + ids[:1])}


def best_facing(segments, facets, elements, outward_of) -> set:
    """Pair each segment with the facet whose outward normal is closest to the segment's."""
    pairs = set()
    normals = np.array([-elements[f].inward_normal for f in facets])
    for s in segments:
        f = facets[int(np.argmax(normals @ outward_of(s)))]
        pairs.add(tuple(sorted((s, f))))
    return pairs


# --- lamp ------------------------------------------------------------------------------------


def lamp(radius: float = 60.0) -> tuple[trimesh.Trimesh, Model]:
    """A diamond-shaped lamp: a round brilliant without girdle band, 57 convex facets."""
    eighth = 2 * np.pi / 8
    theta = eighth * np.arange(8)  # main directions (table corners, bezels, pavilion mains)
    half = theta + eighth / 2  # between them (stars, girdle halves, lower-half tips)
    c = np.cos(eighth / 2)
    r_table = 0.57 * radius
    h_table = (radius - r_table) * np.tan(np.radians(34.5))  # crown angle 34.5 deg
    r_star = (r_table + 0.5 * (radius - r_table)) / c  # star facets reach half way
    h_star = h_table * (radius - r_star * c) / (radius - r_table)  # keeps each bezel planar
    h_pav = radius * np.tan(np.radians(40.75))  # pavilion angle 40.75 deg
    r_low = 0.25 * radius / c  # lower girdle facets reach 75% of the way down
    z_low = -h_pav * (1 - r_low * c / radius)  # keeps each pavilion main planar

    table = ring(theta, r_table, h_table)
    star = ring(half, r_star, h_star)
    girdle_main = ring(theta, radius, 0.0)
    girdle_half = ring(half, radius, 0.0)
    low = ring(half, r_low, z_low)
    culet = np.array([0.0, 0.0, -h_pav])
    inside = np.array([0.0, 0.0, -0.2 * h_pav])

    crown, pavilion = [facet(table, inside, "crown")], []
    for k in range(8):
        n = (k + 1) % 8
        crown.append(facet([table[k], table[n], star[k]], inside, "crown"))  # star
    for k in range(8):
        p = (k - 1) % 8
        crown.append(facet([table[k], star[p], girdle_main[k], star[k]], inside, "crown"))
    for k in range(8):
        n = (k + 1) % 8
        crown.append(facet([star[k], girdle_main[k], girdle_half[k]], inside, "crown"))
        crown.append(facet([star[k], girdle_half[k], girdle_main[n]], inside, "crown"))
    for k in range(8):
        p = (k - 1) % 8
        pavilion.append(facet([culet, low[p], girdle_main[k], low[k]], inside, "pavilion"))
    for k in range(8):
        n = (k + 1) % 8
        pavilion.append(facet([low[k], girdle_main[k], girdle_half[k]], inside, "pavilion"))
        pavilion.append(facet([low[k], girdle_half[k], girdle_main[n]], inside, "pavilion"))

    elements = crown + pavilion
    points = np.vstack([table, star, girdle_main, girdle_half, low, culet])
    mesh = trimesh.convex.convex_hull(points)
    adjacency = adjacency_by_shared_vertices(elements, minimum=1)
    description = (
        "Diamond-shaped lamp (round brilliant cut, no girdle band): 57 convex "
        "facets, 33 on the crown and 24 on the pavilion. Neighbours share a vertex."
    )
    return mesh, _model("lamp", elements, adjacency, description)


# --- cup -------------------------------------------------------------------------------------

CUP = {
    "foot_radius": 44.0,  # circumradius of the octagonal foot
    "foot_height": 6.0,
    "wall_radius": 40.0,
    "wall_top": 100.0,
    "lip": 2.0,  # radius of the rounded lip (half the wall thickness)
    "floor": 10.0,
    "sections": 64,
    "handle_centre": (40.0, 55.0),  # (x, z) of the handle's arc centre
    "handle_arc": 25.0,
    "handle_tube": 5.0,
}


def cup() -> tuple[trimesh.Trimesh, Model]:
    """A mug on an octagonal foot: 9 facets, 16 segments, 224 points."""
    p = CUP
    foot = ring(np.radians(22.5) + np.radians(45) * np.arange(8), p["foot_radius"], 0.0)
    foot_top = foot + [0.0, 0.0, p["foot_height"]]
    body, lip_centre = _cup_body(p)
    handle, handle_points = _cup_handle(p)
    mesh = trimesh.util.concatenate([prism_mesh(foot, foot_top), body, handle])

    inside_foot = np.array([0.0, 0.0, p["foot_height"] / 2])
    elements = [facet(foot, inside_foot, "foot")]
    for k in range(8):
        n = (k + 1) % 8
        quad = [foot[k], foot[n], foot_top[n], foot_top[k]]
        elements.append(facet(quad, inside_foot, "foot"))
    seg_angles = np.radians(11.25) + np.radians(22.5) * np.arange(16)
    r = p["wall_radius"]
    for a in seg_angles:
        ends = [
            [r * np.cos(a), r * np.sin(a), p["foot_height"]],
            [r * np.cos(a), r * np.sin(a), p["wall_top"]],
        ]
        elements.append(Element(SEGMENT, ends, [-np.cos(a), -np.sin(a), 0.0], "wall"))
    for position, normal in handle_points:
        elements.append(Element(POINT, [position], normal, "handle"))
    lip_angles = 2 * np.pi * np.arange(32) / 32
    for a in lip_angles:
        top = [lip_centre * np.cos(a), lip_centre * np.sin(a), p["wall_top"] + p["lip"]]
        elements.append(Element(POINT, [top], [0.0, 0.0, -1.0], "lip"))

    adjacency = _cup_adjacency(seg_angles, lip_angles)
    description = (
        "Mug on an octagonal foot: 9 facets (foot bottom and sides), 16 line "
        "segments on the cylindrical wall, 224 points (192 on the handle, 32 on the lip)."
    )
    return mesh, _model("cup", elements, adjacency, description)


def _cup_body(p) -> tuple[trimesh.Trimesh, float]:
    """The mug's wall, lip and cavity as a solid of revolution; also the lip's centre radius."""
    r, t = p["wall_radius"], p["lip"]
    centre = r - t
    arc = np.linspace(0.0, np.pi, 13)  # includes the lip's top at 90 degrees
    lip = np.column_stack([centre + t * np.cos(arc), p["wall_top"] + t * np.sin(arc)])
    bottom = p["foot_height"] - 2.0  # hidden inside the foot
    profile = np.vstack(
        [
            [[0.0, bottom], [r, bottom], [r, p["foot_height"]]],
            lip,
            [[r - 2 * t, p["floor"]], [0.0, p["floor"]]],
        ]
    )
    return revolved(profile, p["sections"]), centre


def _cup_handle(p) -> tuple[trimesh.Trimesh, list]:
    """Handle: a half torus with short straight roots into the wall; and its 24 x 8 points."""
    cx, cz = p["handle_centre"]
    big, tube = p["handle_arc"], p["handle_tube"]
    element_angles = np.radians(np.linspace(80.0, -80.0, 24))
    between = (element_angles[:-1] + element_angles[1:]) / 2
    arc = np.sort(np.concatenate([element_angles, between, np.radians([90.0, 85.0, -85.0, -90.0])]))
    arc = arc[::-1]  # from the top root, round, to the bottom root
    centres = np.column_stack([cx + big * np.cos(arc), np.zeros_like(arc), cz + big * np.sin(arc)])
    tangents = np.column_stack([np.sin(arc), np.zeros_like(arc), -np.cos(arc)])
    normals = np.column_stack([np.cos(arc), np.zeros_like(arc), np.sin(arc)])  # away from centre
    root = p["wall_radius"] - 3.0
    top_root = [[root, 0.0, cz + big]]
    bottom_root = [[root, 0.0, cz - big]]
    centres = np.vstack([top_root, centres, bottom_root])
    tangents = np.vstack([[[1.0, 0.0, 0.0]], tangents, [[-1.0, 0.0, 0.0]]])
    normals = np.vstack([[[0.0, 0.0, 1.0]], normals, [[0.0, 0.0, -1.0]]])
    mesh = tube_mesh(centres, tangents, normals, tube, 16)
    points = []
    binormals = np.cross(tangents, normals)
    for i in range(1, len(arc) + 1):
        if not np.any(np.isclose(arc[i - 1], element_angles)):
            continue
        for j in range(0, 16, 2):
            phi = 2 * np.pi * j / 16
            radial = np.cos(phi) * normals[i] + np.sin(phi) * binormals[i]
            points.append((centres[i] + tube * radial, -radial))
    return mesh, points


def _cup_adjacency(seg_angles, lip_angles) -> set:
    """Foot around its bottom, foot sides to the wall, wall rulings in a ring, lip, handle grid."""
    bottom, sides = 0, list(range(1, 9))
    segs = list(range(9, 25))
    handle = np.arange(25, 25 + 192).reshape(24, 8)
    lip = list(range(25 + 192, 25 + 192 + 32))
    pairs = {(bottom, s) for s in sides} | cyclic(sides) | cyclic(segs)
    side_angles = np.radians(45.0) * np.arange(8)  # outward normal of side k
    for s, a in zip(segs, seg_angles):
        k = int(np.argmin(np.abs(np.angle(np.exp(1j * (side_angles - a))))))
        pairs.add((sides[k], s))
    pairs |= cyclic(lip)
    for point, a in zip(lip, lip_angles):
        gap = np.abs(np.angle(np.exp(1j * (seg_angles - a))))
        for s in np.flatnonzero(gap <= np.radians(11.25) + 1e-9):
            pairs.add((segs[s], point))
    for i in range(24):
        pairs |= cyclic(handle[i].tolist())
        if i + 1 < 24:
            pairs |= {(int(a), int(b)) for a, b in zip(handle[i], handle[i + 1])}
    for end in (handle[0], handle[-1]):  # the handle's roots meet the wall beside two rulings
        for s in (segs[0], segs[-1]):
            pairs |= {(s, int(h)) for h in end}
    return {tuple(sorted(pair)) for pair in pairs}


# --- pistol ----------------------------------------------------------------------------------

PISTOL = {
    "receiver": ((0.0, 130.0), (-14.0, 14.0), (0.0, 36.0)),  # x, y, z ranges of the block
    "barrel_radius": 9.0,
    "barrel_axis": (0.0, 24.0),  # (y, z)
    "barrel_x": (120.0, 195.0),  # starts inside the block
    "grip_axes": (16.0, 13.0),  # semi-axes of the elliptic section (fore-aft, across)
    "grip_top": (36.0, 0.0, 12.0),  # centre of the grip's top end, inside the block
    "grip_length": 110.0,
    "grip_rake": 18.0,  # degrees from vertical, butt towards the back
    "bottom_front_x": 56.0,  # the bottom facet runs from here to the front
}


def pistol() -> tuple[trimesh.Trimesh, Model]:
    """A pistol: receiver block, round barrel, raked elliptic grip; 7 facets, 42 segments."""
    p = PISTOL
    (x0, x1), (y0, y1), (z0, z1) = p["receiver"]
    block = trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, z1]])
    barrel_mesh, barrel = _barrel(p)
    grip_mesh, grip, butt = _grip(p)
    mesh = trimesh.util.concatenate([block, barrel_mesh, grip_mesh])

    centre = np.array([(x0 + x1) / 2, 0.0, (z0 + z1) / 2])
    xb = p["bottom_front_x"]
    faces = [
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],  # top
        [[x0, y1, z0], [x1, y1, z0], [x1, y1, z1], [x0, y1, z1]],  # left (+y)
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],  # right (-y)
        [[x0, y0, z0], [x0, y1, z0], [x0, y1, z1], [x0, y0, z1]],  # back
        [[xb, y0, z0], [x1, y0, z0], [x1, y1, z0], [xb, y1, z0]],  # bottom, before the grip
    ]
    elements = [facet(f, centre, "receiver") for f in faces]
    muzzle_centre = np.array([p["barrel_x"][1], *p["barrel_axis"]])
    elements.append(facet([end for _, end in barrel], muzzle_centre - [1.0, 0, 0], "muzzle"))
    elements.append(facet(butt, np.mean(butt, axis=0) - _grip_axis(p), "grip"))
    for (start, end), normal in zip(barrel, _barrel_normals(len(barrel))):
        elements.append(Element(SEGMENT, [start, end], normal, "barrel"))
    for (start, end), normal in grip:
        elements.append(Element(SEGMENT, [start, end], normal, "grip"))

    adjacency = _pistol_adjacency(elements, len(barrel), len(grip))
    description = (
        "Pistol: receiver block, round barrel and raked elliptic grip. 7 facets "
        "(receiver top, sides, back and bottom, muzzle, grip butt) and 42 line segments (18 "
        "on the barrel, 24 on the grip)."
    )
    return mesh, _model("pistol", elements, adjacency, description)


def _barrel_normals(count: int) -> np.ndarray:
    """(count, 3) float: inward normals of the barrel's rulings."""
    a = 2 * np.pi * np.arange(count) / count
    return -np.column_stack([np.zeros(count), np.cos(a), np.sin(a)])


def _barrel(p, count: int = 18, sections: int = 72):
    """Barrel mesh (a cylinder along x) and its rulings from the block's front to the muzzle."""
    r = p["barrel_radius"]
    y, z = p["barrel_axis"]
    start, end = p["barrel_x"]
    front = p["receiver"][0][1]
    a = 2 * np.pi * np.arange(sections) / sections
    section = np.column_stack([np.zeros(sections), y + r * np.cos(a), z + r * np.sin(a)])
    rings = np.stack([section + [start, 0, 0], section + [end, 0, 0]])
    mesh = _loft(rings, [start, y, z], [end, y, z])
    step = sections // count
    rulings = [
        (section[k] + [front, 0, 0], section[k] + [end, 0, 0]) for k in range(0, sections, step)
    ]
    return mesh, rulings


def _grip_axis(p) -> np.ndarray:
    """(3,) float: unit direction from the grip's top end down to its butt."""
    rake = np.radians(p["grip_rake"])
    return np.array([-np.sin(rake), 0.0, -np.cos(rake)])


def _grip(p, count: int = 24, sections: int = 96):
    """Grip mesh (elliptic cylinder), its rulings (below the block) and its butt polygon."""
    a, b = p["grip_axes"]
    down = _grip_axis(p)
    across = np.array([0.0, 1.0, 0.0])
    fore = np.cross(across, down)  # forwards, perpendicular to the axis
    top = np.array(p["grip_top"])
    butt_centre = top + p["grip_length"] * down
    t = 2 * np.pi * np.arange(sections) / sections
    offsets = a * np.cos(t)[:, None] * fore + b * np.sin(t)[:, None] * across
    mesh = _loft(np.stack([top + offsets, butt_centre + offsets]), top, butt_centre)
    bottom_of_block = p["receiver"][2][0]
    rulings, butt = [], []
    for k in range(0, sections, sections // count):
        upper = top + offsets[k]
        s = (bottom_of_block - upper[2]) / down[2]  # where the ruling leaves the block
        outward = np.cos(t[k]) / a * fore + np.sin(t[k]) / b * across
        rulings.append(((upper + s * down, butt_centre + offsets[k]), -outward))
        butt.append(butt_centre + offsets[k])
    return mesh, rulings, np.array(butt)


def _pistol_adjacency(elements, n_barrel: int, n_grip: int) -> set:
    """Receiver faces sharing edges; barrel and grip rulings in rings, to their end facets and
    to the receiver face they run into."""
    top, left, right, back, bottom, muzzle, butt = range(7)
    barrel = list(range(7, 7 + n_barrel))
    grip = list(range(7 + n_barrel, 7 + n_barrel + n_grip))
    pairs = {(top, left), (top, right), (top, back), (left, back), (right, back)}
    pairs |= {(left, bottom), (right, bottom)}
    pairs |= cyclic(barrel) | cyclic(grip)
    pairs |= {(muzzle, s) for s in barrel} | {(butt, s) for s in grip}

    def outward(i):
        return -elements[i].inward_normal

    pairs |= best_facing(barrel, [top, left, right, bottom], elements, outward)
    pairs |= best_facing(grip, [left, right, back, bottom], elements, outward)
    return {tuple(sorted(pair)) for pair in pairs}


# --- writing ---------------------------------------------------------------------------------

BUILDERS = {"lamp": lamp, "cup": cup, "pistol": pistol}


def build(name: str, out_dir: Path = HERE) -> tuple[Path, Model]:
    """Write ``<name>.stl`` and ``<name>.model.json`` into ``out_dir``."""
    mesh, model = BUILDERS[name]()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    mesh.export(out_dir / f"{name}.stl")
    return save_model(model, out_dir / f"{name}.model.json"), model


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out_dir = Path(argv[0]) if argv else HERE
    for name in BUILDERS:
        path, model = build(name, out_dir)
        print(f"{path}: {model.counts()}, {len(model.adjacency)} neighbour pairs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
