"""Open meshes: small holes filled and reported, openings refused unless asked, several bodies
held as one part only when asked and then said. Every mesh is made here by trimesh."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from closure_nlp.cli.main import main
from closure_nlp.model.meshes import holes_filled, load_mesh, repair_mesh


def grid_box(n: int) -> trimesh.Trimesh:
    """A unit cube whose faces are n x n grids of squares, two triangles each."""
    vertices, faces, index = [], [], {}

    def vertex(p) -> int:
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(vertices)
            vertices.append(p)
        return index[key]

    for axis in range(3):
        u, v = [k for k in range(3) if k != axis]
        for side in (-0.5, 0.5):
            for i in range(n):
                for j in range(n):
                    quad = []
                    for a, b in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)):
                        p = np.zeros(3)
                        p[axis], p[u], p[v] = side, -0.5 + a / n, -0.5 + b / n
                        quad.append(vertex(p))
                    faces += [quad[:3], [quad[0], quad[2], quad[3]]]
    box = trimesh.Trimesh(np.array(vertices), np.array(faces), process=False)
    trimesh.repair.fix_normals(box)
    return box


def holed_box() -> trimesh.Trimesh:
    """A fine box with a 3-edge hole on its -z face and a 24-edge one (1 x 11 squares) on top."""
    n = 32
    box = grid_box(n)
    c = box.triangles_center
    x, y = c[:, 0] * n, c[:, 1] * n  # in squares; the grid's lines are at whole numbers
    slot = (c[:, 2] > 0.49) & (x > 0) & (x < 1) & (y > -5) & (y < 6)
    keep = ~slot
    keep[np.flatnonzero(c[:, 2] < -0.49)[0]] = False
    return trimesh.Trimesh(box.vertices, box.faces[keep], process=False)


def cup() -> trimesh.Trimesh:
    """A can without its lid: its mouth is an opening, not a defect."""
    cyl = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=24)
    return trimesh.Trimesh(cyl.vertices, cyl.faces[cyl.face_normals[:, 2] < 0.5])


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_small_holes_are_filled_and_reported(tmp_path, capsys):
    mesh = tmp_path / "holed.obj"
    holed_box().export(mesh)
    out = tmp_path / "holed.model.json"
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out, "--json")
    assert code == 0, err
    payload = json.loads(stdout)
    assert payload["holes_filled"] == [3, 24]
    assert "filled 2 hole(s) bounded by 3, 24 edges" in payload["repairs"]
    assert payload["elements"]["facet"] == 6
    [line] = [x for x in err.splitlines() if "filled" in x]
    assert line == f"warning: {mesh}: filled 2 hole(s) bounded by 3, 24 edges"


def test_holes_meeting_at_a_vertex_are_filled():
    """Two holes sharing a corner make one boundary that passes a vertex twice: it is cut there
    into two loops, each capped."""
    n = 32
    box = grid_box(n)
    c = box.triangles_center
    top, h = c[:, 2] > 0.49, 2.0 / n
    a = top & (c[:, 0] > 0) & (c[:, 0] < h) & (c[:, 1] > 0) & (c[:, 1] < h)
    b = top & (c[:, 0] < 0) & (c[:, 0] > -h) & (c[:, 1] < 0) & (c[:, 1] > -h)
    repairs = []
    closed = repair_mesh(trimesh.Trimesh(box.vertices, box.faces[~(a | b)]), "m", repairs)
    assert closed.is_watertight and closed.volume == pytest.approx(1.0)
    assert [r.holes for r in repairs if r.holes] == [(8, 8)]


def test_loose_squares_whose_vertices_meet_once_merged_are_one_part(tmp_path):
    """An OBJ whose squares each have their own vertices, one triangle missing: every square is
    an open piece as the file gives it; once its vertices are merged the part has one small
    hole."""
    box = grid_box(8)
    lines, k = [], 0
    for pair in box.faces.reshape(-1, 2, 3):
        used = list(dict.fromkeys(pair.ravel().tolist()))
        lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in box.vertices[used]]
        for face in pair[: 1 if k == 0 else 2]:  # the first square is half a square
            lines.append("f " + " ".join(str(k + 1 + used.index(i)) for i in face))
        k += len(used)
    path = tmp_path / "squares.obj"
    path.write_text("\n".join(lines) + "\n")
    repairs = []
    closed = load_mesh(path, None, repairs)
    assert closed.is_watertight and closed.volume == pytest.approx(1.0)
    assert holes_filled(repairs) == [3]


def test_an_opening_is_refused_unless_closing_is_asked(tmp_path, capsys):
    mesh = tmp_path / "cup.stl"
    cup().export(mesh)
    out = tmp_path / "cup.model.json"
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out)
    assert code == 2 and not out.exists()
    assert err.startswith(f"error: {mesh}: the mesh is open: a hole bounded by 24 edges")
    assert "opening" in err and "--close-holes" in err and len(err.splitlines()) == 1
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out, "--close-holes", "--json")
    assert code == 0, err
    payload = json.loads(stdout)
    assert payload["holes_filled"] == [24]
    assert payload["elements"]["facet"] == 2
    assert err.count("filled 1 hole(s) bounded by 24 edges") == 1


def test_separate_bodies_are_refused_and_said_when_merged(tmp_path, capsys):
    boxes = []
    for k in range(3):
        box = trimesh.creation.box((1.0, 1.0, 1.0))
        box.apply_translation([3.0 * k, 0.0, 0.0])
        boxes.append(box)
    mesh = tmp_path / "boxes.stl"
    trimesh.util.concatenate(boxes).export(mesh)
    out = tmp_path / "boxes.model.json"
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out)
    assert code == 2 and "3 separate bodies" in err and "--merge-bodies" in err
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out, "--merge-bodies", "--json")
    assert code == 0, err
    payload = json.loads(stdout)
    assert payload["merged_bodies"] == 3 and payload["holes_filled"] == []
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out, "--merge-bodies")
    assert code == 0, err
    assert f"{mesh}: 3 separate bodies held as one rigid part (--merge-bodies)" in stdout


def test_one_body_reports_no_merged_bodies(tmp_path, capsys):
    mesh = tmp_path / "box.stl"
    trimesh.creation.box((1.0, 2.0, 3.0)).export(mesh)
    out = tmp_path / "box.model.json"
    code, stdout, err = run(capsys, "characterize", mesh, "--out", out, "--json")
    assert code == 0, err
    payload = json.loads(stdout)
    assert payload["merged_bodies"] == 0 and payload["holes_filled"] == [] and not err
