"""Same part, same answer: a part in metres and in millimetres gets placements whose certified
capacities agree within the reported gaps (the ceiling is certified in both units)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import model_from_dict, nearest_weights
from closure_nlp.model.scale import contact_specs, resolve
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from tests.shapes import box_facets

MODELS = Path(__file__).resolve().parents[1] / "models"
QUICK = PlacementOptions(starts=1, extra_starts=0, neighbour_moves=0, bound_cells=6)


def _scaled(data: dict, factor: float) -> dict:
    out = dict(data)
    out["elements"] = [
        {**e, "vertices": (np.asarray(e["vertices"], float) * factor).tolist()}
        for e in data["elements"]
    ]
    if "reference_point" in data:
        out["reference_point"] = (np.asarray(data["reference_point"]) * factor).tolist()
    out.pop("mesh", None)
    return out


def _placed(model, kind: str, elements):
    scale = resolve(model)
    specs = contact_specs(len(elements), type=kind, mu=0.5, mu_s=scale.mu_s)
    return Placer(Eligibility(model, specs, scale.torque_scale), QUICK)(elements)


def _agree(a, b):
    """Both capacities lie within their gaps below the best placement, so they differ by at
    most the larger gap times the smaller ceiling."""
    cap_a, cap_b = -a.bounds[1], -b.bounds[1]
    assert a.gap is not None and b.gap is not None
    allowed = max(a.gap, b.gap) * min(a.capacity_bound, b.capacity_bound)
    assert abs(cap_a - cap_b) <= allowed + 1e-6 * max(cap_a, cap_b)
    # and each ceiling is above the other unit's placement (one part, one ceiling)
    assert cap_a <= b.capacity_bound * (1 + 1e-9) and cap_b <= a.capacity_bound * (1 + 1e-9)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, kind, elements",
    [("lamp", "pcwf", [14, 10, 55, 47]), ("cup", "sfce", None), ("pistol", "fpc", None)],
)
def test_examples_times_1000_agree_within_the_gap(name, kind, elements):
    data = json.loads((MODELS / f"{name}.model.json").read_text())
    small = model_from_dict(_scaled(data, 1.0), MODELS)
    big = model_from_dict({**_scaled(data, 1000.0), "units": ""}, MODELS)  # micrometres
    if elements is None:  # the first elements of the model's eligible kind, one per contact
        from closure_nlp.selection.algorithms import heuristic

        scale = resolve(small)
        count = 7 if kind == "fpc" else 4
        specs = contact_specs(count, type=kind, mu=0.5, mu_s=scale.mu_s)
        elements = list(heuristic(Eligibility(small, specs, scale.torque_scale), seed=0).elements)
    a, b = _placed(small, kind, elements), _placed(big, kind, elements)
    assert a.force_closure and b.force_closure
    _agree(a, b)


@pytest.mark.slow
def test_a_box_in_metres_and_millimetres_agrees_within_the_gap():
    """A domino-sized box (pybullet's domino: 0.05 x 0.025 x 0.01 m) with 4 soft fingers."""
    ids = [2, 3, 4, 5]
    _agree(_placed(_box_in(1.0), "sfce", ids), _placed(_box_in(1000.0), "sfce", ids))


@pytest.mark.parametrize("factor", [1e-3, 1.0, 1e3])
def test_nearest_weights_are_the_same_in_any_unit(factor):
    # a 3 cm triangle 0.37 m from the origin, a point beyond its edge (0, 1) and off its
    # plane: the nearest point is on that edge, at a fraction known in closed form
    triangle = np.array([[0.0, 0.0, 0.0], [0.03, 0.0, 0.0], [0.0, 0.02, 0.0]])
    offset = np.array([0.3, -0.1, 0.2])
    point = np.array([0.012, -0.004, 0.005])
    w = nearest_weights((triangle + offset) * factor, (point + offset) * factor)
    np.testing.assert_allclose(w, [0.6, 0.4, 0.0], atol=1e-9)


def _box_in(factor: float):
    """pybullet's domino as a box (0.05 x 0.025 x 0.01 m), its coordinates times ``factor``."""
    half = np.array([0.025, 0.0125, 0.005])
    elements = [
        {
            "kind": "facet",
            "vertices": f.vertices.tolist(),
            "inward_normal": f.inward_normal.tolist(),
        }
        for f in box_facets(half)
    ]
    data = {"name": "domino", "units": "m", "elements": elements}
    return model_from_dict({**_scaled(data, factor), "units": "m" if factor == 1 else "mm"})


# The exchange method alone, two starts (the centroids', then a random one): on this box the
# random start's restricted problems have non-unique optima and contacts tie for the largest
# support value, choices that round-off decided differently in each unit (11% apart in rho).
EXCHANGE_ONLY = PlacementOptions(
    starts=2, extra_starts=0, neighbour_moves=0, bound=False, lp_centre=True
)


@pytest.mark.parametrize("kind, ids", [("fpc", [5, 4, 3, 2, 1, 0, 0])])
def test_a_box_in_metres_and_millimetres_gets_the_same_placement(kind, ids):
    """Same part, same answer: the same rho to 1e-6, relative, not merely within a certified
    gap, and the same contact positions to 1e-5 of the part's size (ten times finer than the
    digits printed). The exchange stops once a round gains under 1e-6 of rho, and rho is flat to
    first order along the optimum, so the two units' round-off may stop it a few 1e-6 of the
    size apart."""
    placed = []
    for factor in (1.0, 1000.0):
        model = _box_in(factor)
        scale = resolve(model)
        specs = contact_specs(len(ids), type=kind, mu=0.2, mu_s=scale.mu_s)
        placer = Placer(Eligibility(model, specs, scale.torque_scale), EXCHANGE_ONLY)
        placed.append((placer(ids), model.radius))
    (a, radius_a), (b, radius_b) = placed
    assert radius_b == pytest.approx(1000.0 * radius_a, rel=1e-12)
    xa = np.array([c.position for c in a.contacts]) / radius_a
    xb = np.array([c.position for c in b.contacts]) / radius_b
    np.testing.assert_allclose(xa, xb, rtol=0, atol=1e-5)
    assert abs(a.rho - b.rho) <= 1e-6 * max(abs(a.rho), abs(b.rho))
    assert a.force_closure and b.force_closure
