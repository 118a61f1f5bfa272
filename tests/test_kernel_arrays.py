"""The kernels' own sort against numba's np.argsort (whose order the branch and bound's games
took their rows in: the same order keeps the certified bounds bitwise the same)."""

import numpy as np
from numba import njit

from closure_nlp.kernels.arrays import argsort


@njit(cache=False)
def numba_argsort(values):
    return np.argsort(values)


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
