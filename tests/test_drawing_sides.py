"""Pictures tell the near side of a part from the far side, and outline the chosen elements."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from closure_nlp.model.characterize import characterize_mesh  # noqa: E402
from closure_nlp.report.drawing import HIGHLIGHT_COLOUR, draw_model, pyplot  # noqa: E402


def test_far_contacts_are_hollow_and_chosen_facets_outlined():
    model = characterize_mesh(trimesh.creation.box((1.0, 1.0, 1.0))).model
    top = next(i for i, e in enumerate(model.elements) if e.inward_normal[2] < -0.9)
    bottom = next(i for i, e in enumerate(model.elements) if e.inward_normal[2] > 0.9)
    pts = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, -0.5]])  # seen from above: top near, bottom far
    nrm = np.array([model.elements[top].inward_normal, model.elements[bottom].inward_normal])
    plt = pyplot()
    fig = plt.figure()
    try:
        ax = fig.add_subplot(projection="3d")
        draw_model(model, (pts, nrm), ax, highlight=[top], show_mesh=False, view=(30.0, -60.0))
        balls = [c for c in ax.collections if c.get_zorder() == 31]
        assert len(balls) == 2  # the far side first, then the near side
        far, near = balls
        assert np.allclose(far.get_facecolor()[0][:3], 1.0)  # hollow: white inside
        assert not np.allclose(near.get_facecolor()[0][:3], 1.0)
        assert np.allclose(far._offsets3d[2], -0.5) and np.allclose(near._offsets3d[2], 0.5)
        facets = next(c for c in ax.collections if isinstance(c, Poly3DCollection))
        fig.canvas.draw()  # colours in drawing order (sorted by depth): count them
        edge = np.array(matplotlib.colors.to_rgba(HIGHLIGHT_COLOUR))
        edges = np.all(np.isclose(facets.get_edgecolor(), edge), axis=1)
        fills = np.all(np.isclose(facets.get_facecolor()[:, :3], edge[:3]), axis=1)
        assert edges.sum() == 1 and not fills.any()  # the chosen facet outlined, not filled
    finally:
        plt.close(fig)


def test_contacts_already_in_place_are_drawn_black_and_named(tmp_path):
    """``show`` draws the first contacts of a plan's contacts.json marked ``fixed`` in black."""
    import json

    from closure_nlp.cli.show_command import fixed_count

    model = characterize_mesh(trimesh.creation.box((1.0, 1.0, 1.0))).model
    top = next(e for e in model.elements if e.inward_normal[2] < -0.9)
    entry = {"position": [0.0, 0.0, 0.5], "inward_normal": top.inward_normal.tolist()}
    path = tmp_path / "contacts.json"
    path.write_text(json.dumps({"contacts": [{**entry, "fixed": True}, entry, entry]}))
    assert fixed_count(str(path)) == 1
    pts = np.array([[0.0, 0.0, 0.5]] * 3)
    nrm = np.array([top.inward_normal] * 3)
    plt = pyplot()
    fig = plt.figure()
    try:
        ax = fig.add_subplot(projection="3d")
        draw_model(model, (pts, nrm), ax, show_mesh=False, view=(30.0, -60.0), fixed=1)
        balls = [c for c in ax.collections if c.get_zorder() == 31]
        colours = [tuple(np.round(b.get_facecolor()[0][:3], 3)) for b in balls]
        assert sorted(len(b._offsets3d[0]) for b in balls) == [1, 2]
        assert (0.0, 0.0, 0.0) in colours  # the one in place, black
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert any(t.startswith("fixed contacts") for t in labels)
    finally:
        plt.close(fig)
