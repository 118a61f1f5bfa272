"""Surface elements and element models: validation, neighbours, save/load, broken files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from closure_nlp.model.elements import (
    Element,
    ElementKind,
    Model,
    load_model,
    model_from_dict,
    save_model,
)
from tests.shapes import box_facets

SQUARE = [[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]]


def square_model() -> Model:
    """A facet, a segment beside it and a point above: a chain of neighbours 0-1-2."""
    return Model(
        (
            Element("facet", SQUARE, [0, 0, 1], label="base"),
            Element("segment", [[20, 0, 0], [20, 0, 30]], [-1, 0, 0]),
            Element("point", [[5, 5, 40]], [0, 0, -2]),
        ),
        ((0, 1), (1, 2)),
        name="demo",
        units="mm",
        mesh="demo.stl",
    )


def model_dict(**changes) -> dict:
    data = square_model().to_dict()
    data.update(changes)
    return data


# --- valid elements --------------------------------------------------------------------------


def test_facet_keeps_its_vertices_and_normalises_the_normal():
    e = Element("facet", SQUARE, [0, 0, 5])
    assert e.kind is ElementKind.FACET
    np.testing.assert_allclose(e.inward_normal, [0, 0, 1])
    np.testing.assert_allclose(e.centroid, [5, 5, 0])
    assert e.size == pytest.approx(np.sqrt(200))
    np.testing.assert_allclose(e.position([0.5, 0.5, 0, 0]), [5, 0, 0])


def test_vertex_grasp_matrices_have_the_normal_as_first_column():
    e = Element("segment", [[0, 0, 0], [0, 0, 2]], [1, 0, 0])
    G = e.grasp_matrices()
    assert G.shape == (2, 6, 4)
    np.testing.assert_allclose(G[:, :3, 0], [[1, 0, 0], [1, 0, 0]])
    np.testing.assert_allclose(G[1, 3:, 0], np.cross([0, 0, 2], [1, 0, 0]))


def test_clockwise_and_straight_cornered_facets_are_valid():
    Element("facet", SQUARE[::-1], [0, 0, 1])
    Element("facet", [[0, 0, 0], [5, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], [0, 0, -1])


# --- broken elements, each with its own message ----------------------------------------------


@pytest.mark.parametrize(
    ("kind", "vertices", "normal", "message"),
    [
        ("facet", [[0, 0, 0], [10, 0, 0], [10, 10, 1], [0, 10, 0]], [0, 0, 1], "not planar"),
        (
            "facet",
            [[0, 0, 0], [10, 0, 0], [5, 2, 0], [10, 10, 0], [0, 10, 0]],
            [0, 0, 1],
            "not convex",
        ),
        ("facet", [[0, 0, 0], [10, 10, 0], [10, 0, 0], [0, 10, 0]], [0, 0, 1], "not convex"),
        ("facet", [[0, 0, 0], [1, 1, 1], [2, 2, 2]], [0, 0, 1], "collinear"),
        ("facet", [[0, 0, 0], [1, 0, 0]], [0, 0, 1], "at least 3 vertices"),
        ("facet", SQUARE, [0, 1, 1], "not perpendicular to the facet"),
        ("segment", [[0, 0, 0]], [1, 0, 0], "exactly 2 vertices"),
        ("segment", [[1, 2, 3], [1, 2, 3]], [1, 0, 0], "coincide"),
        ("segment", [[0, 0, 0], [0, 0, 1]], [0, 1, 1], "not perpendicular to the segment"),
        ("point", [[0, 0, 0], [1, 0, 0]], [1, 0, 0], "exactly 1 vertex"),
        ("point", [[0, 0, 0]], [0, 0, 0], "inward_normal"),
        ("point", [[0, 0, np.nan]], [0, 0, 1], "finite"),
        ("blob", [[0, 0, 0]], [0, 0, 1], "unknown element kind"),
    ],
)
def test_broken_element_is_rejected_naming_it(kind, vertices, normal, message):
    with pytest.raises(ValueError, match=message) as info:
        Element(kind, vertices, normal, name="elements[7]")
    assert "elements[7]" in str(info.value)


def test_zero_normal_message_says_zero():
    with pytest.raises(ValueError, match="(?i)zero"):
        Element("facet", SQUARE, [0, 0, 0], name="elements[0]")


# --- models ----------------------------------------------------------------------------------


def test_neighbours_are_symmetric_and_sorted():
    m = square_model()
    assert m.neighbours(0) == (1,)
    assert m.neighbours(1) == (0, 2)
    assert m.neighbours(2) == (1,)
    assert m.counts() == {"facet": 1, "segment": 1, "point": 1}
    with pytest.raises(ValueError, match="out of range"):
        m.neighbours(3)


def test_model_round_trip_keeps_everything(tmp_path):
    m = square_model()
    path = save_model(m, tmp_path / "demo.model.json")
    back = load_model(path)
    assert back.name == "demo" and back.units == "mm" and back.mesh == "demo.stl"
    assert back.mesh_path == tmp_path / "demo.stl"
    assert back.adjacency == m.adjacency
    assert [e.label for e in back.elements] == ["base", "", ""]
    for a, b in zip(m.elements, back.elements):
        assert a.kind is b.kind
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_allclose(a.inward_normal, b.inward_normal)
    assert back.to_dict() == m.to_dict()
    assert not list(tmp_path.glob(".*.tmp"))  # the atomic write leaves no temporary file


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"adjacency": [[0, 3]]}, r"adjacency\[0\]: element id 3 out of range"),
        ({"adjacency": [[1, 1]]}, r"adjacency\[0\]: an element is not its own neighbour"),
        ({"adjacency": [[0]]}, r"adjacency\[0\]: expected a pair"),
        ({"adjacency": [[0, "1"]]}, r"adjacency\[0\]: expected a pair"),
        ({"adjacency": {"0": 1}}, "adjacency: expected a list"),
        ({"elements": []}, "at least one element"),
        ({"elements": "none"}, "elements: expected a list"),
        ({"name": 3}, "name: expected text"),
    ],
)
def test_broken_model_is_rejected_naming_the_field(changes, message):
    with pytest.raises((ValueError, TypeError), match=message):
        model_from_dict(model_dict(**changes))


def test_broken_element_in_a_file_names_its_index(tmp_path):
    data = model_dict()
    data["elements"][1]["vertices"] = [[20, 0, 0]]
    path = tmp_path / "bad.model.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"elements\[1\]: a segment has exactly 2 vertices"):
        load_model(path)


def test_unknown_key_is_rejected(tmp_path):
    data = model_dict()
    data["elements"][0]["normal"] = [0, 0, 1]
    with pytest.raises(ValueError, match="normal"):
        model_from_dict(data)


def test_malformed_json_says_where(tmp_path):
    path = tmp_path / "broken.model.json"
    path.write_text('{"elements": [\n  {"kind": "point",]\n}')
    with pytest.raises(ValueError, match="malformed JSON at line 2"):
        load_model(path)


def test_missing_file_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match="file not found"):
        load_model(tmp_path / "nothing.model.json")


@pytest.mark.parametrize("size", [1e-15, 1e-3, 1.0, 1e11])
def test_degeneracy_is_judged_against_the_part_not_absolutely(size):
    """The same cube is a model at any scale; a facet or segment too small for the part, or a
    sliver at any scale, is refused."""
    Model(tuple(box_facets(size / 2)))  # accepted
    s = size / 2
    segment = Element("segment", [[-s, -s, -s], [s, -s, -s]], [0, 1, 1])  # a cube's edge
    Model((*box_facets(size / 2), segment))
    tiny = 1e-9 * size * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]) + [0, 0, -s]
    speck = Element("facet", tiny, [0, 0, 1], name="elements[6]")
    with pytest.raises(ValueError, match=r"elements\[6\]: the facet is .* degenerate against"):
        Model((*box_facets(size / 2), speck))
    short = Element(
        "segment", [[-s, -s, -s], [-s + 1e-9 * size, -s, -s]], [0, 1, 1], name="elements[6]"
    )
    with pytest.raises(ValueError, match=r"elements\[6\]: the segment is"):
        Model((*box_facets(size / 2), short))
    sliver = size * np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0]])
    with pytest.raises(ValueError, match="collinear"):
        Element("facet", sliver, [0, 0, 1])
