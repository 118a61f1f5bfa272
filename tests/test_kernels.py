"""The compiled kernels against the independent reference (tests/reference.py): row, slot and
set support values and support points, for every contact type, mixed, contacts and elements."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from closure_nlp.contact.contact_set import ContactType
from closure_nlp.contact.wrenches import WrenchSlots
from tests import reference

TYPES = [t.value for t in ContactType]


def random_slots(rng, kinds, max_rows):
    """Slots of 1..max_rows vertex rows each (one: a contact), in the reference's layout."""
    mu, mu_s, ts = rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0), rng.uniform(0.1, 3.0)
    out = []
    for k in kinds:
        n = rng.standard_normal(3)
        G = [
            reference.grasp(rng.standard_normal(3), n, ts)
            for _ in range(rng.integers(1, max_rows + 1))
        ]
        out.append((np.array(G), k, mu, mu_s, rng.uniform(0.5, 2.0)))
    return out


def unit(rng, n):
    U = rng.standard_normal((n, 6))
    return U / np.linalg.norm(U, axis=1, keepdims=True)


cases = st.tuples(
    st.integers(0, 2**31 - 1),
    st.sampled_from(TYPES + ["mixed"]),
    st.integers(1, 6),
    st.integers(1, 5),
)


@settings(max_examples=60, deadline=None)
@given(case=cases)
def test_rows_slots_and_set_agree_with_the_reference(case):
    seed, kind, m, max_rows = case
    rng = np.random.default_rng(seed)
    kinds = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    ref = random_slots(rng, kinds, max_rows)
    slots = WrenchSlots.build(ref)
    U = unit(rng, 30)
    ref_rows = [
        [
            reference.contact_support(Gj.T @ u, k, mu, mu_s, f)
            for G, k, mu, mu_s, f in ref
            for Gj in G
        ]
        for u in U
    ]
    rows, wrenches = slots.row_support(U)
    np.testing.assert_allclose(rows, ref_rows, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(slots.row_values(U), ref_rows, rtol=1e-10, atol=1e-12)
    # each row's wrench attains its value and lies in that row's set (no direction sees past it)
    np.testing.assert_allclose(np.einsum("nkr,nr->nk", wrenches, U), rows, rtol=1e-10, atol=1e-12)
    V = unit(rng, 50)
    flat = [(Gj, k, mu, mu_s, f) for G, k, mu, mu_s, f in ref for Gj in G]
    bound = np.array(
        [[reference.contact_support(Gj.T @ v, *rest) for Gj, *rest in flat] for v in V]
    )
    assert np.all(np.einsum("nkr,vr->nvk", wrenches, V) <= bound[None] + 1e-10)
    slot_ref = [[reference.slot_support(u, s) for s in ref] for u in U]
    np.testing.assert_allclose(slots.slot_values(U), slot_ref, rtol=1e-10, atol=1e-12)
    values, points = slots.evaluate(U)
    expected = [reference.support(u, ref) for u in U]
    np.testing.assert_allclose(values, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(slots.support(U), expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nr,nr->n", points, U), values, rtol=1e-10, atol=1e-12)
    set_bound = np.array([reference.support(v, ref) for v in V])
    assert np.all(points @ V.T <= set_bound[None, :] + 1e-10)


def eq26(values):
    """Eq 26 from slot values (N, m), written again: the sum of the positive ones, else the
    largest (the literal max over 2^m - 1 subsets is out of reach at hundreds of slots)."""
    positive = np.where(values > 0, values, 0.0).sum(axis=1)
    return np.where((values > 0).any(axis=1), positive, values.max(axis=1))


@pytest.mark.parametrize("m, max_rows", [(203, 1), (61, 4)])
def test_many_rows_agree_with_the_reference(m, max_rows):
    """Hundreds of rows of every type, mixed, as contacts and as elements: the row loops run
    in SIMD lanes with a remainder (203 rows), each row's terms must still be its own."""
    rng = np.random.default_rng(m)
    ref = random_slots(rng, list(rng.choice(TYPES, m)), max_rows)
    slots = WrenchSlots.build(ref)
    U = unit(rng, 40)
    rows = np.array(
        [[reference.contact_support(Gj.T @ u, k, mu, mu_s, f) for G, k, mu, mu_s, f in ref
          for Gj in G] for u in U]
    )  # fmt: skip
    values, wrenches = slots.row_support(U)
    np.testing.assert_allclose(values, rows, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nkr,nr->nk", wrenches, U), rows, rtol=1e-10, atol=1e-12)
    slot_ref = np.array([[reference.slot_support(u, c) for c in ref] for u in U])
    np.testing.assert_allclose(slots.slot_values(U), slot_ref, rtol=1e-10, atol=1e-12)
    for sign in (1.0, -1.0):  # both signs: the set mostly in front of the origin, then not
        got, points = slots.evaluate(sign * U)
        want = eq26(np.array([[reference.slot_support(sign * u, c) for c in ref] for u in U]))
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(slots.support(sign * U), want, rtol=1e-10, atol=1e-10)
        # a support point attains the value and lies in the set: no direction sees past it
        np.testing.assert_allclose(np.einsum("nr,nr->n", points, sign * U), want, rtol=1e-10)
        V = unit(rng, 30)
        seen = eq26(np.array([[reference.slot_support(v, c) for c in ref] for v in V]))
        assert np.all(points @ V.T <= seen[None, :] + 1e-9 * np.abs(seen).max())


def test_no_positive_slot_gives_the_largest_alone():
    """Directions where every slot is negative (the origin outside the set): the value is the
    largest slot value, and the support point that slot's wrench alone."""
    rng = np.random.default_rng(2)
    n = np.array([0.0, 0.0, 1.0])
    ref = [
        (np.array([reference.grasp(rng.standard_normal(3), n)]), "pcwf", 0.3, 0.1, f)
        for f in (1.0, 2.0)
    ]
    slots = WrenchSlots.build(ref)
    u = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    value, point = slots.evaluate(u[None])
    assert value[0] == reference.support(u, ref) == -1.0  # f 1: the larger of -1 and -2
    np.testing.assert_allclose(point[0], ref[0][0][0][:, 0], atol=1e-15)


def test_local_minimum_converges_on_soft_fingers():
    """The local minimiser on the sphere (round cones, soft fingers: smooth pieces where plain
    steps crawl) converges within its iteration cap from every start, never ends above its
    start, and ends at a local minimum of the reference support function: no direction of a
    small circle around its end is lower (to the wrench scale's round-off)."""
    from closure_nlp.contact.random_sets import random_contact_set
    from closure_nlp.criterion.sphere_search import sphere_samples
    from closure_nlp.criterion.support_minimum import _local_minimum

    rng = np.random.default_rng(3)
    for _ in range(6):
        cs = random_contact_set(rng, ["sfce"] * 4)
        slots, ref = WrenchSlots.from_contacts(cs), reference.from_contact_set(cs)
        scale = max(np.abs(ref_g).max() for ref_g in slots.G)
        for u0 in sphere_samples(8):
            u, _, status, converged = _local_minimum(slots, u0)
            assert converged, status
            value = reference.support(u, ref)
            assert value <= reference.support(u0, ref) + 1e-12 * scale
            near = u + 1e-4 * unit(rng, 40)
            near /= np.linalg.norm(near, axis=1, keepdims=True)
            lowest = min(reference.support(v, ref) for v in near)
            assert lowest >= value - 1e-9 * scale, (value, lowest)
