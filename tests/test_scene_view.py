"""The interactive 3-D view: the same up axis as the pictures, a camera that sees the contacts,
contacts above the surface, a title with rho and a legend; a headless browser renders it."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.cli.main import main
from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.model.elements import load_model
from closure_nlp.report.drawing import UP_AXES, build_scene, export_scene, model_extent, scene_view

MODELS = Path(__file__).resolve().parents[1] / "models"
BOX = Path(__file__).resolve().parents[1] / "examples" / "box_7fpc.contacts.json"


@pytest.mark.parametrize("up", ["x", "y", "z"])
def test_the_models_up_axis_is_the_viewers_up(up):
    """three.js draws +y upwards: the model's ``up`` axis must land there, the pictures' other
    two axes (UP_AXES) as their horizontal ones, by a rotation (no mirror image)."""
    lamp = load_model(MODELS / "lamp.model.json")
    scene = build_scene(lamp, up=up)
    a, b, c = UP_AXES[up]
    element = lamp.elements[0]
    lifted = element.vertices - 0.002 * model_extent(lamp) * element.inward_normal
    expected = np.column_stack([lifted[:, a], lifted[:, c], -lifted[:, b]])  # x, up, -y drawn
    shown = scene.geometry["element_0"].vertices[: len(expected)]
    assert np.allclose(shown, expected, atol=1e-9 * lamp.radius)


def test_contacts_sit_above_the_surface_and_face_the_camera():
    """Each ball's centre lies outside the part along its contact's outward normal, and the
    camera looks from the side the contacts face."""
    lamp = load_model(MODELS / "lamp.model.json")
    facet = lamp.elements[14]
    n = facet.inward_normal
    contacts = ContactSet((Contact(facet.centroid, n), Contact(facet.centroid + 1.0, n)))
    scene = build_scene(lamp, contacts, up="z")
    for k, c in enumerate(contacts.contacts):
        centre = scene.geometry[f"contact_{k}"].vertices.mean(axis=0)
        p = np.array([c.position[0], c.position[2], -c.position[1]])
        outward = -np.array([n[0], n[2], -n[1]])
        offset = centre - p
        assert offset @ outward > 0.9 * np.linalg.norm(offset) > 0
    eye = scene.camera_transform[:3, 2]  # the camera looks down its -z: this points to the eye
    assert eye @ -np.array([n[0], n[2], -n[1]]) > 0.05


def test_the_camera_sees_the_most_contacts():
    """Contacts on opposite sides: no view sees both; with three facing +x and one -x the
    camera takes the +x side. The default view (the pictures') wins a tie."""
    bounds = np.array([[-1.0, -1, -1], [1, 1, 1]])
    normals = np.array([[-1.0, 0, 0]] * 3 + [[1.0, 0, 0]])  # inward: three seen from +x
    eye = scene_view(bounds, np.zeros((4, 3)), normals)[:3, 2]
    assert eye[0] > 0.05
    default = scene_view(bounds, np.zeros((0, 3)), np.zeros((0, 3)))[:3, 2]
    e, a = np.radians(22.0), np.radians(-58.0)
    assert np.allclose(default, [np.cos(e) * np.cos(a), np.sin(e), -np.cos(e) * np.sin(a)])
    camera = scene_view(bounds, np.zeros((4, 3)), normals)
    assert np.allclose(camera[:3, :3].T @ camera[:3, :3], np.eye(3))
    assert np.linalg.norm(camera[:3, 3]) > 2 * np.sqrt(3)  # the whole box in a 45 degree view


def test_the_page_has_a_title_with_rho_and_a_legend(tmp_path, capsys):
    out = tmp_path / "lamp.html"
    lamp = MODELS / "lamp.model.json"
    facets = load_model(lamp).elements
    contacts = ContactSet(
        tuple(Contact(facets[e].centroid, facets[e].inward_normal) for e in (14, 10, 55, 47)),
        torque_scale=1 / 60,
    )
    path = tmp_path / "four.contacts.json"
    path.write_text(__import__("json").dumps(contacts.to_dict()))
    assert main(["show", str(lamp), "--contacts", str(path), "--out", str(out)]) == 0
    assert main(["rho", str(path)]) == 0
    printed = capsys.readouterr().out
    value = re.search(r"rho = (\S+) \(", printed.splitlines()[-1]).group(1)
    page = out.read_text()
    assert f"<title>lamp: 4 contacts, rho = {value} (force closure)</title>" in page
    legend = re.search(r'<div id="legend".*?</div></div>', page).group(0)
    assert "facets" in legend and "contacts" in legend and "segments" not in legend


def _browser() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_browser() is None, reason="no headless Chromium on this machine")
def test_a_headless_browser_renders_the_page(tmp_path):
    """Chromium (software WebGL) draws the scene: the screenshot holds the contacts' red, the
    chosen elements' orange and the facets' blue, not a blank or an error page."""
    from matplotlib.image import imread

    lamp = load_model(MODELS / "lamp.model.json")
    facets = lamp.elements
    contacts = ContactSet(
        tuple(Contact(facets[e].centroid, facets[e].inward_normal) for e in (14, 10, 55, 47))
    )
    page = export_scene(lamp, contacts, tmp_path / "view.html", highlight=(14, 10, 55, 47))
    shot = tmp_path / "shot.png"
    command = [
        _browser(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--hide-scrollbars",
        "--window-size=800,600",
        "--virtual-time-budget=8000",
        f"--screenshot={shot}",
        page.as_uri(),
    ]
    subprocess.run(command, check=True, capture_output=True, timeout=120)
    pixels = imread(shot)[..., :3]
    assert pixels.shape[:2] == (600, 800)

    def share(colour, tol=0.12):
        return np.mean(np.all(np.abs(pixels - np.array(colour)) < tol, axis=-1))

    assert share([0.75, 0.22, 0.17]) > 1e-4  # contacts (#c0392b, shaded)
    assert share([0.95, 0.55, 0.15], 0.2) > 1e-4  # chosen elements
    assert share([1.0, 1.0, 1.0], 0.02) < 0.97  # not a blank page
