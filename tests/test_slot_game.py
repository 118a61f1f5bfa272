"""The cell bound with one budget of weights per slot: its game against HiGHS, the bound against
the reference support function."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.sphere_branch_bound import _initial_cells
from closure_nlp.kernels import branch_bound as kernels
from closure_nlp.kernels import slot_game
from closure_nlp.kernels.slot_game import block_game_weights

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


def _fresh_game(M, block, blocks, exact):
    """The weights and pivots of ``M``'s game solved afresh."""
    lam = np.empty(M.shape[1])
    if exact:
        pivots = kernels.game_weights(M.copy(), lam, np.inf, 400)
    else:
        pivots = block_game_weights(M.copy(), block, blocks, lam)
    return lam, pivots


@pytest.mark.parametrize("stop", [False, True])
@pytest.mark.parametrize("exact", [False, True])
def test_games_grown_warm_reach_the_value_of_fresh_ones(exact, stop):
    """A game grown a row or a column at a time, each step re-solved from the last tableau
    (dual simplex after a row added to an optimal game, primal pivots on the negative basic
    variables after one added to a game stopped early, primal after a column), ends each
    full solve at the value of the same game solved afresh (and HiGHS's), to round-off, with
    fewer pivots in sum; with ``stop``, every other step stops once its value reaches a level
    below the game's (and does reach it)."""
    rng = np.random.default_rng(11 + exact + 2 * stop)
    warm_pivots = fresh_pivots = warm_steps = stopped = 0
    for trial in range(30):
        C, K = int(rng.integers(10, 33)), int(rng.integers(12, 61))
        blocks = 1 if exact else int(rng.integers(1, 5))
        M = 7.0 + (1e-3 if trial % 3 == 0 else 1.0) * rng.normal(size=(C, K))
        block = np.zeros(K, np.int64) if exact else rng.integers(0, blocks, K)
        block[:blocks] = np.arange(blocks)
        T, basis = slot_game.game_tableau(C, K, blocks)
        c, k = 4, K // 2
        low, span = slot_game.game_open(M[:c, :k], block[:k], blocks, exact, T, basis)
        order = rng.permutation(["row"] * (C - c) + ["col"] * (K - k))[: C // 2]
        for n, step in enumerate(order):
            fresh, cold = _fresh_game(M[:c, :k], block[:k], blocks, exact)
            value_cold = (M[:c, :k] @ fresh).min()
            spread = np.ptp(M[:c, :k]) if exact else np.abs(M[:c, :k]).max()
            level = value_cold - 0.05 * spread if stop and n % 2 == 0 else np.inf
            lam, mix = np.zeros(K), np.empty(c)
            pivots, warm = slot_game.game_solve(M[:c, :k].copy(), block[:k], blocks, exact, T,
                                                basis, low, span, lam[:k], level, -np.inf, 400,
                                                1e-9, mix)  # fmt: skip
            value = (M[:c] @ lam).min()
            assert np.all(lam >= 0)
            if exact:
                assert abs(lam.sum() - 1.0) < 1e-12
            else:
                assert np.all(np.bincount(block, lam, blocks) <= 1 + 1e-12)
            if level < np.inf:
                assert value >= level - 1e-12 * spread
                stopped += n > 0
            else:
                warm_pivots += pivots
                fresh_pivots += cold
                assert abs(value - value_cold) <= 1e-7 * spread, (trial, c, k, value, value_cold)
                if not exact:
                    best = _block_game_value(M[:c, :k], block[:k], blocks)
                    assert best - 1e-7 * spread <= value <= best + 1e-9 * spread
            c, k = (c + 1, k) if step == "row" else (c, k + 1)
            if not warm:
                low, span = slot_game.game_open(M[:c, :k].copy(), block[:k], blocks, exact, T,
                                                basis)  # fmt: skip
            elif step == "row":
                slot_game.game_add_row(M[:c, :k].copy(), block[:k], blocks, T, basis, low, span)
            else:
                slot_game.game_add_column(M[:c, :k].copy(), block[:k], blocks, T, basis, low,
                                          span)  # fmt: skip
            warm_steps += warm
    assert warm_steps > 200 and (stopped > 100 or not stop)
    assert warm_pivots < 0.7 * fresh_pivots, (warm_pivots, fresh_pivots)
