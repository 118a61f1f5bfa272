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
