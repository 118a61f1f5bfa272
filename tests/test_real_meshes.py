"""Parts as users bring them: metre-scale files, several bodies, large holes, smooth meshes.

Every mesh here is made by trimesh, so the suite needs no dataset package.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from closure_nlp.cli.main import main
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.characterize import SPACING_FRACTION, characterize_mesh, winding_number
from closure_nlp.model.elements import load_model, save_model
from closure_nlp.model.scale import MU_S_FRACTION, contact_specs, resolve, scale_warnings

DOMINO = (0.025, 0.006, 0.051)  # metres, like pybullet's domino


def domino(factor: float = 1.0, offset=(0.3, -0.1, 0.2)) -> trimesh.Trimesh:
    """The domino, by default far from the origin like a part in a scene."""
    box = trimesh.creation.box(extents=DOMINO)
    box.apply_translation(offset)
    box.apply_scale(factor)
    return box


def test_metre_and_millimetre_parts_give_the_same_wrenches_with_the_defaults():
    found = {u: characterize_mesh(domino(f), units=u) for u, f in (("m", 1.0), ("mm", 1000.0))}
    m, mm = found["m"].model, found["mm"].model
    assert m.counts() == mm.counts() == {"facet": 6, "segment": 0, "point": 0}
    # Torques about the centre of mass, not the scene's origin.
    assert np.allclose(m.reference_point, [0.3, -0.1, 0.2], atol=1e-12)
    assert np.allclose(mm.reference_point, 1000 * m.reference_point, rtol=1e-12)
    scales = {u: resolve(f.model) for u, f in found.items()}
    assert scales["m"].torque_scale == pytest.approx(1000 * scales["mm"].torque_scale, rel=1e-12)
    assert scales["mm"].mu_s == pytest.approx(MU_S_FRACTION * mm.radius)
    hands = {
        u: Eligibility(
            f.model, contact_specs(4, type="sfce", mu_s=scales[u].mu_s), scales[u].torque_scale
        )
        for u, f in found.items()
    }
    ids = [0, 1, 2, 3]
    a, b = hands["m"].slots(ids), hands["mm"].slots(ids)
    for x, y in zip(a.slot_values(np.eye(6)), b.slot_values(np.eye(6))):
        assert np.allclose(x, y, rtol=1e-9, atol=1e-12)
    # The same certificate in both units: the spin column counts times mu_s (a length) in the
    # set's scales; unweighted, the metre part's bracket stopped at [-0.339, -0.030].
    r_m, r_mm = hands["m"](ids), hands["mm"](ids)
    assert r_m.converged and r_mm.converged
    assert r_m.rho_hat == pytest.approx(r_mm.rho_hat, rel=1e-6)
    np.testing.assert_allclose(r_m.bounds, r_mm.bounds, rtol=1e-6)
    assert not scale_warnings(scales["m"], ["sfce"]) and not scale_warnings(scales["mm"], ["sfce"])


def test_scale_warnings_name_what_looks_wrong():
    part = characterize_mesh(domino(), units="mm").model  # a 0.03 mm "part": a file in metres
    scale = resolve(part, torque_scale=1e4, mu_s=0.2)  # torque rows 286x the force rows
    lines = scale_warnings(scale, ["sfce"])
    assert any("far too small" in line and "another unit" in line for line in lines)
    assert any("torque rows and force rows differ" in line for line in lines)
    assert any("mu_s 0.2 exceeds the part's radius" in line for line in lines)


@pytest.mark.slow
def test_metre_scale_domino_plan_spreads_locators_like_millimetres():
    from closure_nlp.planning.plan import plan

    runs, spread, hands = {}, {}, {}
    for units, factor in (("m", 1.0), ("mm", 1000.0)):
        model = characterize_mesh(domino(factor), units=units).model
        scale = resolve(model)
        hand = Eligibility(model, contact_specs(7, type="fpc"), scale.torque_scale)
        hands[units] = hand
        runs[units] = run = plan(hand, seeds=1, seed=0)
        assert run.placement.force_closure
        starts = np.array([model.elements[e].centroid for e in run.placement.elements])
        positions = np.array([c.position for c in run.placement.contacts])
        spread[units] = np.abs(positions - starts).max() / model.radius
    m, mm = runs["m"], runs["mm"]
    # The domino's two large faces tie for the seventh locator (mirror images of each other):
    # the search's round-off may take either. Either set is as eligible in both units.
    assert m.iterative.rho_hat == pytest.approx(mm.iterative.rho_hat, rel=1e-9)
    if m.iterative.elements != mm.iterative.elements:
        swapped = hands["mm"](m.iterative.elements).rho_hat
        assert swapped == pytest.approx(mm.iterative.rho_hat, rel=1e-9)
    assert min(spread.values()) > 0.05  # the locators left the face centres
    # The placement is a local method: round-off differences between the two files' grasp
    # matrices (1e-16) can end it in another optimum, so only the same depth is asked here.
    assert m.placement.rho == pytest.approx(mm.placement.rho, rel=0.25)


def test_overlapping_bodies_are_merged_and_no_element_lies_inside():
    a = trimesh.creation.box(extents=[2.0, 1.0, 1.0])
    b = trimesh.creation.box(extents=[1.0, 1.0, 2.0])
    b.apply_translation([0.5, 0.0, 0.5])
    both = trimesh.util.concatenate([a, b])
    found = characterize_mesh(both, segment_spacing=0, point_spacing=0)
    assert any("boolean union" in r for r in found.repairs)
    union = trimesh.boolean.union([a, b], engine="manifold")
    step = 1e-3
    for e in found.model.elements:
        probe = e.centroid
        assert winding_number(union, [probe + step * e.inward_normal])[0] > 0.5
        assert winding_number(union, [probe - step * e.inward_normal])[0] < 0.5
    assert found.model.counts()["facet"] <= 12  # one L-shaped union, not two boxes' 12 faces


def test_bodies_touching_face_to_face_become_one_part():
    a = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    b = a.copy()
    b.apply_translation([1.0, 0.0, 0.0])  # a convex decomposition of a 2 x 1 x 1 block
    found = characterize_mesh(trimesh.util.concatenate([a, b]))
    assert found.model.counts() == {"facet": 6, "segment": 0, "point": 0}


def test_large_holes_of_a_curved_part_are_capped():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    keep = sphere.triangles_center[:, 2] < 0.8  # a cap cut off: one large, non-planar hole
    opened = trimesh.Trimesh(sphere.vertices, sphere.faces[keep])
    assert not opened.is_watertight
    found = characterize_mesh(opened, close_holes=True)  # an opening: capped when asked
    [line] = found.repairs
    assert line.startswith("filled 1 hole(s) bounded by ")
    assert int(line.split("bounded by ")[1].split()[0]) > 10
    assert len(found.model) > 0


def test_smooth_mesh_with_defaults_gets_a_spacing_from_its_size(tmp_path, capsys):
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.05)  # 2,562 vertices, metres
    sphere.export(tmp_path / "ball.stl")
    out = tmp_path / "ball.model.json"
    code = main(
        ["characterize", str(tmp_path / "ball.stl"), "--units", "m", "--out", str(out), "--json"]
    )
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["point_spacing"] == pytest.approx(SPACING_FRACTION * 0.05, rel=1e-3)
    model = load_model(out)
    points = np.array([e.vertices[0] for e in model.elements])
    assert 50 <= len(points) <= 600  # thinned from 2,562, but still covering the ball
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(len(points))
    assert gaps.min() >= payload["point_spacing"] * (1 - 1e-9)  # no duplicates, spacing held
    assert model.units == "m" and np.allclose(model.reference_point, 0, atol=1e-9)


def test_old_model_files_mean_the_origin_and_new_ones_keep_their_point(tmp_path):
    found = characterize_mesh(domino(), units="m")
    path = save_model(found.model, tmp_path / "d.model.json")
    data = json.loads(path.read_text())
    assert data["reference_point"] == found.model.reference_point.tolist()
    again = load_model(path)
    assert np.array_equal(again.reference_point, found.model.reference_point)
    del data["reference_point"]
    path.write_text(json.dumps(data))
    old = load_model(path)
    assert not old.reference_point.any()
    # Moments about the origin differ from moments about the centre of mass by r x f.
    G_new = again.elements[0].grasp_matrices()
    G_old = old.elements[0].grasp_matrices()
    assert np.allclose(G_new[:, :3], G_old[:, :3])
    assert not np.allclose(G_new[:, 3:], G_old[:, 3:])


def test_crack_at_a_t_junction_is_closed():
    box = trimesh.creation.box()
    faces = box.faces.tolist()
    a, c = (int(v) for v in box.face_adjacency_edges[0])
    i = next(
        k for k, f in enumerate(faces) if any(f[j] == c and f[(j + 1) % 3] == a for j in range(3))
    )
    j = next(j for j in range(3) if faces[i][j] == c and faces[i][(j + 1) % 3] == a)
    x = faces[i][(j + 2) % 3]
    m = len(box.vertices)  # a vertex on edge a-c, used by one side only: a zero-area crack
    vertices = np.vstack([box.vertices, (box.vertices[a] + box.vertices[c]) / 2])
    faces[i] = [c, m, x]
    faces.append([m, a, x])
    cracked = trimesh.Trimesh(vertices, faces, process=False)
    assert not cracked.is_watertight
    found = characterize_mesh(cracked)
    assert any("T-junctions" in r for r in found.repairs)
    assert found.model.counts() == {"facet": 6, "segment": 0, "point": 0}


def test_cli_characterize_of_a_mesh_elsewhere_writes_the_repaired_mesh_beside_the_model(
    tmp_path, capsys
):
    (tmp_path / "data").mkdir()
    (tmp_path / "models").mkdir()
    a = trimesh.creation.box(extents=[0.02, 0.01, 0.01])
    b = trimesh.creation.box(extents=[0.01, 0.01, 0.03])
    trimesh.util.concatenate([a, b]).export(tmp_path / "data" / "cross.obj")
    out = tmp_path / "models" / "cross.model.json"
    args = ["characterize", str(tmp_path / "data" / "cross.obj"), "--units", "m", "--out", str(out)]
    assert main(args) == 0
    assert "merged 2 bodies" in capsys.readouterr().out
    model = load_model(out)
    assert model.mesh == "cross.mesh.stl"
    drawn = trimesh.load(tmp_path / "models" / "cross.mesh.stl")
    assert drawn.is_watertight and drawn.body_count == 1  # the union, not the two boxes
    assert main(["show", str(out), "--out", str(tmp_path / "cross.png")]) == 0
