"""The cell bound with one budget of weights per slot: its game against HiGHS, the bound against
the reference support function."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from closure_nlp.branch_bound import _initial_cells
from closure_nlp.kernels import branch_bound as kernels
from closure_nlp.kernels.slot_game import block_game_weights
from closure_nlp.random_sets import random_contact_set
from closure_nlp.wrenches import WrenchSlots

from . import reference
from .test_certify import element_sets


def _block_game_value(M, block, blocks):
    """max t s.t. (M lam)_c >= t, lam >= 0, each block's weights summing to at most 1 (HiGHS)."""
    C, K = M.shape
    cost = np.zeros(K + 1)
    cost[-1] = -1.0
    A = np.vstack(
        [np.hstack([-M, np.ones((C, 1))]),
         np.hstack([(block[None, :] == np.arange(blocks)[:, None]).astype(float),
                    np.zeros((blocks, 1))])]
    )  # fmt: skip
    b = np.concatenate([np.zeros(C), np.ones(blocks)])
    found = linprog(cost, A_ub=A, b_ub=b, bounds=[(0, None)] * K + [(None, None)])
    assert found.status == 0
    return -found.fun


@pytest.mark.parametrize("shape", [(8, 20, 2), (32, 88, 4), (12, 60, 6), (3, 9, 3)])
def test_block_game_weights_reach_the_lp_value(shape):
    """Feasible weights (each block's at most 1) whose value is HiGHS's, on games whose
    entries are mostly positive (a cell's support values) with some negative columns."""
    C, K, blocks = shape
    rng = np.random.default_rng(K)
    for _ in range(10):
        M = 1.0 + rng.normal(size=(C, K))
        M[:, rng.random(K) < 0.2] -= 2.0
        block = rng.integers(0, blocks, K)
        block[:blocks] = np.arange(blocks)
        lam = np.empty(K)
        block_game_weights(M, block, blocks, lam)
        assert np.all(lam >= 0)
        assert np.all(np.bincount(block, lam, blocks) <= 1 + 1e-12)
        value = (M @ lam).min()
        best = _block_game_value(M, block, blocks)
        spread = np.abs(M).max()
        assert best - 1e-7 * spread <= value <= best + 1e-9 * spread


@pytest.mark.parametrize("shape", [(8, 20, 2), (32, 88, 4), (12, 60, 6)])
def test_block_game_weights_give_up_only_below_the_lp_value(shape):
    """A game asked to give up below a level stops early only when HiGHS's value is below it
    (its dual bound is an upper bound), and one whose value is above the level runs to it."""
    C, K, blocks = shape
    rng = np.random.default_rng(C + K)
    gave_up = 0
    for _ in range(10):
        M = 1.0 + rng.normal(size=(C, K))
        block = rng.integers(0, blocks, K)
        block[:blocks] = np.arange(blocks)
        best = _block_game_value(M, block, blocks)
        spread = np.abs(M).max()
        for level in (best + 0.05 * spread, best - 0.05 * spread):
            lam = np.empty(K)
            pivots = block_game_weights(M, block, blocks, lam, np.inf, level)
            if pivots < 0:
                gave_up += 1
                assert best < level
            else:
                assert (M @ lam).min() >= best - 1e-7 * spread
    assert gave_up > 0


@pytest.mark.parametrize("kind", ["pcwf", "sfce", "sfcl", "mixed", "elements"])
def test_slot_bounds_hold_under_the_reference(kind):
    """Every positive slot bound of a cell lies below the reference support function at random
    directions of the cell, and some cells get one (the check is not vacuous)."""
    rng = np.random.default_rng(len(kind))
    if kind == "elements":  # slots of several rows (facets), independent reference slots
        name, slots, ref = next(e for e in element_sets() if e[0].startswith("elements mixed m=4"))
    else:
        types = ["pcwf", "sfcl", "sfce", "pcwf"] if kind == "mixed" else [kind] * 4
        cs = random_contact_set(rng, types)
        slots, ref = WrenchSlots.from_contacts(cs), reference.from_contact_set(cs)
    axis, sign, lo, hi = _initial_cells(3)
    pick = rng.choice(len(lo), 150, replace=False)
    G, f, W, npc, ends = slots.packed
    work = kernels.slot_work(f, ends, 22)
    centre, corners, unit = np.empty(6), np.empty((32, 6)), np.empty((32, 6))
    positive = 0
    for n in pick:
        delta, nearest = kernels.cell_geometry(
            axis[n], sign[n], lo[n], hi[n], np.eye(6), 1.0, centre, corners, unit
        )
        dirs = _cell_directions(rng, axis[n], sign[n], lo[n], hi[n], 22)
        wbar = slots.support_points(centre[None])[0]
        bound = kernels.slot_bound(G, f, W, npc, ends, dirs, corners, unit, nearest, np.inf,
                                   -np.inf, wbar, work)  # fmt: skip
        if not np.isfinite(bound):
            continue
        positive += 1
        low = min(
            reference.support(u, ref)
            for u in _cell_directions(rng, axis[n], sign[n], lo[n], hi[n], 60)
        )
        assert bound <= low + 1e-12 * max(1.0, abs(low)), (n, bound, low)
    assert positive >= 10


def _cell_directions(rng, axis, sign, lo, hi, count):
    """Random unit directions (count, 6) of one cell (its corners among them)."""
    y = lo + (hi - lo) * rng.uniform(size=(count, 5))
    y[:4] = np.where(rng.random((4, 5)) < 0.5, lo, hi)
    x = np.empty((count, 6))
    x[:, axis] = sign
    x[:, [j for j in range(6) if j != axis]] = y
    return x / np.linalg.norm(x, axis=1, keepdims=True)
