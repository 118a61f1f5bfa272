"""Frictionless contacts' capacity in closed form (zonotope facets) and the climb on it."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.contacts import contact_specs
from closure_nlp.eligibility import Eligibility
from closure_nlp.placement import PlacementOptions, Placer
from closure_nlp.placement_bound import BoundOptions, capacity_bound
from closure_nlp.quality import rho
from closure_nlp.random_sets import random_contact_set
from closure_nlp.zonotope import climb, frictionless_capacity
from tests.shapes import box_model


def _wrenches(contact_set) -> np.ndarray:
    """(1, m, 6): each contact's normal-force wrench (column 0 of its grasp matrix)."""
    return contact_set.grasp_matrices()[None, :, :, 0]


@pytest.mark.parametrize("m", [7, 8])
def test_capacity_matches_the_certified_rho(m):
    """On random frictionless sets the closed form lies in the certified rho bracket when it is
    positive, and the certified rho is >= 0 when it is 0 (8 sets of each kind, from a pool of
    500 where force closure is rare)."""
    rng = np.random.default_rng(m)
    pool = [random_contact_set(rng, ["fpc"] * m, tilt=0.1) for _ in range(500)]
    values = frictionless_capacity(np.concatenate([_wrenches(cs) for cs in pool]))
    closure, other = np.flatnonzero(values > 0)[:8], np.flatnonzero(values == 0)[:8]
    assert len(closure) == len(other) == 8
    for k in closure:
        lo, hi = rho(pool[k]).bounds
        assert -hi * (1 - 1e-6) <= values[k] <= -lo * (1 + 1e-6)
    for k in other:
        assert rho(pool[k]).bounds[1] >= 0.0


def test_capacity_scales_with_the_wrenches():
    """The same set in other units of length and force: the capacity scales, nothing else."""
    rng = np.random.default_rng(3)
    W = np.concatenate(
        [_wrenches(random_contact_set(rng, ["fpc"] * 7, tilt=0.1)) for _ in range(300)]
    )
    base = frictionless_capacity(W)
    assert (base > 0).sum() >= 3
    for factor in (1e-3, 1e3):
        np.testing.assert_allclose(frictionless_capacity(W * factor), base * factor, rtol=1e-9)


def test_fewer_than_seven_contacts_are_never_force_closure():
    W = np.random.default_rng(0).standard_normal((4, 6, 6))
    assert np.all(frictionless_capacity(W) == 0.0)
    with pytest.raises(ValueError, match="W"):
        frictionless_capacity(np.zeros((2, 7, 5)))


def test_climb_keeps_to_the_pieces_and_only_climbs():
    """Members stay on their pieces (a segment, a square, a point) and end no lower than they
    start; the best one ends well above the start's best."""
    rng = np.random.default_rng(1)
    model = box_model(1.0)
    elements = (0, 1, 2, 3, 4, 5, 0)
    vertices, rows, starts = [], [], []
    for i, e in enumerate(elements):
        v = np.asarray(model.elements[e].vertices, float)
        if i == 1:
            v = v[:2]  # a segment
        if i == 6:
            v = v[2:3]  # a point
        cs_rows = np.stack(
            [_wrenches(_single(model, e, x))[0, 0] for x in v]
        )  # (k, 6) vertex wrenches
        vertices.append(v)
        rows.append(cs_rows)
        starts.append(rng.dirichlet(np.ones(len(v)), 50))
    before = frictionless_capacity(np.stack([s @ r for s, r in zip(starts, rows)], axis=1))
    positions, values = climb(vertices, rows, starts, 40, seed=2)
    assert np.all(values >= before) and values.max() > before.max()
    W = []
    for v, r, x in zip(vertices, rows, positions):
        # every position in its piece: its box coordinates within the piece's extent
        assert np.all(x >= v.min(axis=0) - 1e-12) and np.all(x <= v.max(axis=0) + 1e-12)
        W.append(np.stack([_wrenches(_single(model, None, p, r))[0, 0] for p in x]))
    np.testing.assert_allclose(frictionless_capacity(np.stack(W, axis=1)), values, rtol=1e-9)


def _single(model, element, x, rows=None):
    """A one-contact set at ``x`` on ``element`` (or, with ``rows``, on the element whose
    vertex wrenches those are: the normal is their force part)."""
    from closure_nlp.contacts import Contact, ContactSet

    normal = model.elements[element].inward_normal if rows is None else rows[0, :3]
    return ContactSet((Contact(np.asarray(x, float), normal, "fpc"),), 1.0)


def test_the_ceiling_search_improves_a_poor_frictionless_placement():
    """Seven frictionless contacts on the box, placed by the exchange method from a start near
    corners: the ceiling's search (its climb on the zonotope, no periodic exchange runs) returns
    a certified placement above it, and the ceiling stays above both."""
    model = box_model(1.0)
    eligibility = Eligibility(model, contact_specs(7, type="fpc"), 1.0)
    options = PlacementOptions(neighbour_moves=0, starts=1, extra_starts=0, bound=False)
    placer = Placer(eligibility, options)
    elements = (0, 1, 2, 3, 4, 5, 0)
    corner = [np.array([0.97, 0.01, 0.01, 0.01])] * 7
    poor = Placer(eligibility, PlacementOptions(**{**vars(options), "max_rounds": 1}))(
        elements, corner
    )
    found = capacity_bound(
        placer, elements, poor, BoundOptions(time_budget=1.0, root_cuts=4, polish_every=0)
    )
    assert found.placement is not None
    assert found.capacity == pytest.approx(-found.placement.bounds[1])
    assert found.capacity > max(1.05 * -poor.bounds[1], 0.0)
    assert found.value >= found.capacity


def test_climb_takes_the_same_steps_in_any_unit():
    """The box in metres and in millimetres (positions x1000, torque scale /1000): the climb's
    placements are the same ones, scaled."""
    model = box_model(1.0)
    elements = (0, 1, 2, 3, 4, 5, 0)
    runs = []
    for factor in (1.0, 1000.0):
        vertices = [np.asarray(model.elements[e].vertices, float) * factor for e in elements]
        rows = []
        for e, v in zip(elements, vertices):
            n = model.elements[e].inward_normal
            rows.append(np.hstack([np.tile(n, (len(v), 1)), np.cross(v, n) / factor]))
        starts = [np.random.default_rng(4).dirichlet(np.ones(4), 30) for _ in elements]
        runs.append(climb(vertices, rows, starts, 30, seed=5))
    (small, a), (big, b) = runs
    np.testing.assert_allclose(b, a, rtol=1e-9)
    for x, y in zip(small, big):
        np.testing.assert_allclose(y / 1000.0, x, rtol=1e-9, atol=1e-12)
