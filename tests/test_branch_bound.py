"""The branch and bound: its matrix-game solver against an independent LP solver (HiGHS), its
cell bounds against the reference support function, and its budget."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linprog

from benchmarks.bench import ring
from closure_nlp.contact.contact_set import Contact, ContactSet, ContactType, contact_set_from_dict
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import certified_bounds
from closure_nlp.criterion.sphere_branch_bound import (
    BranchBoundOptions,
    _initial_cells,
    sphere_minimum,
)
from closure_nlp.criterion.sphere_search import sphere_samples
from closure_nlp.criterion.support_minimum import SupportMinimizer
from closure_nlp.kernels import branch_bound as kernels

from . import reference
from .test_certify import symmetric_sets

DATA = Path(__file__).parent / "data"


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
    lam = np.empty((len(M), K))
    for n in range(len(M)):
        kernels.game_weights(M[n], lam[n])
    assert np.all(lam >= 0) and np.allclose(lam.sum(axis=1), 1.0, atol=1e-12)
    values = np.einsum("nck,nk->nc", M, lam).min(axis=1)
    for n in range(len(M)):
        # Feasible weights give at most the value; the dual bound at least. The simplex runs on
        # the game scaled to [0, 1]: within 1e-6 of the spread of its entries.
        # (HiGHS on the game scaled to [0, 1] too: its tolerances are absolute.)
        low, spread = M[n].min(), M[n].max() - M[n].min()
        upper = low + spread * _game_upper_bound((M[n] - low) / spread)
        assert upper - 1e-6 * spread <= values[n] <= upper + 1e-12 * abs(upper)


def test_game_weights_stop_once_their_value_reaches_the_target():
    """A cell's game needs no more than its target: weights stopped there reach it (they give
    the bound that drops the cell), with fewer pivots than the full game."""
    rng = np.random.default_rng(3)
    saved = 0
    for _ in range(20):
        M = 7.0 + rng.normal(size=(32, 60))
        full = np.empty(60)
        pivots = kernels.game_weights(M, full)
        value = (M @ full).min()
        stop = value - 0.2 * (value - M.min(axis=0).max())  # between one column's and the game's
        lam = np.empty(60)
        fewer = kernels.game_weights(M, lam, stop)
        assert (M @ lam).min() >= stop - 1e-12 * abs(stop)
        assert fewer <= pivots
        saved += pivots - fewer
    assert saved > 0


def test_game_weights_give_up_only_below_the_lp_value():
    """A game asked to give up below a level stops early only when the LP's value is below it
    (the mix of rows it reads is an upper bound), and one whose value is above the level runs
    to it: giving up costs a cell only the pivots that could not drop it."""
    rng = np.random.default_rng(5)
    gave_up = 0
    for _ in range(20):
        M = 7.0 + rng.normal(size=(32, 55))
        low, spread = M.min(), M.max() - M.min()
        best = low + spread * _game_upper_bound((M - low) / spread)
        for level in (best + 0.02 * spread, best - 0.02 * spread):
            lam = np.empty(55)
            pivots = kernels.game_weights(M, lam, np.inf, kernels.MAX_PIVOTS, level)
            if pivots < 0:
                gave_up += 1
                assert best < level
            else:
                assert (M @ lam).min() >= best - 1e-6 * spread
    assert gave_up > 0


@pytest.mark.parametrize("kind", ["fpc", "pcwf", "sfcl", "sfce", "mixed"])
def test_cell_bounds_hold_under_the_reference(kind):
    """Every stage of a cell's bound (single support points, Frank-Wolfe combinations with the
    anchors, the exact game of small cells: target +inf runs all three; at the incumbent's
    value the games stop early) lies below the reference support function at random
    directions of the cell."""
    rng = np.random.default_rng(len(kind))
    types = ["fpc", "pcwf", "sfcl", "sfce"] if kind == "mixed" else [kind] * 4
    cs = random_contact_set(rng, types * (2 if kind == "fpc" else 1))
    slots, ref = WrenchSlots.from_contacts(cs), reference.from_contact_set(cs)
    axis, sign, lo, hi = _initial_cells(2)
    pick = rng.choice(len(lo), 40, replace=False)
    axis, sign, lo, hi = axis[pick], sign[pick], lo[pick], hi[pick]
    best, best_u = np.array([np.inf, 0.0]), np.zeros(6)
    U, points, values = (np.empty((len(pick), *shape)) for shape in ((11, 6), (11, 6), (11,)))
    # the centres' samples and the cells' geometry, every cell kept (no gap reached)
    geo, centre_w, centre_v = (
        kernels.geometry(len(pick)),
        np.empty((len(pick), 6)),
        np.empty(len(pick)),
    )
    tally = np.array([np.inf, 0, 0, -1, 0, 0], dtype=float)
    live = kernels.screen_centres(
        *slots.packed, axis, sign, lo, hi, np.eye(6), 1.0, -np.inf, 0.0, tally, best, best_u, geo,
        False, centre_w, centre_v,
    )  # fmt: skip
    assert len(live) == len(pick)
    kernels.evaluate_cells(
        *slots.packed, axis, sign, lo, hi, np.eye(6), U, points, values, best, best_u, centre_w,
        centre_v,
    )  # fmt: skip
    # the geometry as the screen left it, then computed afresh into room for it
    fresh = kernels.geometry(len(pick))
    bounds = [
        kernels.bound_cells(
            *slots.packed, axis, sign, lo, hi, np.eye(6), 1.0, U, points, values, target, target,
            0.0, 12, 10.0, best, best_u, np.empty((kernels.ANCHORS, 6)), np.zeros(7),
            np.full((len(pick), 6), np.nan), room, cached,
        )
        for target, room, cached in ((np.inf, geo, True), (best[0], fresh, False))
    ]  # fmt: skip
    bound = np.maximum(*bounds)
    for n in range(len(pick)):
        low = min(reference.support(u, ref) for u in _cell_directions(rng, axis, sign, lo, hi, n))
        assert bound[n] <= low + 1e-12 * max(1.0, abs(low)), (n, bound[n], low)


def _cell_directions(rng, axis, sign, lo, hi, n, count=60):
    """Random unit directions (count, 6) of cell ``n``."""
    y = lo[n] + (hi[n] - lo[n]) * rng.uniform(size=(count, 5))
    x = np.empty((len(y), 6))
    x[:, axis[n]] = sign[n]  # the cube face; the box's five free coordinates
    x[:, [j for j in range(6) if j != axis[n]]] = y
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def test_cells_screened_by_an_inherited_point_hold_the_target():
    """A halved cell is first bounded by the point of the set its parent's bound used: the
    cells that bound drops lie at or above the target under the reference support function,
    and the least of their bounds (``tally[LOWER]``) below every value seen in them."""
    rng = np.random.default_rng(11)
    cs = random_contact_set(rng, ["pcwf", "sfce", "sfcl", "fpc"])
    slots, ref = WrenchSlots.from_contacts(cs), reference.from_contact_set(cs)
    axis, sign, lo, hi = _initial_cells(2)
    pick = rng.choice(len(lo), 120, replace=False)
    axis, sign, lo, hi = axis[pick], sign[pick], lo[pick], hi[pick]
    # each cell's point: the support point of its parent's centre (the cell doubled in size)
    parent_lo, parent_hi = lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo)
    x = np.zeros((len(pick), 6))
    x[np.arange(len(pick)), axis] = sign
    free = np.array([[j for j in range(6) if j != a] for a in axis])
    np.put_along_axis(x, free, 0.5 * (parent_lo + parent_hi), axis=1)
    lin = slots.support_points(x / np.linalg.norm(x, axis=1, keepdims=True))
    values = slots.support(x / np.linalg.norm(x, axis=1, keepdims=True))
    target = float(np.median(values))
    tally = np.array([np.inf, 0, 0, -1, 0, 0], dtype=float)
    geo = kernels.geometry(len(axis))
    live = kernels.screen(axis, sign, lo, hi, np.eye(6), 1.0, lin, target, 0.0, tally, geo)
    dropped = np.setdiff1d(np.arange(len(pick)), live)
    assert 0 < len(dropped) < len(pick)
    fresh = kernels.geometry(1)  # the kept cells' geometry, in order
    for row, n in enumerate(live):
        kernels.geometry_into(axis, sign, lo, hi, np.eye(6), 1.0, fresh, n, 0)
        assert all(np.array_equal(have[row], want[0]) for have, want in zip(geo, fresh))
    for n in dropped:
        low = min(reference.support(u, ref) for u in _cell_directions(rng, axis, sign, lo, hi, n))
        assert low >= target - 1e-12 * max(1.0, abs(target)), (n, low, target)
        assert tally[kernels.LOWER] <= low


def test_cells_screened_by_their_centre_hold_the_target():
    """Before its other ten samples a cell is bounded by its centre's support point: the cells
    that bound drops lie at or above the incumbent minus the gap under the reference support
    function, ``tally[LOWER]`` is below every value seen in them, and the centres' values
    enter the incumbent."""
    rng = np.random.default_rng(12)
    cs = random_contact_set(rng, ["pcwf", "sfce", "sfcl", "pcwf"])
    slots, ref = WrenchSlots.from_contacts(cs), reference.from_contact_set(cs)
    axis, sign, lo, hi = _initial_cells(2)
    pick = rng.choice(len(lo), 150, replace=False)
    axis, sign, lo, hi = axis[pick], sign[pick], lo[pick], hi[pick]
    best, best_u = np.array([np.inf, 0.0]), np.zeros(6)
    start = sphere_samples(8).copy()  # writable: the declared signature
    kernels.consider(*slots.packed, start, np.empty((len(start), 6)), best, best_u)
    gap = 0.3 * abs(best[0])  # a coarse gap: some cells dropped, some kept
    tally = np.array([np.inf, 0, 0, -1, 0, 0], dtype=float)
    geo, centre_w, centre_v = (
        kernels.geometry(len(axis)),
        np.empty((len(axis), 6)),
        np.empty(len(axis)),
    )
    live = kernels.screen_centres(
        *slots.packed, axis, sign, lo, hi, np.eye(6), 1.0, gap, 0.0, tally, best, best_u, geo,
        False, centre_w, centre_v,
    )  # fmt: skip
    dropped = np.setdiff1d(np.arange(len(pick)), live)
    assert 0 < len(dropped) < len(pick)
    assert best[1] == len(start) + len(pick)  # every centre evaluated
    # the kept cells' geometry and centre samples, in order: as computed afresh
    fresh = kernels.geometry(1)
    for row, n in enumerate(live):
        kernels.geometry_into(axis, sign, lo, hi, np.eye(6), 1.0, fresh, n, 0)
        for have, want in zip(geo, fresh):
            assert np.array_equal(have[row], want[0])
        assert centre_v[row] == slots.support(geo[2][row][None])[0]
        assert centre_v[row] == pytest.approx(reference.support(geo[2][row], ref), abs=1e-12)
    assert reference.support(best_u, ref) == pytest.approx(best[0], abs=1e-12)
    for n in dropped:
        low = min(reference.support(u, ref) for u in _cell_directions(rng, axis, sign, lo, hi, n))
        assert low >= best[0] - gap - 1e-12, (n, low, best[0] - gap)
        assert tally[kernels.LOWER] <= low


def _min_over_sphere(contact_set, max_cells, **budget):
    """The branch and bound of a contact set from its search's direction, at a small budget
    (``max_cells``) that it may or may not extend."""
    slots = WrenchSlots.from_contacts(contact_set)
    u = SupportMinimizer()(slots).direction
    gap = 1e-6 * max(1.0, abs(float(slots.support(u[None])[0])))
    options = BranchBoundOptions(max_cells=max_cells, **budget)
    return slots, sphere_minimum(slots, u, gap=gap, options=options)


def test_a_flat_minimum_converges_past_the_budget():
    # Four soft fingers on a box's faces: about 1,800 cells in all, with few alive per level
    # (over the whole sphere: its symmetry would leave a quarter).
    cs = dict(symmetric_sets())["box sfce faces (0, 1, 2, 3)"]
    slots, extended = _min_over_sphere(cs, 1000, symmetry=False)
    assert extended.converged and extended.cells > 1500
    gap = extended.upper - extended.lower
    options = BranchBoundOptions(max_cells=1000, extended_cells=1000, symmetry=False)
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
    _, found = _min_over_sphere(pair, 1000, extension_alive=1000, symmetry=False)
    assert not found.converged
    assert 1000 < found.cells < BranchBoundOptions().extended_cells // 10


@pytest.mark.slow
def test_a_fixture_whose_live_cells_swell_past_the_budget_converges():
    # Seven locators with friction on a stepped shaft, torques unscaled (lever arms up to
    # 110 mm): its live cells swell to about 5,000 after the 40k-cell budget, then fall; the
    # default extension carries it to a converged bracket (it stopped at [-1.27, -0.147]).
    data = json.loads((DATA / "stepped_shaft_fixture_pcwf.json").read_text())
    contact_set = contact_set_from_dict(data)
    bounds = certified_bounds(WrenchSlots.from_contacts(contact_set))
    assert bounds.converged and bounds.force_closure
    # The bracket holds an independent estimate of min p: dense samples, locally polished.
    p_ref, _ = reference.reference_min(
        reference.from_contact_set(contact_set), samples=300, starts=3
    )
    assert -bounds.hi <= p_ref + 1e-9 * max(1.0, p_ref)
    assert bounds.hi - bounds.lo <= 1e-6 * max(1.0, abs(bounds.lo))


def test_cell_geometry_holds_the_box_mapped_by_the_metric():
    """A cell's corners are its box's 32 corners mapped by the metric (numpy's product, for a
    diagonal and a general metric), and its cap (centre, radius ``delta``) and ``nearest``
    hold every direction of the box: random points inside lie within ``delta`` of the centre
    and no nearer the origin than ``nearest``."""
    rng = np.random.default_rng(5)
    centre, corners, unit = np.empty(6), np.empty((32, 6)), np.empty((32, 6))
    for trial in range(60):
        axis, sign = int(rng.integers(6)), float(rng.choice([-1.0, 1.0]))
        lo = rng.uniform(-1.0, 0.6, 5)
        hi = lo + rng.uniform(0.0, 0.4, 5)
        M = rng.normal(size=(6, 6)) if trial % 2 else np.diag(rng.uniform(0.1, 2.0, 6))
        floor = np.linalg.svd(M, compute_uv=False).min()
        delta, nearest = kernels.cell_geometry(axis, sign, lo, hi, M, floor, centre, corners, unit)
        for q in range(32):
            y = np.where([(q >> (4 - j)) & 1 for j in range(5)], hi, lo)
            x = M @ np.insert(y, axis, sign)
            assert np.allclose(corners[q], x, rtol=0, atol=1e-12 * np.abs(M).max())
            assert np.allclose(unit[q], x / np.linalg.norm(x), rtol=0, atol=1e-12)
        inside = M @ np.insert(lo + (hi - lo) * rng.uniform(size=(200, 5)), axis, sign, axis=1).T
        assert np.linalg.norm(inside, axis=0).min() >= nearest * (1 - 1e-12)
        cos = centre @ (inside / np.linalg.norm(inside, axis=0))
        assert np.arccos(np.clip(cos, -1, 1)).max() <= delta + 1e-12


@pytest.mark.parametrize("half", [1e-3, 1e-7, 1e-10, 1e-13])
def test_a_tiny_cell_keeps_its_angular_radius(half):
    """The cap's radius of a cell of half-width ``half`` about a face's centre is the angle to
    its corners, ``atan(half sqrt(5))`` (not 0, where the arccos of a cosine rounds to 1): the
    cap bounds of a deep search hold."""
    lo, hi = np.full(5, -half), np.full(5, half)
    centre, corners, unit = np.empty(6), np.empty((32, 6)), np.empty((32, 6))
    delta, _ = kernels.cell_geometry(0, 1.0, lo, hi, np.eye(6), 1.0, centre, corners, unit)
    angle = np.arctan(half * np.sqrt(5.0))
    assert angle <= delta <= angle * (1 + 1e-6) + 1e-14


def _volume(lo, hi):
    return np.prod(np.maximum(hi - lo, 0.0), axis=-1)


def _tile_exactly(parent_lo, parent_hi, lo, hi, rng):
    """The boxes ``lo, hi`` (n, 5) lie inside the parent box, overlap in no volume and their
    volumes add up to its volume: together they are the parent box."""
    assert np.all(lo >= parent_lo) and np.all(hi <= parent_hi) and np.all(hi > lo)
    assert np.isclose(_volume(lo, hi).sum(), _volume(parent_lo, parent_hi), rtol=1e-9, atol=0)
    for a in range(len(lo)):
        overlap = _volume(np.maximum(lo[a], lo[a + 1 :]), np.minimum(hi[a], hi[a + 1 :]))
        assert np.all(overlap <= 1e-12 * _volume(parent_lo, parent_hi))
    # and every point of the parent lies in some piece
    points = parent_lo + (parent_hi - parent_lo) * rng.uniform(size=(500, 5))
    inside = np.all((points[:, None] >= lo) & (points[:, None] <= hi), axis=2)
    assert inside.any(axis=1).all()


@pytest.mark.parametrize("shrink", [2.0, 4.0, 8.0])
def test_shells_round_a_point_tile_the_box(shrink):
    """A box cut into shells round a point (anywhere in it, on its faces too): the pieces tile
    the box, the last is the inner box of half-width ``h`` round the point (clipped to the
    box), and there are about ``10 log_shrink(width / h)`` of them."""
    rng = np.random.default_rng(11)
    for trial in range(40):
        lo = rng.uniform(-1.0, 0.5, 5)
        hi = lo + rng.uniform(0.01, 0.5, 5)
        y = lo + (hi - lo) * rng.uniform(size=5)
        if trial % 4 == 0:
            y[trial % 5] = hi[trial % 5]  # on a face: the slabs beyond it are empty
        h = 10.0 ** rng.uniform(-6, -2)
        plo, phi = kernels.shells(lo, hi, y, h, shrink)
        _tile_exactly(lo, hi, plo, phi, rng)
        assert np.all(plo[-1] <= y) and np.all(y <= phi[-1])
        assert np.all(phi[-1] - plo[-1] <= 2 * h + 1e-15)
        levels = np.ceil(np.log(0.5 * (hi - lo).max() / h) / np.log(shrink))
        assert len(plo) <= 10 * levels + 1


def test_split_cuts_the_incumbents_cell_into_shells_and_halves_the_others():
    """Every child lies in its parent and each parent's children tile it; the cell holding the
    incumbent (small enough) gets an inner box of angular radius about ``radius`` round it."""
    rng = np.random.default_rng(3)
    axis, sign, lo, hi = _initial_cells(1)
    metric = np.diag(rng.uniform(0.5, 2.0, 6))
    u = rng.normal(size=6)
    u /= np.linalg.norm(u)
    x = np.linalg.solve(metric, u)
    k = int(np.argmax(np.abs(x)))
    y = np.delete(x, k) / abs(x[k])
    holder = np.flatnonzero(
        (axis == k) & (sign == np.sign(x[k])) & np.all((lo <= y) & (y <= hi), axis=1)
    )[0]
    # a small cell round the incumbent and two others
    small_lo, small_hi = y - rng.uniform(0.01, 0.02, 5), y + rng.uniform(0.01, 0.02, 5)
    cells = [holder, (holder + 1) % len(axis), (holder + 7) % len(axis)]
    lo, hi = lo[cells].copy(), hi[cells].copy()
    lo[0], hi[0] = small_lo, small_hi
    axis, sign = axis[cells], sign[cells]
    radius = 1e-4
    caxis, csign, clo, chi, parent = kernels.split(
        axis, sign, lo, hi, 128, metric, u, radius, 0.6, 8.0
    )
    for c in range(3):
        mine = parent == c
        assert np.all(caxis[mine] == axis[c]) and np.all(csign[mine] == sign[c])
        _tile_exactly(lo[c], hi[c], clo[mine], chi[mine], rng)
    shells = np.flatnonzero(parent == 0)
    assert len(shells) > 11  # more than one shell
    inner = shells[-1]
    assert np.all(clo[inner] <= y) and np.all(y <= chi[inner])
    scratch = np.empty(6), np.empty((32, 6)), np.empty((32, 6))
    delta, _ = kernels.cell_geometry(
        axis[0], sign[0], clo[inner], chi[inner], metric, 1.0, *scratch
    )
    assert 0.99 * radius <= delta <= 1.01 * radius


def _dealt_statuses(monkeypatch) -> list:
    """The status of every round that :func:`sphere_minimum` deals into two parts."""
    from closure_nlp.criterion import sphere_branch_bound

    seen, dealt = [], sphere_branch_bound._dealt_round

    def spy(*args):
        status, cells = dealt(*args)
        seen.append(status)
        return status, cells

    monkeypatch.setattr(sphere_branch_bound, "_dealt_round", spy)
    return seen


def test_long_rounds_in_two_threads_give_the_serial_bits(monkeypatch):
    from closure_nlp.criterion.support_minimum import rho

    cs = dict(symmetric_sets())["cylinder sfce m=4"]
    seen = _dealt_statuses(monkeypatch)
    one, two = rho(cs, workers=1), rho(cs, workers=2)
    assert seen.count(kernels.ROUND) > 10  # rounds were dealt, in both runs
    assert len(kernels.advance.signatures) == 1  # the parts' arrays as the kernel was compiled
    assert (one.rho, one.bounds, one.converged) == (two.rho, two.bounds, two.converged)
    assert np.array_equal(one.direction, two.direction)
    # The bracket is certified to 1e-6 and holds an independent estimate of min p.
    lo, hi = one.bounds
    assert one.converged and hi - lo <= 1e-6 * max(1.0, abs(lo))
    p_ref, _ = reference.reference_min(reference.from_contact_set(cs), samples=300, starts=3)
    assert -hi <= p_ref + 1e-9 * p_ref


def test_a_dealt_search_stopped_by_its_budget_counts_the_live_cells(monkeypatch):
    # The budget runs out in a round dealt into two parts: the lower bound must take in the
    # cells still alive in both (their bounds lie below the incumbent minus the gap), each
    # part's least bound as that part recorded it.
    from closure_nlp.criterion import sphere_branch_bound

    seen, parts, run = _dealt_statuses(monkeypatch), [], sphere_branch_bound._Search.run

    def recorded(search, cells, stage, frame, settings):
        status, live = run(search, cells, stage, frame, settings)
        if settings[kernels.ROUND_CELLS] == 0:  # a part of a dealt round
            low = search.tally[kernels.LOWER]
            dealt_on = status == kernels.ROUND  # its live cells' least parent bound
            parts.append(min(low, search.tally[kernels.LIVE_LOWER]) if dealt_on else low)
        return status, live

    monkeypatch.setattr(sphere_branch_bound._Search, "run", recorded)
    cs = ring("sfce", 6)  # a long search: a flat valley of minima
    slots, stopped = _min_over_sphere(cs, 1500, extended_cells=1500, workers=2)
    assert seen[-1] == kernels.BUDGET and kernels.ROUND in seen
    least = min(parts[-2:])  # the last round's two parts
    assert least - 1e-12 <= stopped.lower <= least  # less only by the symmetry's slack
    gap = 1e-6 * max(1.0, abs(stopped.upper))
    assert not stopped.converged and stopped.upper - stopped.lower > gap
    p_ref, _ = reference.reference_min(reference.from_contact_set(cs), samples=300, starts=3)
    assert stopped.lower <= p_ref


def test_a_dealt_round_that_meets_a_negative_value_stops_the_search(monkeypatch):
    from closure_nlp.criterion import sphere_branch_bound

    # Every round dealt from the first. Three fingers round a ring, their normals tilted up
    # past the friction angle: no force down, so the origin is just outside W, and only a
    # later round's samples meet a negative support value.
    monkeypatch.setattr(sphere_branch_bound, "ROUND_CELLS", 1)
    monkeypatch.setattr(sphere_branch_bound, "ROUNDS_AFTER", 0)
    seen = _dealt_statuses(monkeypatch)
    a = 2 * np.pi * np.arange(3) / 3
    P = np.column_stack([np.cos(a), np.sin(a), np.zeros(3)])
    N = np.column_stack([-P[:, :2], np.full(3, 0.55)])
    cs = ContactSet(tuple(Contact(p, n, "pcwf", mu=0.5) for p, n in zip(P, N)))
    found = sphere_minimum(WrenchSlots.from_contacts(cs), gap=1e-6)
    assert seen[-1] == kernels.BELOW_ZERO and seen.count(kernels.ROUND) > 3
    assert found.upper < 0 and found.lower == -np.inf and not found.converged


@pytest.mark.parametrize("bad", [0, 1.5, True, "2"])
def test_workers_must_be_a_positive_count(bad):
    from closure_nlp.criterion.support_minimum import rho

    with pytest.raises(ValueError, match="workers"):
        BranchBoundOptions(workers=bad)
    with pytest.raises(ValueError, match="workers"):
        rho(ring("sfce", 3), workers=bad)
