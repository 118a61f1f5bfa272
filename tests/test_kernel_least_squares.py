"""The compiled least squares of Wolfe's nearest point against LAPACK's (numpy's SVD solver):
well and ill-conditioned systems, overdetermined and square, and rank-deficient ones."""

import numpy as np
import pytest

from closure_nlp.kernels.least_squares import least_squares

EPS = np.finfo(float).eps


def solve(A, b):
    z = np.full(A.shape[1], np.nan)
    rank = least_squares(A.copy(), b.copy(), z)
    return z, rank


def conditioned(rng, m, n, kappa):
    """A random (m, n) matrix with singular values from 1 down to 1 / kappa."""
    U, _ = np.linalg.qr(rng.standard_normal((m, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (U * np.logspace(0, -np.log10(kappa), n)) @ V.T


@pytest.mark.parametrize("kappa", [1.0, 1e4, 1e8, 1e12])
def test_full_rank_systems_match_lapack_within_the_perturbation_bound(kappa):
    rng = np.random.default_rng(int(np.log10(kappa)))
    for _ in range(200):
        m = 6
        n = int(rng.integers(1, m + 1))
        scale = 10.0 ** rng.uniform(-6, 6)  # the bound is scale-free: so is the check
        A = scale * conditioned(rng, m, n, kappa)
        b = scale * rng.standard_normal(m)
        z, rank = solve(A, b)
        ref = np.linalg.lstsq(A, b, rcond=None)[0]
        assert rank == n
        # Higham Thm 20.3 + the least squares perturbation bound, both solvers' errors
        r = np.linalg.norm(A @ ref - b)
        k = np.linalg.cond(A)
        tol = 10 * m * n * EPS * (k + k**2 * r / (np.linalg.norm(A, 2) * np.linalg.norm(ref)))
        assert np.linalg.norm(z - ref) <= tol * np.linalg.norm(ref)


def test_the_residual_is_orthogonal_to_the_columns():
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(1, 7))
        A, b = rng.standard_normal((6, n)), rng.standard_normal(6)
        z, _ = solve(A, b)
        r = A @ z - b
        assert np.abs(A.T @ r).max() <= 100 * EPS * np.linalg.norm(A) * np.linalg.norm(b)


def test_rank_deficient_systems_reach_the_least_residual():
    rng = np.random.default_rng(3)
    for _ in range(200):
        base = rng.standard_normal((6, int(rng.integers(1, 5))))
        mix = rng.standard_normal((base.shape[1], int(rng.integers(1, 3))))
        A = np.column_stack([base, base @ mix])[:, rng.permutation(base.shape[1] + mix.shape[1])]
        b = rng.standard_normal(6)
        z, rank = solve(A, b)
        assert rank == base.shape[1]
        assert np.all(np.isfinite(z))
        best = np.linalg.norm(A @ np.linalg.lstsq(A, b, rcond=None)[0] - b)
        assert np.linalg.norm(A @ z - b) <= best + 1e3 * EPS * np.linalg.norm(b)
