"""Frictionless contacts' capacity in closed form (zonotope facets) and the climb on it."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.contact.contact_set import grasp_matrices
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.frictionless import climb, facet_rows, frictionless_capacity
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.ceiling import BoundOptions, _solve_lp, capacity_bound
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from tests.reference import zonotope_capacity
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


@pytest.mark.parametrize("m", [7, 9, 12])
def test_the_compiled_capacity_matches_the_determinants_subset_by_subset(m):
    """The compiled loop against LAPACK's determinants of every five-subset one at a time
    (tests/reference.py), on random sets (force closure and not), sets with a repeated
    generator (subsets that span no facet) and a set with every generator in one hyperplane
    (capacity 0); relative to the set's scale."""
    rng = np.random.default_rng(m)
    W = rng.standard_normal((40, m, 6)) * rng.uniform(1e-3, 1e3, (40, 1, 1))
    # the last generator a negative combination of the others: 0 inside, force closure
    W[:, -1] = -np.einsum("bj,bjk->bk", rng.uniform(0.2, 1.0, (40, m - 1)), W[:, :-1])
    W[: m - 5, :, :] = np.abs(W[: m - 5])  # all in one orthant: capacity 0
    W[10, 1] = 2.0 * W[10, 0]
    W[11, 2:4] = W[11, 0]
    W[12, :, 5] = 0.0
    values = frictionless_capacity(W)
    expected = np.array([zonotope_capacity(w / np.abs(w).max()) * np.abs(w).max() for w in W])
    assert (expected > 0).sum() >= 10 and (expected == 0).sum() >= m - 5 + 1
    scale = np.abs(W).max(axis=(1, 2))
    np.testing.assert_allclose(values, expected, rtol=1e-12, atol=1e-12 * scale.min())
    assert np.all((values > 0) == (expected > 0))


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
    from closure_nlp.contact.contact_set import Contact, ContactSet

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


def _facet_cells(seed: int, count: int, size: float):
    """Force-closure sets of 7 frictionless contacts (random positions and normals) and around
    each contact a piece of radius ``size`` in its tangent plane (a point, a segment, a triangle
    or a hexagon): per cell, each contact's vertices (k, 3) and its wrench map (positions (k, 3)
    -> wrenches (k, 6))."""
    rng = np.random.default_rng(seed)
    cells = []
    while len(cells) < count:
        cs = random_contact_set(rng, ["fpc"] * 7, tilt=0.1)
        if not frictionless_capacity(_wrenches(cs))[0] > 0.0:
            continue
        vertices, maps = [], []
        for c in cs.contacts:
            n = c.inward_normal / np.linalg.norm(c.inward_normal)
            t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
            t1 /= np.linalg.norm(t1)
            t2 = np.cross(n, t1)
            k = int(rng.choice([1, 2, 3, 6]))
            angles = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(k) / k
            offsets = np.outer(np.cos(angles), t1) + np.outer(np.sin(angles), t2)
            vertices.append(c.position + size * offsets * (k > 1))

            def wrenches(x, n=n, cs=cs, f=c.f_max):
                G = grasp_matrices(x - cs.reference_point, n, cs.torque_scale)
                return f * G[:, :, 0]

            maps.append(wrenches)
        cells.append((vertices, maps))
    return cells


def _facet_value(pieces) -> float:
    """The certified value of ``facet_rows`` (its LP's weak dual), inf without rows."""
    A = facet_rows(pieces)
    if not len(A):
        return np.inf
    owner = np.repeat(np.arange(len(pieces)), [len(p) for p in pieces])
    return max(0.0, _solve_lp(A, owner, np.zeros((len(A), 6))).value)


def _best_in_cell(vertices, rows, seed: int):
    """A climb's best placement in the cell (positions per contact) and its capacity."""
    rng = np.random.default_rng(seed)
    starts = [rng.dirichlet(np.full(len(v), 0.5), 40) for v in vertices]
    positions, values = climb(vertices, rows, starts, 120, seed=seed)
    b = int(np.argmax(values))
    return [p[b] for p in positions], float(values[b])


def _facet_violations(cells, seed: int, value=_facet_value):
    """(cells where a placement (200 random ones and a climb's best) beats the cell's bound,
    cells with a bound, climbed capacities)."""
    rng = np.random.default_rng(seed)
    bad, bounded, best = 0, 0, []
    for vertices, maps in cells:
        rows = [f(v) for f, v in zip(maps, vertices)]
        bound = value(rows)
        bounded += np.isfinite(bound)
        weights = [rng.dirichlet(np.full(len(v), 0.5), 200) for v in vertices]
        W = np.stack([w @ r for w, r in zip(weights, rows)], axis=1)  # the wrench is affine
        _, climbed = _best_in_cell(vertices, rows, seed)
        best.append(climbed)
        bad += max(climbed, frictionless_capacity(W).max()) > bound
    return bad, bounded, np.array(best)


@pytest.mark.parametrize("size", [0.001, 0.005])
def test_facet_bound_is_above_every_sampled_placement(size):
    """On 8 random cells (points, segments, triangles, hexagons around force-closure sets) no
    placement (random, or the best of a climb) has a closed-form capacity above the facet bound;
    most cells have one."""
    bad, bounded, best = _facet_violations(_facet_cells(0, 8, size), seed=1)
    assert bad == 0
    assert bounded >= 6 and np.all(best > 0.0)


def test_the_sampling_check_catches_a_bound_too_tight():
    """The same check fails with the bound lowered by 1% on the smaller cells: the climbs come
    that close to it."""

    def lowered(pieces):
        return 0.99 * _facet_value(pieces)

    bad, _, _ = _facet_violations(_facet_cells(0, 8, 0.001), seed=1, value=lowered)
    assert bad > 0


def test_facet_bound_shrinks_with_the_square_of_the_cell():
    """Cells around a climb's best placement, halved in size: the bound's excess over that
    placement's capacity falls by about 4 (second order), where a first-order bound's would
    halve."""
    ratios = []
    for vertices, maps in _facet_cells(2, 5, 0.05):
        rows = [f(v) for f, v in zip(maps, vertices)]
        best, value = _best_in_cell(vertices, rows, seed=1)
        excess = []
        for h in (0.1, 0.05):
            pieces = [f(b + h * (v - b)) for f, v, b in zip(maps, vertices, best)]
            excess.append(_facet_value(pieces) - value)
        assert excess[1] >= 0.0 and np.isfinite(excess[0])
        ratios.append(excess[1] / excess[0])
    assert np.median(ratios) < 0.4


def test_facet_rows_are_checked():
    with pytest.raises(ValueError, match="vertex_wrenches"):
        facet_rows([np.ones((1, 6))] * 6)
