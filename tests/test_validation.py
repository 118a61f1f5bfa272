"""Input checks at the boundary: number types, accepted magnitudes, limits, unreadable files."""

import json

import numpy as np
import pytest

from closure_nlp.base.files import load_json
from closure_nlp.base.validation import (
    MAX_COORDINATE,
    MAX_ELEMENT_CONTACTS,
    MAX_SET_CONTACTS,
    SCALE_RANGE,
    as_unit_vector,
    as_vector,
)
from closure_nlp.contact.contact_set import Contact, ContactSet, contact_set_from_dict
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import Element, Model
from closure_nlp.model.meshes import read_mesh
from closure_nlp.model.scale import contact_specs


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


# --- what the API validates is a copy, kept read-only ------------------------------------------

BOX_FILE = json.loads(
    (
        __import__("pathlib").Path(__file__).resolve().parents[1]
        / "examples"
        / "box_7fpc.contacts.json"
    ).read_text()
)


def _box_from_one_buffer():
    """The box's contacts built the way a loop reuses one buffer for every position."""
    from closure_nlp.criterion.support_minimum import rho

    buffer, normal = np.empty(3), np.empty(3)
    contacts = []
    for i, entry in enumerate(BOX_FILE["contacts"]):
        buffer[:] = entry["position"]
        normal[:] = entry["inward_normal"]
        contacts.append(Contact(buffer, normal, "fpc", name=f"contacts[{i}]"))
    return rho, ContactSet(tuple(contacts), BOX_FILE["torque_scale"]), buffer, normal


def test_a_reused_buffer_changes_no_contact():
    rho, reused, buffer, normal = _box_from_one_buffer()
    expected = rho(contact_set_from_dict(BOX_FILE))
    for contact, entry in zip(reused.contacts, BOX_FILE["contacts"]):
        assert contact.position.tolist() == entry["position"]
    buffer[:] = np.nan  # the caller writes into its buffer afterwards: nothing changes
    normal[:] = 0.0
    assert rho(reused).rho == pytest.approx(expected.rho, abs=1e-9)


def test_validated_arrays_are_read_only_copies():
    position, normal = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -2.0])
    contact = Contact(position, normal)
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    element = Element("facet", vertices, [0, 0, 1])
    point = np.array([0.5, 0.5, 0.5])
    model = Model((element,), reference_point=point)
    for kept, given in (
        (contact.position, position),
        (contact.inward_normal, normal),
        (element.vertices, vertices),
        (model.reference_point, point),
    ):
        assert not np.shares_memory(kept, given)
        assert not kept.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            kept[0] = 7.0
    assert position.flags.writeable and vertices.flags.writeable  # the caller's stay writable
    vertices[0] = [9.0, 9.0, 9.0]
    point[:] = 0.0
    assert element.vertices[0].tolist() == [0.0, 0.0, 0.0]
    assert model.reference_point.tolist() == [0.5, 0.5, 0.5]


# --- closed lists compared exactly, ASCII digits, ordered ids, numpy scalars -----------------


@pytest.mark.parametrize("value", ["fpc\u00a0", "fpc ", " fpc", "fpc\n", "\uff46pc", "fpc\u200b"])
def test_contact_types_compared_exactly(value):
    from closure_nlp.contact.contact_set import ContactType

    with pytest.raises(ValueError, match="unknown contact type"):
        ContactType.parse(value)
    data = {"contacts": [{**BOX_FILE["contacts"][0], "type": value}]}
    with pytest.raises(ValueError, match=r"contacts\[0\].type: unknown contact type"):
        contact_set_from_dict(data)
    assert ContactType.parse("FPC").value == "fpc"  # ASCII case is not a stray character


@pytest.mark.parametrize("units", ["km", "mm ", "MM", "\u00b5m", 3])
def test_units_from_a_closed_list(units):
    from closure_nlp.model.elements import model_from_dict

    from .shapes import box_model

    data = box_model().to_dict()
    with pytest.raises((ValueError, TypeError), match="units: "):
        model_from_dict({**data, "units": units})
    with pytest.raises((ValueError, TypeError), match="units: "):
        contact_set_from_dict({**BOX_FILE, "units": units})
    for good in ("", "m", "cm", "mm", "in"):
        assert model_from_dict({**data, "units": good}).units == good
        contact_set_from_dict({**BOX_FILE, "units": good})


def test_duplicate_keys_refused_in_model_files(tmp_path):
    from closure_nlp.model.elements import load_model

    from .shapes import box_model

    text = json.dumps(box_model().to_dict())
    path = tmp_path / "dup.model.json"
    path.write_text(text[:-1] + ', "units": "m"}')
    with pytest.raises(ValueError, match="duplicate key 'units'"):
        load_model(path)
    nested = text.replace('"kind": "facet"', '"kind": "facet", "kind": "point"', 1)
    path.write_text(nested)
    with pytest.raises(ValueError, match="duplicate key 'kind'"):
        load_model(path)


@pytest.mark.parametrize(
    "argv",
    [
        ["eligibility", "--elements", "\uff14\uff18,1,2,3"],  # full-width 48
        ["eligibility", "--elements", "0,1,2,\u0663"],  # Arabic-Indic 3
        ["eligibility", "--elements", "0,1,2,3", "--mu", "\uff10.5"],
        ["eligibility", "--elements", "0,1,2,3", "--type", "fpc\u00a0"],
        ["select", "--contacts", "\uff14"],
        ["plan", "--contacts", "4", "--seed", "\uff11"],
        ["show", "--out", "x.png", "--highlight", "\uff11"],
    ],
)
def test_cli_reads_ascii_digits_only(tmp_path, capsys, argv):
    import os

    import closure_nlp.cli.main as cli
    from closure_nlp.model.elements import save_model

    from .shapes import box_model

    model = save_model(box_model(), tmp_path / "box.model.json")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        code = cli.main([argv[0], str(model), *argv[1:]])
    finally:
        os.chdir(cwd)
    out, err = capsys.readouterr()
    assert code == 2 and out == "", err
    assert err.startswith("error: ") and len(err.splitlines()) == 1


def test_a_set_of_element_ids_is_refused():
    from closure_nlp.placement.place import Placer
    from closure_nlp.selection.algorithms import heuristic

    from .shapes import box_model

    eligibility = Eligibility(box_model(), contact_specs(4))
    for call in (
        lambda: eligibility({0, 1, 2, 3}),
        lambda: eligibility(frozenset({0, 1, 2, 3})),
        lambda: eligibility.check_elements({0: 1, 1: 1, 2: 1, 3: 1}),
        lambda: heuristic(eligibility, start={0, 1}),
        lambda: Placer(eligibility)({0, 1, 2, 3}),
    ):
        with pytest.raises(TypeError, match="expected a list of element ids"):
            call()
    ids = eligibility.check_elements(np.array([3, 2, 1, 0]))
    assert ids == (3, 2, 1, 0) and all(type(i) is int for i in ids)


def test_numpy_booleans_and_integers_accepted_where_python_ones_are():
    from closure_nlp.criterion.support_minimum import rho
    from closure_nlp.placement.options import PlacementOptions
    from closure_nlp.selection.algorithms import SelectionOptions

    from .shapes import box_model

    model = box_model()
    eligibility = Eligibility(model, contact_specs(np.int64(4)))
    ids = [np.int64(0), np.int32(1), np.uint8(2), np.int16(3)]
    assert eligibility(ids, certify=np.bool_(False)).rho_hat == pytest.approx(
        eligibility([0, 1, 2, 3], certify=False).rho_hat, rel=1e-12
    )
    options = PlacementOptions(starts=np.int64(2), seed=np.uint32(3), certify=np.bool_(True))
    assert type(options.starts) is int and options.certify is True
    assert SelectionOptions(initial=np.int64(2), screen=np.bool_(False)).screen is False
    box = contact_set_from_dict(BOX_FILE)
    assert rho(box, certify=np.bool_(True)).force_closure
    assert model.check_id(np.int64(5), "id") == 5
    for bad in (np.bool_(True), True, 1.0, np.float64(1.0)):
        with pytest.raises(TypeError):
            model.check_id(bad, "id")
    with pytest.raises(TypeError, match="certify: expected True or False"):
        eligibility([0, 1, 2, 3], certify=1)
