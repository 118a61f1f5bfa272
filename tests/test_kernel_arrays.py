"""The kernels' own sort against numba's np.argsort (whose order the branch and bound's games
took their rows in: the same order keeps the certified bounds bitwise the same), and their
linear solve against numba's np.linalg.solve (the same bits) and numpy's (the residual)."""

import numpy as np
from numba import njit

from closure_nlp.kernels.arrays import argsort, solve


@njit(cache=False)
def numba_argsort(values):
    return np.argsort(values)


@njit(cache=False)
def numba_solve(a, b):
    return np.linalg.solve(a, b.copy())


def test_argsort_orders_as_numba_does_ties_and_nan_included():
    rng = np.random.default_rng(0)
    for n in (0, 1, 2, 3, 15, 16, 17, 32, 33, 64, 100, 257):
        for kind in ("distinct", "ties", "nan", "sorted", "reversed", "equal"):
            if kind == "distinct":
                values = rng.standard_normal(n)
            elif kind == "ties":
                values = rng.integers(0, 4, n).astype(float)
            elif kind == "nan":
                values = rng.integers(0, 5, n).astype(float)
                values[rng.random(n) < 0.3] = np.nan
            elif kind == "sorted":
                values = np.sort(rng.integers(0, 6, n).astype(float))
            elif kind == "reversed":
                values = np.sort(rng.standard_normal(n))[::-1].copy()
            else:
                values = np.full(n, -0.0)
            order = argsort(values)
            assert order.dtype == np.int64
            assert np.array_equal(order, numba_argsort(values)), (n, kind)
            # a permutation that sorts (NaN last), whatever numba does
            assert np.array_equal(np.sort(order), np.arange(n))
            assert np.array_equal(values[order], np.sort(values), equal_nan=True)


def test_solve_gives_the_bits_of_numbas_linalg_solve():
    # the branch and bound's split solves metric x = u: positive diagonals, and a symmetry's
    # rotations and shears; here also badly scaled and near-singular systems
    rng = np.random.default_rng(1)
    for k in range(4000):
        kind = k % 4
        if kind == 0:
            a = np.diag(rng.uniform(0.1, 10.0, 6))
        elif kind == 1:
            a = rng.normal(size=(6, 6))
        elif kind == 2:
            a = rng.normal(size=(6, 6)) * 10.0 ** rng.integers(-8, 9, (6, 6))
        else:
            a = np.outer(rng.normal(size=6), rng.normal(size=6)) + 1e-9 * rng.normal(size=(6, 6))
        b = rng.normal(size=6)
        b[rng.integers(0, 6)] = 0.0 if k % 8 < 2 else b[0]
        x = solve(a, b)
        assert x.tobytes() == numba_solve(a, b).tobytes(), k
        scale = np.abs(a) @ np.abs(x) + np.abs(b)
        assert np.all(np.abs(a @ x - b) <= 1e-10 * np.linalg.cond(a) * scale), k
    assert solve(np.eye(3), np.array([1.0, -2.0, 0.5])).tolist() == [1.0, -2.0, 0.5]
    # singular: no solution (np.linalg.solve raises)
    assert np.isnan(solve(np.zeros((6, 6)), np.ones(6))).all()
