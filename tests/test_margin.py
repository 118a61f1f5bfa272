"""Contacts kept a margin D from their element's boundary (``--margin``)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import closure_nlp.cli.main as cli
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import Element, Model, save_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.margin import shrunk, with_margin
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import heuristic
from tests.shapes import box_model


def _edge_distances(element: Element, point: np.ndarray) -> np.ndarray:
    """Distances from ``point`` (in the facet's plane) to each edge line of ``element``."""
    v = element.vertices
    out = []
    for j in range(len(v)):
        a, b = v[j], v[(j + 1) % len(v)]
        d = (b - a) / np.linalg.norm(b - a)
        r = point - a
        out.append(np.linalg.norm(r - (r @ d) * d))
    return np.array(out)


def test_a_facet_shrinks_inward_by_the_margin():
    rng = np.random.default_rng(0)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 7))
    polygon = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(7)])
    facet = Element("facet", polygon, [0, 0, 1])
    inner = shrunk(facet, 0.1)
    for x in inner.vertices:
        assert _edge_distances(facet, x).min() == pytest.approx(0.1, rel=1e-9)
    for w in rng.dirichlet(np.ones(len(inner.vertices)), 50):  # every point of it
        assert _edge_distances(facet, w @ inner.vertices).min() >= 0.1 - 1e-12
    assert shrunk(facet, 0.0) is facet
    assert shrunk(facet, 2.0) is None  # nothing left


def test_segments_shorten_and_points_stay():
    segment = Element("segment", [[0, 0, 0], [1, 0, 0]], [0, 1, 0])
    np.testing.assert_allclose(shrunk(segment, 0.2).vertices, [[0.2, 0, 0], [0.8, 0, 0]])
    assert shrunk(segment, 0.5) is None
    point = Element("point", [[0, 0, 0]], [0, 1, 0])
    assert shrunk(point, 5.0) is point


def test_too_small_elements_are_left_out_and_named():
    model, dropped = with_margin(box_model(1.0), 1.5)
    assert dropped == tuple(range(6))
    assert model.unusable == dropped
    model, dropped = with_margin(box_model(1.0), 0.25)
    assert dropped == () and len(model.elements) == 6 and model.unusable == ()
    with pytest.raises(ValueError, match="margin"):
        with_margin(box_model(1.0), -1.0)


@pytest.mark.slow
def test_place_keeps_the_margin(tmp_path, capsys):
    path = tmp_path / "box.model.json"
    save_model(box_model(1.0), path)
    out = tmp_path / "placed.contacts.json"
    argv = ["place", str(path), "--elements", "0,1,2,3", "--mu", "0.5", "--starts", "1"]
    code = cli.main([*argv, "--margin", "0.3", "--bound-cells", "2", "--json", "--out", str(out)])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["margin"] == 0.3
    box = box_model(1.0)
    for c in data["contacts"]:
        element = box.elements[c["element"]]
        position = np.array(c["position"])
        assert _edge_distances(element, position).min() >= 0.3 - 1e-9
        np.testing.assert_allclose(np.array(c["weights"]) @ element.vertices, position, atol=1e-9)
    assert json.loads(out.read_text())["margin"] == 0.3
    assert cli.main(["rho", str(out), "--json"]) == 0  # the written file reads back
    capsys.readouterr()
    code = cli.main([*argv, "--margin", "1.5"])
    err = capsys.readouterr().err
    assert code == 2 and "--margin" in err and "0,1,2,3" in err


def _box_with_unusable_copies() -> Model:
    """The box's six facets twice: the first six (ids 0-5) unusable, then the same six again.
    Ties in the heuristic go to the lowest id, so a selection that ignored ``unusable`` would
    pick the copies; every copy is adjacent to its twin and to the other faces' copies."""
    faces = box_model(1.0).elements
    adjacency = [(i, j) for i in range(12) for j in range(i + 1, 12) if i % 6 // 2 != j % 6 // 2]
    adjacency += [(i, i + 6) for i in range(6)]
    return Model(faces + faces, tuple(adjacency), "box twice", "", unusable=tuple(range(6)))


def test_unusable_elements_are_never_selected_nor_neighbours():
    model = _box_with_unusable_copies()
    assert model.neighbours(6) and not set(model.neighbours(6)) & set(range(6))
    specs = contact_specs(4, type="pcwf", mu=0.5)
    free = Eligibility(replace(model, unusable=()), specs, 1.0)
    assert set(heuristic(free, seed=0).elements) & set(range(6))  # the copies win the ties
    eligibility = Eligibility(model, specs, 1.0)
    options = PlacementOptions(starts=1, bound_cells=1, bound_neighbours=True)
    for seed in range(3):
        found = plan(eligibility, seeds=1, seed=seed, placement=options, alternatives=0)
        used = {*found.heuristic.elements, *found.iterative.elements, *found.placement.elements}
        used |= {e for ids in found.placement.bound_elements for e in ids}
        assert found.force_closure and min(used) >= 6, used
    with pytest.raises(ValueError, match=r"element\(s\) 2 may hold no contact"):
        eligibility([2, 7, 8, 9])
    with pytest.raises(ValueError, match="unusable"):
        Model(model.elements, (), unusable=(12,))


@pytest.mark.slow
def test_plan_keeps_the_margin_and_leaves_small_elements_out(tmp_path, capsys):
    box = box_model(1.0)
    small = box_model(0.1).elements  # a small box inside: too small for the margin
    model = Model(box.elements + small, box.adjacency, "box", "")
    path = tmp_path / "box.model.json"
    save_model(model, path)
    out = tmp_path / "run"
    argv = ["plan", str(path), "--contacts", "4", "--mu", "0.5", "--starts", "1", "--seeds", "1"]
    code = cli.main([*argv, "--margin", "0.3", "--json", "--out", str(out)])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["margin"] == 0.3
    for c in data["placement"]["contacts"]:
        element = box.elements[c["element"]]
        position = np.array(c["position"])
        assert _edge_distances(element, position).min() >= 0.3 - 1e-9
        np.testing.assert_allclose(np.array(c["weights"]) @ element.vertices, position, atol=1e-9)
    assert json.loads((out / "contacts.json").read_text())["margin"] == 0.3
    assert json.loads((out / "report.json").read_text())["options"]["margin"] == 0.3
    assert "0.3 from its element's boundary" in (out / "summary.md").read_text()
    code = cli.main([*argv, "--margin", "0.3"])
    assert code == 0 and "6 element(s) too small for it left out (6,7,8,9,10,11)" in (
        capsys.readouterr().out
    )
    code = cli.main([*argv, "--margin", "1.5"])
    err = capsys.readouterr().err
    assert code == 2 and "--margin" in err and "every element" in err
