"""Element models from meshes, the committed example models, and the characterize/show CLI."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

from closure_nlp.cli.main import main
from closure_nlp.model.characterize import (
    characterize,
    characterize_mesh,
    load_mesh,
    winding_number,
)
from closure_nlp.model.elements import ElementKind, load_model

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
PAPER_COUNTS = {
    "lamp": {"facet": 57, "segment": 0, "point": 0},
    "cup": {"facet": 9, "segment": 16, "point": 224},
    "pistol": {"facet": 7, "segment": 42, "point": 0},
}


def of_kind(model, kind: str) -> list:
    return [e for e in model.elements if e.kind is ElementKind(kind)]


def is_connected(model) -> bool:
    seen, todo = {0}, [0]
    while todo:
        for j in model.neighbours(todo.pop()):
            if j not in seen:
                seen.add(j)
                todo.append(j)
    return len(seen) == len(model)


def l_bracket() -> trimesh.Trimesh:
    """An L-shaped profile (non-convex) extruded 20 along y."""
    xz = np.array([[0, 0], [40, 0], [40, 8], [8, 8], [8, 30], [0, 30]], dtype=float)
    k = len(xz)
    front = np.column_stack([xz[:, 0], np.zeros(k), xz[:, 1]])
    back = front + [0.0, 20.0, 0.0]
    fan = [[0, i, i + 1] for i in range(1, k - 1)]  # the L is star-shaped from its corner 0
    faces = [[a, c, b] for a, b, c in fan] + [[k + a, k + b, k + c] for a, b, c in fan]
    for i in range(k):
        j = (i + 1) % k
        faces += [[i, j, k + j], [i, k + j, k + i]]
    mesh = trimesh.Trimesh(np.vstack([front, back]), faces)
    trimesh.repair.fix_normals(mesh)
    return mesh


# --- analytic shapes -------------------------------------------------------------------------


def test_box_gives_six_facets_adjacent_along_its_twelve_edges():
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    model = characterize(box)
    assert model.counts() == {"facet": 6, "segment": 0, "point": 0}
    assert len(model.adjacency) == 12
    normals = np.array([e.inward_normal for e in model.elements])
    for i, j in model.adjacency:  # neighbours meet at an edge: perpendicular faces
        assert abs(normals[i] @ normals[j]) < 1e-9
    centres = np.array([e.centroid for e in model.elements])
    np.testing.assert_allclose(normals, -centres / np.linalg.norm(centres, axis=1)[:, None])
    assert sum(len(e.vertices) for e in model.elements) == 24


def test_cylinder_gives_two_caps_and_wall_rulings():
    cyl = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=16)
    model = characterize(cyl)
    assert model.counts() == {"facet": 2, "segment": 16, "point": 0}
    for cap in of_kind(model, "facet"):
        assert len(cap.vertices) == 16
        assert abs(abs(cap.inward_normal[2]) - 1) < 1e-12
        assert cap.inward_normal[2] * cap.centroid[2] < 0
    for seg in of_kind(model, "segment"):
        np.testing.assert_allclose(np.sort(seg.vertices[:, 2]), [-1.0, 1.0])
        radial = seg.centroid * [1, 1, 0]
        np.testing.assert_allclose(seg.inward_normal, -radial / np.linalg.norm(radial), atol=1e-9)
    for i, e in enumerate(model.elements):  # ring of rulings, each touching both caps
        kinds = [model.elements[j].kind.value for j in model.neighbours(i)]
        if e.kind is ElementKind.SEGMENT:
            assert sorted(kinds) == ["facet", "facet", "segment", "segment"]


def test_segment_spacing_thins_rulings_and_keeps_them_in_a_ring():
    cyl = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=64)
    model = characterize(cyl, segment_spacing=0.3)
    segments = [i for i, e in enumerate(model.elements) if e.kind is ElementKind.SEGMENT]
    assert 12 <= len(segments) <= 21  # circumference 6.28 at spacing 0.3..0.39
    mids = np.array([model.elements[i].centroid for i in segments])
    gaps = np.linalg.norm(mids[:, None] - mids[None], axis=2) + 10 * np.eye(len(mids))
    assert gaps.min() >= 0.3
    for i in segments:
        assert sum(j in segments for j in model.neighbours(i)) == 2


def test_cone_rulings_meet_at_the_apex_without_making_every_ruling_a_neighbour():
    cone = trimesh.creation.cone(radius=1.0, height=2.0, sections=24)
    model = characterize(cone, segment_spacing=0)
    assert model.counts() == {"facet": 1, "segment": 24, "point": 0}
    apex = np.array([0.0, 0.0, 2.0])
    for seg in of_kind(model, "segment"):
        assert np.min(np.linalg.norm(seg.vertices - apex, axis=1)) < 1e-9
        assert seg.inward_normal[2] < 0  # a cone's surface leans over its inside
    assert max(len(model.neighbours(i)) for i in range(len(model))) <= 24


def test_sphere_gives_points_only_with_normals_to_the_centre():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=5.0)
    model = characterize(sphere)
    assert model.counts() == {"facet": 0, "segment": 0, "point": len(sphere.vertices)}
    for p in model.elements:
        np.testing.assert_allclose(p.inward_normal, -p.vertices[0] / 5.0, atol=2e-2)
    assert is_connected(model)


def test_coarse_polyhedron_gives_facets_not_points():
    ico = trimesh.creation.icosphere(subdivisions=1)  # 80 faces about 20 degrees apart
    assert characterize(ico).counts() == {"facet": 80, "segment": 0, "point": 0}
    assert characterize(ico, faceted_limit=10).counts() == {"facet": 0, "segment": 0, "point": 42}


def test_point_spacing_thins_points_and_keeps_the_model_connected():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    model = characterize(sphere, point_spacing=1.5)
    pts = np.array([e.vertices[0] for e in model.elements])
    assert 20 < len(pts) < len(sphere.vertices) / 3
    gaps = np.linalg.norm(pts[:, None] - pts[None], axis=2) + 100 * np.eye(len(pts))
    assert gaps.min() >= 1.5
    assert is_connected(model)


def test_l_bracket_is_covered_exactly_by_convex_facets():
    mesh = l_bracket()
    model = characterize(mesh, name="bracket", units="mm")
    counts = model.counts()
    assert counts["segment"] == counts["point"] == 0
    assert 10 <= counts["facet"] <= 12  # 6 sides, each L-shaped end in 2 (or 3) pieces
    area = sum(_polygon_area(e.vertices) for e in model.elements)
    assert area == pytest.approx(mesh.area)
    assert is_connected(model)
    assert model.name == "bracket" and model.units == "mm"


def test_stepped_shaft_gives_end_facets_shoulder_facets_and_two_rings_of_rulings():
    profile = np.array([[0, 0], [10, 0], [10, 20], [6, 20], [6, 50], [0, 50]], dtype=float)
    shaft = trimesh.creation.revolve(profile, sections=32)
    model = characterize(shaft, segment_spacing=0)
    segments = of_kind(model, "segment")
    assert len(segments) == 64 and not of_kind(model, "point")
    radii = sorted({round(float(np.hypot(*s.centroid[:2])), 3) for s in segments})
    assert len(radii) == 2 and radii[1] > 9.5
    for f in of_kind(model, "facet"):
        assert abs(abs(f.inward_normal[2]) - 1) < 1e-9
    facet_area = sum(_polygon_area(f.vertices) for f in of_kind(model, "facet"))
    disc = shaft.area_faces[np.abs(shaft.face_normals[:, 2]) > 0.999].sum()
    assert facet_area == pytest.approx(disc)
    assert is_connected(model)


def _polygon_area(vertices: np.ndarray) -> float:
    a = np.zeros(3)
    for p, q in zip(vertices, np.roll(vertices, -1, axis=0)):
        a += np.cross(p, q)
    return float(np.linalg.norm(a) / 2)


# --- repair and bad meshes -------------------------------------------------------------------


def test_box_with_a_missing_triangle_is_repaired():
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    open_box = trimesh.Trimesh(box.vertices, box.faces[1:], process=False)
    assert not open_box.is_watertight
    # Half of a face of a 12-triangle box: longer than the part's radius, an opening.
    with pytest.raises(ValueError, match="opening of the part.*--close-holes"):
        characterize(open_box)
    assert characterize(open_box, close_holes=True).counts()["facet"] == 6


def test_box_with_a_flipped_triangle_is_repaired():
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    faces = box.faces.copy()
    faces[3] = faces[3][::-1]
    model = characterize(trimesh.Trimesh(box.vertices, faces, process=False))
    assert model.counts()["facet"] == 6
    assert all(e.inward_normal @ e.centroid < 0 for e in model.elements)


def test_inside_out_mesh_gets_inward_normals_pointing_inside():
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    box.invert()
    model = characterize(box)
    assert all(e.inward_normal @ e.centroid < 0 for e in model.elements)


def finned_box() -> trimesh.Trimesh:
    """A box with a large fin on one of its edges: that edge has three triangles."""
    box = trimesh.creation.box()
    a, b = box.edges_unique[0]
    far = (box.vertices[a] + box.vertices[b]) / 2 + 3 * (box.vertices[a] - box.centroid)
    vertices = np.vstack([box.vertices, far])
    return trimesh.Trimesh(vertices, np.vstack([box.faces, [[a, b, len(box.vertices)]]]))


def test_open_mesh_that_cannot_be_closed_is_rejected_naming_its_open_edges(tmp_path):
    path = tmp_path / "fin.stl"
    finned_box().export(path)
    with pytest.raises(ValueError, match=r"fin\.stl: the mesh is not closed \(3 open or non-man"):
        characterize(path)


def test_large_flat_hole_is_capped():
    cyl = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=16)
    keep = cyl.face_normals[:, 2] < 0.5  # no top cap: a 16-edge hole
    repairs = []
    opened = trimesh.Trimesh(cyl.vertices, cyl.faces[keep])
    model = characterize_mesh(opened, segment_spacing=0, close_holes=True)
    repairs = model.repairs
    assert model.model.counts() == {"facet": 2, "segment": 16, "point": 0}
    assert repairs == ("filled 1 hole(s) bounded by 16 edges",)


def test_unreadable_and_missing_files_are_rejected_naming_them(tmp_path):
    bad = tmp_path / "junk.stl"
    bad.write_bytes(b"this is not a mesh\n")
    with pytest.raises(ValueError, match="junk.stl: "):
        characterize(bad)
    with pytest.raises(ValueError, match="nowhere.obj: file not found"):
        characterize(tmp_path / "nowhere.obj")
    with pytest.raises(TypeError, match="mesh: expected"):
        load_mesh(42)
    with pytest.raises(ValueError, match="segment_spacing"):
        characterize(trimesh.creation.box(), segment_spacing=-1.0)


def test_winding_number_tells_inside_from_outside():
    box = trimesh.creation.box((2.0, 2.0, 2.0))
    w = winding_number(box, [[0, 0, 0], [0.9, -0.9, 0.9], [1.1, 0, 0], [0, 0, 5]])
    np.testing.assert_allclose(w, [1, 1, 0, 0], atol=1e-9)


# --- the committed models of the paper -------------------------------------------------------


@pytest.fixture(scope="module", params=sorted(PAPER_COUNTS))
def paper_model(request):
    model = load_model(MODELS / f"{request.param}.model.json")
    mesh = trimesh.load(model.mesh_path, force="mesh")
    return request.param, model, mesh


def test_paper_model_counts_match_the_paper(paper_model):
    name, model, _ = paper_model
    assert model.name == name and model.units == "mm"
    assert model.counts() == PAPER_COUNTS[name]


def test_paper_model_elements_lie_on_the_surface_with_inward_normals(paper_model):
    _, model, mesh = paper_model
    assert mesh.is_watertight
    step = 1e-3 * float(np.ptp(mesh.vertices, axis=0).max())
    probes = np.array([0.9 * e.centroid + 0.1 * v for e in model.elements for v in e.vertices])
    normals = np.array([e.inward_normal for e in model.elements for _ in e.vertices])
    assert np.all(winding_number(mesh, probes + step * normals) > 0.5)  # just inside
    assert np.all(winding_number(mesh, probes - step * normals) < 0.5)  # just outside


def test_paper_model_neighbourhoods_are_meaningful(paper_model):
    _, model, _ = paper_model
    assert all(len(model.neighbours(i)) >= 1 for i in range(len(model)))
    assert is_connected(model)
    scale = max(e.size for e in model.elements)
    for i, j in model.adjacency:  # neighbours are near each other
        gap = np.linalg.norm(model.elements[i].centroid - model.elements[j].centroid)
        assert gap < 1.5 * scale


def test_lamp_is_a_convex_polyhedron_of_exactly_its_57_facets():
    model = load_model(MODELS / "lamp.model.json")
    mesh = trimesh.load(model.mesh_path, force="mesh")
    assert mesh.is_convex
    planes = len(mesh.facets) + len(mesh.faces) - sum(len(f) for f in mesh.facets)
    assert planes == 57
    labels = [e.label for e in model.elements]
    assert labels.count("crown") == 33 and labels.count("pavilion") == 24
    for e in model.elements:  # each facet is one face of the hull: every hull vertex behind it
        heights = (mesh.vertices - e.vertices[0]) @ e.inward_normal
        assert heights.min() > -1e-5 * e.size  # STL stores float32
        assert np.sum(np.abs(heights) < 1e-5 * e.size) == len(e.vertices)


def test_characterizing_the_lamp_mesh_recovers_its_57_facets_and_neighbours():
    model = load_model(MODELS / "lamp.model.json")
    found = characterize(model.mesh_path)
    assert found.counts() == PAPER_COUNTS["lamp"]
    assert len(found.adjacency) == len(model.adjacency)
    key = sorted(float(e.centroid @ [1, 2, 3]) for e in found.elements)
    expected = sorted(float(e.centroid @ [1, 2, 3]) for e in model.elements)
    assert key == pytest.approx(expected, abs=1e-3)  # the STL holds float32


# --- command line ----------------------------------------------------------------------------


def run_cli(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse rejects a bad flag value before main's handler
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_characterize_writes_a_model(tmp_path, capsys):
    mesh = tmp_path / "meshes" / "shaft.stl"
    mesh.parent.mkdir()
    trimesh.creation.cylinder(radius=1.0, height=2.0, sections=16).export(mesh)
    out = tmp_path / "models" / "shaft.model.json"
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out, "--json")
    assert code == 0, err
    payload = json.loads(stdout)
    assert payload["elements"] == {"facet": 2, "segment": 16, "point": 0}
    assert payload["out"] == str(out)
    model = load_model(out)
    assert model.counts() == payload["elements"] and model.name == "shaft"
    # A model reads meshes only in its folder (../meshes/ is refused unless allowed), so the
    # repaired mesh is written beside it.
    assert model.mesh == "shaft.mesh.stl" and model.mesh_path.is_file()
    outside = replace(model, mesh="../meshes/shaft.stl")
    with pytest.raises(ValueError, match="outside the model's folder"):
        outside.mesh_path  # noqa: B018
    assert replace(outside, allow_outside_mesh=True).mesh_path == mesh.resolve()
    code, stdout, _ = run_cli(capsys, "characterize", mesh, "--out", out, "--segment-spacing", "1")
    assert code == 0 and "facets" in stdout and "segments" in stdout


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["characterize", "{tmp}/none.stl", "--out", "{tmp}/m.json"], "none.stl: file not found"),
        (["characterize", "{tmp}/junk.stl", "--out", "{tmp}/m.json"], "junk.stl"),
        (["characterize", "{tmp}/open.stl", "--out", "{tmp}/m.json"], "open.stl: the mesh is not"),
        (
            ["characterize", "{tmp}/open.stl", "--out", "x", "--point-spacing", "-2"],
            "--point-spacing",
        ),
        (["show", "{tmp}/junk.model.json", "--out", "{tmp}/a.png"], "junk.model.json: malformed"),
        (["show", "{model}", "--out", "{tmp}/a.txt"], "--out: unsupported file type"),
        (["show", "{model}", "--out", "{tmp}/a.png", "--highlight", "0,99"], "--highlight"),
        (
            ["show", "{model}", "--contacts", "{tmp}/junk.model.json", "--out", "{tmp}/a.png"],
            "junk",
        ),
    ],
)
def test_cli_bad_input_exits_2_with_one_error_line(tmp_path, capsys, args, needle):
    (tmp_path / "junk.stl").write_text("solid nothing\n garbage\n")
    (tmp_path / "junk.model.json").write_text("{ not json")
    finned_box().export(tmp_path / "open.stl")
    fill = {"tmp": tmp_path, "model": MODELS / "pistol.model.json"}
    code, stdout, err = run_cli(capsys, *[a.format(**fill) for a in args])
    assert code == 2
    assert err.startswith("error:") and err.count("\n") == 1 and "Traceback" not in err
    assert needle in err
    assert not (tmp_path / "m.json").exists() and not (tmp_path / "a.png").exists()


def test_cli_show_draws_pictures_and_scenes(tmp_path, capsys):
    model = MODELS / "pistol.model.json"
    contacts = tmp_path / "grip.contacts.json"
    chosen = load_model(model)
    entries = []
    for i in (0, 3, 9, 30):
        e = chosen.elements[i]
        entries.append(
            {
                "position": e.centroid.tolist(),
                "inward_normal": e.inward_normal.tolist(),
                "element": i,
            }
        )
    contacts.write_text(json.dumps({"defaults": {"type": "fpc"}, "contacts": entries}))
    png = tmp_path / "pistol.png"
    code, stdout, err = run_cli(
        capsys, "show", model, "--contacts", contacts, "--out", png, "--json", "--no-mesh"
    )
    assert code == 0, err
    assert json.loads(stdout)["out"] == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    glb = tmp_path / "pistol.glb"
    code, _, err = run_cli(capsys, "show", model, "--contacts", contacts, "--out", glb)
    assert code == 0, err
    assert glb.read_bytes()[:4] == b"glTF"
    scene = trimesh.load(glb)
    assert len(scene.geometry) >= len(chosen) + 2 * len(entries)


def test_draw_model_highlights_and_sizes_contacts():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from closure_nlp.report.drawing import draw_contacts, draw_model

    model = load_model(MODELS / "cup.model.json")
    fig = plt.figure()
    try:
        ax = fig.add_subplot(projection="3d")
        pts = np.array([model.elements[i].vertices[0] for i in (30, 40)])
        nrm = np.array([model.elements[i].inward_normal for i in (30, 40)])
        draw_model(model, (pts, nrm), ax, highlight=[0, 12, 30], show_mesh=False, contact_sizes=120)
        draw_contacts(ax, (pts, nrm), sizes=[10, 20])
        assert "cup: 9 facets, 16 segments, 224 points" in ax.get_title()
        assert ax.get_xlim()[1] - ax.get_xlim()[0] == pytest.approx(
            ax.get_zlim()[1] - ax.get_zlim()[0]
        )
        sizes = {
            float(s)
            for c in ax.collections
            if hasattr(c, "get_sizes")
            for s in np.atleast_1d(c.get_sizes())
        }
        assert 10.0 in sizes and 120.0 in sizes and 30.0 in sizes  # small, large, highlighted
        with pytest.raises(ValueError, match="highlight"):
            draw_model(model, None, ax, highlight=[999])
    finally:
        plt.close(fig)


def test_finely_meshed_flat_faces_are_one_facet_each():
    box = trimesh.creation.box()
    for _ in range(4):
        box = box.subdivide()  # 3,072 triangles, hundreds of vertices inside each face
    model = characterize(box)
    assert model.counts() == {"facet": 6, "segment": 0, "point": 0}
    assert all(len(e.vertices) == 4 for e in model.elements)  # straight corners dropped


# --- what characterize writes, the other commands accept -------------------------------------


def test_the_same_cube_characterizes_alike_at_any_scale(tmp_path, capsys):
    """Thresholds are relative to the part: trimesh's absolute ones refused a cube at 1e11 as
    'every triangle degenerate' (its vertex merge overflowed)."""
    radii = {}
    for scale in (1e-3, 1.0, 1e11):
        mesh = tmp_path / f"cube{scale:g}.obj"
        trimesh.creation.box(extents=(scale, 2 * scale, 3 * scale)).export(mesh)
        out = tmp_path / f"cube{scale:g}.model.json"
        code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out, "--json")
        assert code == 0, err
        assert json.loads(stdout)["elements"] == {"facet": 6, "segment": 0, "point": 0}
        radii[scale] = load_model(out).radius / scale
    assert radii[1e-3] == pytest.approx(radii[1.0], rel=1e-9)
    assert radii[1e11] == pytest.approx(radii[1.0], rel=1e-9)


def test_separate_bodies_are_one_part_only_when_the_user_says_so(tmp_path, capsys):
    boxes = []
    for k in range(200):
        box = trimesh.creation.box(extents=(1, 1, 1))
        box.apply_translation([3.0 * (k % 20), 3.0 * (k // 20), 0.0])
        boxes.append(box)
    mesh = tmp_path / "boxes.glb"
    trimesh.Scene(boxes).export(mesh)
    out = tmp_path / "boxes.model.json"
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out)
    assert code == 2 and not out.exists()
    assert err.startswith(f"error: {mesh}: ") and "200 separate bodies" in err
    assert "--merge-bodies" in err and len(err.splitlines()) == 1
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out, "--merge-bodies")
    assert code == 0, err
    assert load_model(out).counts()["facet"] == 6 * 200


def test_units_default_to_metres_and_are_printed(tmp_path, capsys):
    mesh = tmp_path / "cube.stl"
    trimesh.creation.box(extents=(0.02, 0.03, 0.04)).export(mesh)
    out = tmp_path / "cube.model.json"
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out)
    assert code == 0, err
    assert "units m (default" in stdout
    assert json.loads(out.read_text())["units"] == "m"
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out, "--units", "mm")
    assert code == 0 and "units mm (given)" in stdout
    assert "far too small" in err  # a 0.03 mm part: the warning judges the unit used
    assert json.loads(out.read_text())["units"] == "mm"


def test_characterize_and_the_model_commands_report_one_radius(tmp_path, capsys):
    """Points thinned away used to leave characterize's radius (of every mesh vertex) above
    the model's (of its elements), which plan scales by."""
    mesh = tmp_path / "blob.stl"
    blob = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    blob.vertices *= [1.0, 0.8, 0.6]
    blob.vertices += 0.01 * np.sin(7 * blob.vertices)  # no two vertices at the same distance
    blob.export(mesh)
    out = tmp_path / "blob.model.json"
    code, stdout, err = run_cli(capsys, "characterize", mesh, "--out", out, "--json")
    assert code == 0, err
    reported = json.loads(stdout)["radius"]
    model = load_model(out)
    assert model.counts()["point"] > 0
    code, stdout, err = run_cli(
        capsys, "eligibility", out, "--elements", "0,1,2,3", "--type", "pcwf", "--json"
    )
    assert code == 0, err
    assert reported == json.loads(stdout)["radius"] == model.radius


def test_a_patch_of_tiny_triangles_makes_no_library_warning():
    """trimesh gives a zero normal to a triangle below its absolute area tolerance: a patch of
    such triangles (a boolean union leaves some) divided 0 by 0."""
    import warnings

    from closure_nlp.model.planar import facets

    tiny = 1e-7 * np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    mesh = trimesh.Trimesh(tiny, [[0, 1, 2]], process=False)
    assert not np.any(mesh.face_normals) and mesh.area_faces[0] > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        [draft] = facets(mesh, np.array([0]))
    assert np.allclose(draft.element.inward_normal, [0, 0, -1])


def test_drop_outward_leaves_out_exactly_the_refused_elements():
    from closure_nlp.model.characterize import drop_outward
    from closure_nlp.model.model_mesh import check_normals, outward_elements

    found = characterize_mesh(l_bracket())
    model, mesh = found.model, found.mesh
    assert drop_outward(model, mesh) == (model, [])
    elements = list(model.elements)
    elements[2] = replace(elements[2], inward_normal=-elements[2].inward_normal)
    flipped = replace(model, elements=tuple(elements))
    assert outward_elements(flipped, mesh) == (2,)
    kept, lines = drop_outward(flipped, mesh)
    check_normals(kept, mesh)  # what the model commands apply: nothing left to refuse
    assert len(kept) == len(model) - 1 and len(lines) == 1 and "facet at [" in lines[0]
    assert [e.name for e in kept.elements] == [f"elements[{i}]" for i in range(len(kept))]
    # The dropped facet's neighbours stay connected through where it was.
    around = [j - (j > 2) for j in model.neighbours(2)]
    assert all(b in kept.neighbours(a) for a in around for b in around if a != b)


def test_show_draws_a_refused_element_marked(tmp_path, capsys):
    mesh = tmp_path / "bracket.stl"
    l_bracket().export(mesh)
    out = tmp_path / "bracket.model.json"
    assert run_cli(capsys, "characterize", mesh, "--out", out)[0] == 0
    data = json.loads(out.read_text())
    data["elements"][1]["inward_normal"] = [-x for x in data["elements"][1]["inward_normal"]]
    out.write_text(json.dumps(data))
    code, _, err = run_cli(capsys, "eligibility", out, "--elements", "0,1,2,3", "--type", "pcwf")
    assert code == 2 and "elements[1].inward_normal: points out of" in err
    code, stdout, err = run_cli(capsys, "show", out, "--out", tmp_path / "b.png", "--json")
    assert code == 0, err
    assert json.loads(stdout)["marked"] == [1]
    assert err.startswith(f"warning: {out}: 1 element(s)") and err.rstrip().endswith(": 1")


PYBULLET_MESHES = ["duck.obj", "duck_vhacd.obj", "lego/lego.obj"]


@pytest.mark.slow
@pytest.mark.parametrize("name", PYBULLET_MESHES)
def test_pybullet_meshes_characterize_into_models_the_commands_accept(name, tmp_path, capsys):
    """duck, duck_vhacd and lego: small facets whose corner faces face the other way were
    written, then refused by every model command."""
    data = pytest.importorskip("pybullet_data")
    mesh = Path(data.getDataPath()) / name
    out = tmp_path / "m.model.json"
    code, stdout, err = run_cli(
        capsys, "characterize", mesh, "--out", out, "--merge-bodies", "--json"
    )
    assert code == 0, err
    model = load_model(out)
    from closure_nlp.model.model_mesh import check_normals, read_model_mesh

    check_normals(model, read_model_mesh(model))
    code, _, err = run_cli(capsys, "eligibility", out, "--elements", "0,1,2,3", "--type", "pcwf")
    assert code == 0, err
    assert all(line.startswith("warning: ") for line in err.splitlines())


@pytest.mark.parametrize("spacing", [0.01, 0.05, 0.3])
def test_thinning_keeps_the_greedy_points(spacing):
    """thin's ball-at-a-time search against the definition, by brute force: in order, a point
    is kept unless a point kept before it lies closer than the spacing."""
    from closure_nlp.model.drafts import thin

    rng = np.random.default_rng(3)
    points = rng.random((400, 3))
    order = rng.permutation(len(points))
    for given in (None, order):
        kept = []
        for i in range(len(points)) if given is None else given:
            if all(np.linalg.norm(points[i] - points[j]) >= spacing for j in kept):
                kept.append(int(i))
        assert thin(points, spacing, given) == sorted(kept)
