"""The compiled smoothed descent (contact sets) against the numpy loop it replaces."""

import math

import numpy as np
import pytest

from closure_nlp.contact.contact_set import ContactType
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.sphere_search import _smoothed_descend_numpy, descend, sphere_samples
from closure_nlp.kernels import descent as kernels

TYPES = [t.value for t in ContactType]


def _numpy_as_the_kernels():
    """Whether this numpy's exp and log are the C library's (the kernels' own) and its einsum
    of two rows sums as :func:`kernels._dot6` does: not on every build (AVX-512 has numpy's own
    exp and log)."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-40.0, 5.0, 2000)
    a, b = rng.standard_normal((2, 500, 6))
    return (
        all(np.exp(x) == [math.exp(v) for v in x])
        and all(np.log(-x[x < 0]) == [math.log(-v) for v in x[x < 0]])
        and all(np.einsum("nr,nr->n", a, b) == [kernels._dot6(p, q) for p, q in zip(a, b)])
    )


BITWISE = _numpy_as_the_kernels()


@pytest.mark.parametrize("m", [1, 4, 7, 9])
@pytest.mark.parametrize("kind", TYPES + ["mixed"])
def test_the_compiled_smoothed_descent_takes_the_numpy_steps_to_the_bit(kind, m):
    # numpy's sums, einsums and transcendental functions in their order: the same end points
    # and values, not merely close ones (the placement's paths depend on the last digits),
    # wherever numpy's exp, log and einsum are those the kernels mirror; close elsewhere
    rng = np.random.default_rng(100 * m + len(kind))
    kinds = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    cs = random_contact_set(
        rng, kinds, mu=rng.uniform(0.05, 1.0), mu_s=rng.uniform(0.01, 1.0), torque_scale=1.0
    )
    slots = WrenchSlots.from_contacts(cs)
    U0 = np.vstack([sphere_samples(32), rng.standard_normal((3, 6))])
    U0 /= np.linalg.norm(U0, axis=1, keepdims=True)
    scale = max(1.0, float(slots.f_max.max()))
    for tau in (0.1, 0.03, 0.01):
        U, values = descend(slots, U0, 10, tau * scale)
        U_ref, values_ref = _smoothed_descend_numpy(slots, U0, 10, tau * scale)
        np.testing.assert_allclose(U, U_ref, rtol=0.0, atol=1e-9)
        if BITWISE:
            assert np.array_equal(U, U_ref) and np.array_equal(values, values_ref), (kind, m, tau)
        np.testing.assert_allclose(np.linalg.norm(U, axis=1), 1.0, atol=1e-12)
        np.testing.assert_array_equal(values, slots.support(U))  # p itself at the ends
        U0 = U


def test_the_pairwise_sum_is_numpys():
    rng = np.random.default_rng(3)
    for n in range(kernels.PAIRWISE_BLOCK + 1):
        a = rng.standard_normal(n + 2) * 10.0 ** rng.integers(-8, 8, n + 2)
        assert kernels._pairwise_sum(a, 1, n + 1) == a[1 : n + 1].sum(), n
