"""Input checks at the boundary: number types, accepted magnitudes, limits, unreadable files."""

import json

import numpy as np
import pytest

from closure_nlp.contacts import Contact, ContactSet, contact_set_from_dict, contact_specs
from closure_nlp.elements import Element, Model
from closure_nlp.eligibility import Eligibility
from closure_nlp.files import load_json, read_mesh
from closure_nlp.validation import (
    MAX_COORDINATE,
    MAX_ELEMENT_CONTACTS,
    MAX_SET_CONTACTS,
    SCALE_RANGE,
    as_unit_vector,
    as_vector,
)


@pytest.mark.parametrize(
    "value",
    [["0", "25", "5"], [True, False, False], [0, None, 1], [[0], 1, 2], "012", {"x": 1}, None],
)
def test_vectors_refuse_strings_booleans_and_nesting(value):
    with pytest.raises((TypeError, ValueError), match="position"):
        as_vector(value, "position", 3)


def test_vectors_refuse_integers_beyond_floats():
    with pytest.raises(ValueError, match="too large"):
        as_vector([0, 0, 10**400], "position", 3)


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e-12, 1.0, 1e155, 1e300])
def test_normals_normalised_without_overflow(scale):
    n = as_unit_vector([scale, -2 * scale, 2 * scale], "n")
    np.testing.assert_allclose(n, [1 / 3, -2 / 3, 2 / 3], rtol=1e-15)


def test_zero_normal_refused():
    with pytest.raises(ValueError, match="zero vector"):
        as_unit_vector([0.0, -0.0, 0.0], "inward_normal")


@pytest.mark.parametrize(
    "field,value",
    [
        ("mu", 1e300),
        ("mu", -1.0),
        ("mu_s", 1e300),
        ("f_max", SCALE_RANGE[1] * 10),
        ("f_max", SCALE_RANGE[0] / 10),
        ("f_max", 0.0),
        ("mu", True),
        ("f_max", "1"),
    ],
)
def test_parameters_outside_their_range_name_field_and_range(field, value):
    with pytest.raises((TypeError, ValueError), match=rf"c\.{field}: ") as info:
        Contact([0, 0, 0], [0, 0, 1], "sfce", **{field: value}, name="c")
    if isinstance(value, float):
        assert "accepted range" in str(info.value)


@pytest.mark.parametrize("torque_scale", [1e300, 1e-300, 0.0, -1.0])
def test_torque_scale_range(torque_scale):
    c = Contact([0, 0, 0], [0, 0, 1])
    with pytest.raises(ValueError, match="torque_scale: .*accepted range"):
        ContactSet((c,), torque_scale)
    # Element sets take the same range: an Eligibility at 1e300 would overflow its torque rows.
    square = Element("facet", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [0, 0, 1])
    model = Model((square,), (), "square")
    with pytest.raises(ValueError, match="torque_scale: .*accepted range"):
        Eligibility(model, contact_specs(1, type="pcwf"), torque_scale)


def test_coordinates_beyond_range():
    with pytest.raises(ValueError, match=r"c\.position: .*accepted range"):
        Contact([0, 0, MAX_COORDINATE * 2], [0, 0, 1], name="c")
    with pytest.raises(ValueError, match=r"e\.vertices: .*accepted range"):
        Element("point", [[1e200, 0, 0]], [0, 0, 1], name="e")
    with pytest.raises(TypeError, match=r"e\.vertices\[0\]\[1\]"):
        Element("point", [[0, "1", 0]], [0, 0, 1], name="e")


def test_contact_count_limits_checked_before_building():
    entries = [{"position": [0, 0, 0], "inward_normal": [0, 0, 1]}] * (MAX_SET_CONTACTS + 1)
    with pytest.raises(ValueError, match=f"limit 1..{MAX_SET_CONTACTS}"):
        contact_set_from_dict({"contacts": entries})
    with pytest.raises(ValueError, match=f"limit 1..{MAX_ELEMENT_CONTACTS}"):
        contact_specs(MAX_ELEMENT_CONTACTS + 1)


def test_json_nested_too_deep_and_huge_integers(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match="nested too deeply"):
        load_json(deep)
    digits = tmp_path / "digits.json"
    digits.write_text(json.dumps({"contacts": 1}).replace("1", "1" * 5000))
    with pytest.raises(ValueError, match="malformed JSON"):
        load_json(digits)


@pytest.mark.parametrize(
    "name,content,needle",
    [
        ("r.stl", bytes(range(256)) * 7, "not an STL file"),
        ("e.stl", b"", "not an STL file"),
        ("r.obj", bytes(range(128, 256)) * 10, "not a valid OBJ mesh"),
        ("r.ply", b"\x00\x01garbage" * 50, "not a valid PLY mesh"),
        ("r.txt", b"hello", "not a mesh file"),
    ],
)
def test_unreadable_mesh_files_are_value_errors(tmp_path, name, content, needle):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError, match=needle):
        read_mesh(path)
