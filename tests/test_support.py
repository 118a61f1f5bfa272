"""Support functions of the four contact types: properties, and the paper's formulas."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from closure_nlp.contact.contact_set import (
    Contact,
    ContactSet,
    ContactType,
    grasp_matrices,
    local_frame,
)
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.sphere_search import smoothed_support
from tests import reference

TYPES = [t.value for t in ContactType]
seeds = st.integers(0, 2**31 - 1)


def slots_for(seed, kind, m=3):
    rng = np.random.default_rng(seed)
    cs = random_contact_set(
        rng,
        [kind] * m,
        mu=rng.uniform(0.05, 1.0),
        mu_s=rng.uniform(0.01, 1.0),
        torque_scale=rng.uniform(0.1, 3.0),
    )
    return cs, WrenchSlots.from_contacts(cs), rng


def unit(rng, n=1):
    U = rng.standard_normal((n, 6))
    return U / np.linalg.norm(U, axis=1, keepdims=True)


def sample_force(rng, kind, mu, mu_s, f_max):
    """A force inside F_i n Omega_i (eqs 1-5), sampled independently of the package."""
    fn = rng.uniform(0, f_max)
    direction = rng.standard_normal(3)
    direction /= np.linalg.norm(direction)
    r = rng.uniform(0, 1)
    if kind == "fpc":
        return np.array([fn, 0, 0, 0])
    if kind == "pcwf":
        return np.array([fn, *(r * mu * fn * direction[:2] / np.linalg.norm(direction[:2])), 0])
    if kind == "sfce":  # ellipsoid: (|f_ot| / mu)^2 + (f_s / mu_s)^2 <= f_n^2
        return np.array([fn, *(r * fn * mu * direction[:2]), r * fn * mu_s * direction[2]])
    share = rng.uniform(0, 1)  # sfcl: |f_ot| / mu + |f_s| / mu_s <= f_n
    tang = direction[:2] / np.linalg.norm(direction[:2])
    return np.array(
        [fn, *(r * share * mu * fn * tang), r * (1 - share) * mu_s * fn * np.sign(direction[2])]
    )


@pytest.mark.parametrize("kind", TYPES)
@settings(max_examples=25, deadline=None)
@given(seed=seeds, scale=st.floats(0.01, 100))
def test_positive_homogeneity(kind, seed, scale):
    _, slots, rng = slots_for(seed, kind)
    U = unit(rng, 8)
    np.testing.assert_allclose(
        slots.support(scale * U), scale * slots.support(U), rtol=1e-9, atol=1e-12
    )


@pytest.mark.parametrize("kind", TYPES)
@settings(max_examples=25, deadline=None)
@given(seed=seeds)
def test_subadditive(kind, seed):
    _, slots, rng = slots_for(seed, kind)
    U, V = unit(rng, 8), unit(rng, 8)
    assert np.all(slots.support(U + V) <= slots.support(U) + slots.support(V) + 1e-12)


@pytest.mark.parametrize("kind", TYPES)
@settings(max_examples=25, deadline=None)
@given(seed=seeds)
def test_bounds_every_allowable_wrench_and_is_attained(kind, seed):
    cs, slots, rng = slots_for(seed, kind, m=1)
    c = cs.contacts[0]
    G = cs.grasp_matrices()[0]
    U = unit(rng, 20)
    p = slots.support(U)
    wrenches = np.array([G @ sample_force(rng, kind, c.mu, c.mu_s, c.f_max) for _ in range(200)])
    # For one contact, the set is W_1 and its hull with 0 holds every allowable wrench.
    assert np.all(U @ wrenches.T <= np.maximum(p, 0)[:, None] + 1e-12)
    points = slots.support_points(U)
    np.testing.assert_allclose(np.einsum("nr,nr->n", points, U), p, atol=1e-12)
    # The support point is itself an extreme wrench: its force sits on U_i (eqs 9-12).
    forces = np.linalg.lstsq(G, points.T, rcond=None)[0].T
    np.testing.assert_allclose(forces[:, 0], c.f_max, rtol=1e-9)


@pytest.mark.parametrize("kind", TYPES + ["mixed"])
@settings(max_examples=15, deadline=None)
@given(seed=seeds, m=st.integers(1, 5))
def test_agrees_with_paper_formulas_and_all_subsets(kind, seed, m):
    rng = np.random.default_rng(seed)
    types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    cs = random_contact_set(
        rng,
        types,
        mu=rng.uniform(0.05, 1.0),
        mu_s=rng.uniform(0.01, 1.0),
        torque_scale=rng.uniform(0.1, 3.0),
    )
    ref = reference.from_contact_set(cs)
    U = unit(rng, 10)
    expected = [reference.support(u, ref) for u in U]
    np.testing.assert_allclose(
        WrenchSlots.from_contacts(cs).support(U), expected, rtol=1e-10, atol=1e-12
    )


def test_local_frame_is_right_handed():
    for n in np.random.default_rng(3).standard_normal((50, 3)):
        n /= np.linalg.norm(n)
        F = local_frame(n)
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(np.cross(F[:, 1], F[:, 2]), n, atol=1e-12)  # n = o x t


def test_torque_scale_scales_torque_rows_and_spin_column():
    c = Contact([1.0, 2.0, 3.0], [0, 0, 1], "sfce")
    G1 = ContactSet((c,), 1.0).grasp_matrices()[0]
    G2 = ContactSet((c,), 0.25).grasp_matrices()[0]
    np.testing.assert_allclose(G2[:3], G1[:3])
    np.testing.assert_allclose(G2[3:], 0.25 * G1[3:])
    np.testing.assert_allclose(G1[3:, 3], [0, 0, 1])


@pytest.mark.parametrize("rows", [(1, 3, 4), (1, 1, 1, 1)])  # elements; contacts alone
@pytest.mark.parametrize("kind", ["pcwf", "sfcl", "sfce"])
def test_smoothed_support_is_an_upper_bound_with_its_exact_gradient(kind, rows):
    """The smoothed descent's function: p <= p_tau <= p + O(tau), and its gradient."""
    rng = np.random.default_rng(4)
    kind = ContactType.parse(kind)
    slots = WrenchSlots.build(
        [
            (grasp_matrices(rng.normal(size=(k, 3)), rng.normal(size=3)), kind, 0.4, 0.2, 1.0)
            for k in rows
        ]
    )
    U = rng.normal(size=(20, 6))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    for tau in (0.1, 1e-3):
        value, grad = smoothed_support(slots, U, tau)
        exact = slots.support(U)
        assert np.all(value >= exact - 1e-12)
        # each soft max adds at most tau log(count): rows (twice: P_i and max_i P_i), softplus
        slack = tau * (2 * np.log(12.0) + slots.m * np.log(2.0) + np.log(slots.m))
        assert np.all(value <= exact + slack + 1e-12)
        h = 1e-6
        up = [smoothed_support(slots, U + h * e, tau)[0] for e in np.eye(6)]
        down = [smoothed_support(slots, U - h * e, tau)[0] for e in np.eye(6)]
        numeric = (np.stack(up, axis=1) - np.stack(down, axis=1)) / (2 * h)
        np.testing.assert_allclose(grad, numeric, atol=1e-6 * max(1.0, 1 / tau))


@pytest.mark.parametrize("kind", TYPES + ["mixed"])
@settings(max_examples=15, deadline=None)
@given(seed=seeds)
def test_element_slots_values_and_support_points(kind, seed):
    """Slots of several vertex rows (elements, eq 36): values agree with the reference, and each
    support point attains its value and lies in the set (no direction sees it beyond ``p``).
    Only each slot's best row gets a support wrench, and FPC rows have a shortcut: both here."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 5))
    kinds = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    mu, mu_s, ts = rng.uniform(0.05, 1.0), rng.uniform(0.01, 1.0), rng.uniform(0.1, 3.0)
    slots_ref = []
    for k in kinds:
        n = rng.standard_normal(3)
        rows = range(rng.integers(1, 5))
        G = np.array([reference.grasp(rng.standard_normal(3), n, ts) for _ in rows])
        slots_ref.append((G, k, mu, mu_s, rng.uniform(0.5, 2.0)))
    slots = WrenchSlots.build(slots_ref)
    U = unit(rng, 40)
    values, points = slots.evaluate(U)
    expected = [reference.support(u, slots_ref) for u in U]
    np.testing.assert_allclose(values, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nr,nr->n", points, U), values, rtol=1e-10, atol=1e-12)
    V = unit(rng, 200)
    assert np.all(points @ V.T <= slots.support(V)[None, :] + 1e-10)


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(TYPES), seeds, st.floats(1e-3, 1e3))
def test_scaled_slots_pack_and_scale_as_a_fresh_set(kind, seed, factor):
    """A scaled copy reuses its set's packed rows and rows' norms: the same arrays, row scales
    and values as a set built afresh with the scaled bounds."""
    _, slots, rng = slots_for(seed, kind, m=1 + seed % 5)
    scaled = slots.scaled(factor)
    fresh = WrenchSlots(
        slots.G, slots.starts, slots.f_max * factor, slots.pieces, slots.types, slots.n_pieces
    )
    for mine, theirs in zip(scaled.packed, fresh.packed):
        np.testing.assert_array_equal(mine, theirs)
    for friction in (True, False):
        assert scaled.row_scales(friction) == fresh.row_scales(friction)
    U = unit(rng, 8)
    np.testing.assert_array_equal(scaled.support(U), fresh.support(U))
