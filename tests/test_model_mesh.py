"""A model's mesh: its path stays in the model's folder, a missing one is one warning, and
facet and segment normals that point out of it are refused."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

import closure_nlp.cli.main as cli
from closure_nlp.model.elements import ElementKind, load_model
from closure_nlp.model.model_mesh import check_normals, read_model_mesh

MODELS = Path(__file__).resolve().parents[1] / "models"


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def cup(tmp_path):
    """The cup model and its mesh in tmp/model/, another copy of the mesh in tmp/elsewhere/."""
    (tmp_path / "model").mkdir()
    (tmp_path / "elsewhere").mkdir()
    shutil.copy(MODELS / "cup.stl", tmp_path / "model" / "cup.stl")
    shutil.copy(MODELS / "cup.stl", tmp_path / "elsewhere" / "part.stl")
    data = json.loads((MODELS / "cup.model.json").read_text())

    def write(name, **changes):
        path = tmp_path / "model" / name
        path.write_text(json.dumps({**data, **changes}))
        return path

    return write, data


@pytest.mark.parametrize("mesh", ["../elsewhere/part.stl", "/etc/hostname", "sub/../../x.stl"])
def test_mesh_outside_the_model_folder_is_refused(cup, capsys, tmp_path, mesh):
    write, _ = cup
    path = write("out.model.json", mesh=mesh)
    code, out, err = run(capsys, "show", path, "--out", tmp_path / "x.png")
    assert code == 2 and out == ""
    assert err.startswith(f"error: {path}: mesh: ") and "outside the model's folder" in err
    assert "--allow-outside-mesh" in err and len(err.splitlines()) == 1


def test_allow_outside_mesh_reads_it(cup, capsys, tmp_path):
    write, _ = cup
    path = write("out.model.json", mesh="../elsewhere/part.stl")
    code, _, err = run(capsys, "show", path, "--out", tmp_path / "x.glb", "--allow-outside-mesh")
    assert code == 0 and err == ""
    assert b"mesh" in (tmp_path / "x.glb").read_bytes()


@pytest.mark.parametrize("name,content", [("gone.stl", None), ("notes.txt", "hello")])
def test_missing_or_broken_mesh_is_one_warning(cup, capsys, tmp_path, name, content):
    write, _ = cup
    if content is not None:
        (tmp_path / "model" / name).write_text(content)
    path = write("m.model.json", mesh=name)
    code, _, err = run(capsys, "show", path, "--out", tmp_path / "x.png")
    assert code == 0
    assert err.startswith("warning: mesh ") and name in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("kind", ["facet", "segment"])
def test_flipped_normal_is_refused_naming_the_element(cup, capsys, kind):
    write, data = cup
    elements = [dict(e) for e in data["elements"]]
    i = next(k for k, e in enumerate(elements) if e["kind"] == kind)
    elements[i]["inward_normal"] = [-x for x in elements[i]["inward_normal"]]
    path = write("flip.model.json", elements=elements)
    code, out, err = run(capsys, "eligibility", path, "--elements", "0,1,2,3")
    assert code == 2 and out == ""
    assert err.startswith(f"error: {path}: elements[{i}].inward_normal: points out of")


@pytest.mark.parametrize("name", ["lamp", "cup", "pistol"])
def test_every_single_flip_caught_and_no_false_refusal(name):
    model = load_model(MODELS / f"{name}.model.json")
    mesh = read_model_mesh(model)
    check_normals(model, mesh)  # the shipped models are right
    for i, element in enumerate(model.elements):
        if element.kind is ElementKind.POINT:
            continue
        elements = list(model.elements)
        elements[i] = replace(element, inward_normal=-element.inward_normal)
        with pytest.raises(ValueError, match=rf"elements\[{i}\]\.inward_normal"):
            check_normals(replace(model, elements=tuple(elements)), mesh)
