"""The branch and bound: its batched matrix-game solver against an independent LP solver
(HiGHS), and its budget."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from closure_nlp import branch_bound
from closure_nlp.branch_bound import (
    BranchBoundOptions,
    _cells,
    _exact_bound,
    _game_weights,
    _initial_cells,
    sphere_minimum,
)
from closure_nlp.contacts import Contact, ContactSet, ContactType
from closure_nlp.quality import SupportMinimizer
from closure_nlp.wrenches import WrenchSlots

from . import reference
from .test_certify import symmetric_sets


def _game_upper_bound(M: np.ndarray) -> float:
    """An upper bound on max_lam min_c (M lam)_c from HiGHS's dual: corner weights ``mu``
    give ``max_k (mu M)_k >= the game's value`` whatever their accuracy."""
    C, K = M.shape
    cost = np.zeros(K + 1)
    cost[-1] = -1.0
    A_ub = np.hstack([-M, np.ones((C, 1))])  # t - (M lam)_c <= 0
    A_eq = np.hstack([np.ones((1, K)), np.zeros((1, 1))])
    bounds = [(0, None)] * K + [(None, None)]
    found = linprog(cost, A_ub=A_ub, b_ub=np.zeros(C), A_eq=A_eq, b_eq=[1.0], bounds=bounds)
    assert found.status == 0
    mu = np.maximum(-found.ineqlin.marginals, 0.0)
    return float(((mu / mu.sum()) @ M).max())


@pytest.mark.parametrize("scale", [1.0, 1e-5])
@pytest.mark.parametrize("shape", [(32, 11), (32, 95), (5, 40), (40, 3)])
def test_game_weights_reach_the_lp_value(shape, scale):
    rng = np.random.default_rng(sum(shape))
    C, K = shape
    # Batches mix easy games (a dominant column) with random ones, so rows finish at different
    # pivots; near-duplicate columns mimic support points of nearby directions.
    M = rng.normal(size=(24, C, K))
    M[::3, :, 0] += 5.0
    M[1::3, :, 1:] = M[1::3, :, :1] + 1e-9 * rng.normal(size=(8, C, K - 1))
    # A small cell's game: entries close together, far from zero (its support values).
    M = 7.0 + scale * M
    lam = _game_weights(M)
    assert np.all(lam >= 0) and np.allclose(lam.sum(axis=1), 1.0, atol=1e-12)
    values = np.einsum("nck,nk->nc", M, lam).min(axis=1)
    for n in range(len(M)):
        # Feasible weights give at most the value; the dual bound at least. The simplex runs in
        # float32 on the game scaled to [0, 1]: within 1e-6 of the spread of its entries.
        # (HiGHS on the game scaled to [0, 1] too: its tolerances are absolute.)
        low, spread = M[n].min(), M[n].max() - M[n].min()
        upper = low + spread * _game_upper_bound((M[n] - low) / spread)
        assert upper - 1e-6 * spread <= values[n] <= upper + 1e-12 * abs(upper)


def test_exact_bounds_do_not_depend_on_the_chunking(monkeypatch):
    """Exact bounds run in chunks of cells (memory): every cell's game is its own, so the bounds
    of 1100 cells are those of the same cells one small batch at a time."""
    axis, sign, lo, hi = _initial_cells(2)
    pick = np.random.default_rng(4).choice(len(lo), 1100, replace=False)
    _, _, corners, unit, nearest = _cells(axis[pick], sign[pick], lo[pick], hi[pick], np.ones(6))
    points = np.random.default_rng(5).normal(size=(len(pick), 20, 6))
    whole = _exact_bound(points, corners, unit, nearest)
    monkeypatch.setattr(branch_bound, "EXACT_CHUNK", 7)
    small = _exact_bound(points, corners, unit, nearest)
    np.testing.assert_array_equal(whole, small)
    assert np.isfinite(whole).all()


def _min_over_sphere(contact_set, max_cells, **budget):
    """The branch and bound of a contact set from its search's direction, at a small budget
    (``max_cells``) that it may or may not extend."""
    slots = WrenchSlots.from_contacts(contact_set)
    u = SupportMinimizer()(slots).direction
    gap = 1e-6 * max(1.0, abs(float(slots.support(u[None])[0])))
    options = BranchBoundOptions(max_cells=max_cells, **budget)
    return slots, sphere_minimum(slots, u, gap=gap, options=options)


def test_a_flat_minimum_converges_past_the_budget():
    # Four soft fingers on a box's faces: about 5,700 cells in all, with few alive per level.
    cs = dict(symmetric_sets())["box sfce faces (0, 1, 2, 3)"]
    slots, extended = _min_over_sphere(cs, 1000)
    assert extended.converged and extended.cells > 2000
    gap = extended.upper - extended.lower
    options = BranchBoundOptions(max_cells=1000, extended_cells=1000)
    stopped = sphere_minimum(slots, extended.direction, gap=gap, options=options)
    assert not stopped.converged and stopped.cells < 2000
    # Both brackets hold the minimum: an independent dense sample with local polish.
    p_ref, _ = reference.reference_min(reference.from_contact_set(cs), samples=300, starts=3)
    assert extended.lower <= p_ref + 1e-9 and stopped.lower <= p_ref + 1e-9


def test_a_continuum_of_minima_stops_soon_after_the_budget():
    # Two opposite soft fingers: their weakest directions form a circle, whose cells alive
    # grow level after level. The search stops once they pass twice their number at max_cells
    # (and extension_alive, here as small as that), far below extended_cells.
    pair = ContactSet(
        (
            Contact([0, 0, 1], [0, 0, -1], ContactType.SFCE, mu=0.5, mu_s=0.5),
            Contact([0, 0, -1], [0, 0, 1], ContactType.SFCE, mu=0.5, mu_s=0.5),
        )
    )
    _, found = _min_over_sphere(pair, 1000, extension_alive=1000)
    assert not found.converged
    assert 1000 < found.cells < BranchBoundOptions().extended_cells // 10


def test_the_bounds_do_not_depend_on_the_cell_chunking(monkeypatch):
    """Rounds are bounded in chunks of cells (memory) against one target and one set of
    anchors per round: the search is the same, bit for bit, one small chunk at a time. No
    start direction, so the incumbent moves within rounds, as cells find lower samples."""
    slots = WrenchSlots.from_contacts(dict(symmetric_sets())["box sfce faces (0, 1, 2, 3)"])

    def search():
        return sphere_minimum(slots, gap=1e-6, options=BranchBoundOptions(max_cells=3000))

    whole = search()
    monkeypatch.setattr(branch_bound, "CELL_CHUNK", 7)
    small = search()
    assert whole.cells > 5 * 7
    assert (small.lower, small.upper, small.cells) == (whole.lower, whole.upper, whole.cells)
    np.testing.assert_array_equal(small.direction, whole.direction)
