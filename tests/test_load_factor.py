"""Certified load factors against an independent SOCP on the forces, and analytic cases."""

from pathlib import Path

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.loads import as_loads
from closure_nlp.contact.random_sets import random_contact_set, random_load
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.crosscheck import load_factor_cvxpy
from closure_nlp.criterion.load_factor import load_factor

TYPES = ["fpc", "pcwf", "sfcl", "sfce"]
SETS = 50
AGREE = 1e-6  # relative, on factors that are not marginal
SOCP_ACCURACY = 1e-7  # the SOCP's own, relative to max(factor, the set's natural factor)


def random_case(kind, seed):
    """A contact set and a load, inside the wrench set for even seeds (:func:`random_load`)."""
    rng = np.random.default_rng(seed)
    m = {"fpc": 7, "mixed": 5}.get(kind, 4)
    types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    cs = random_contact_set(rng, types, mu=0.5, mu_s=0.3, tilt=0.25)
    return cs, random_load(rng, cs, inside=seed % 2 == 0)


@pytest.mark.parametrize("kind", [*TYPES, "mixed"])
def test_agrees_with_the_socp(kind):
    worst, held = 0.0, 0
    for seed in range(SETS):
        cs, load = random_case(kind, seed)
        result = load_factor(cs, load)
        reference, status = load_factor_cvxpy(cs, load)
        assert status == "optimal", (seed, status)
        lo, hi = result.bounds
        natural = max(WrenchSlots.from_contacts(cs).row_scales()) / np.linalg.norm(load)
        slack = SOCP_ACCURACY * max(reference, natural)
        assert lo - slack <= reference <= hi + slack, (seed, lo, hi, reference)
        assert result.converged, seed
        if not result.marginal:
            held += 1
            assert hi - lo <= AGREE * hi, (seed, lo, hi)
            worst = max(worst, abs(result.load_factor - reference) / reference)
        else:
            assert hi <= 1e-6 * natural
    assert worst <= AGREE
    assert held >= SETS // 2  # the comparison is not only of zeros


def opposite_pair(f_max, scale=1.0):
    """Two frictionless contacts on the x axis pushing towards each other."""
    return ContactSet(
        (
            Contact([scale, 0, 0], [-1, 0, 0], "fpc", f_max=f_max),
            Contact([-scale, 0, 0], [1, 0, 0], "fpc", f_max=f_max),
        )
    )


def test_opposite_frictionless_pair_holds_f_max_over_the_load():
    cs = opposite_pair(3.0)
    for force in ([-5.0, 0, 0], [0.25, 0, 0]):
        result = load_factor(cs, [*force, 0, 0, 0])
        expected = 3.0 / abs(force[0])
        assert result.bounds[0] <= expected <= result.bounds[1]
        assert result.load_factor == pytest.approx(expected, rel=1e-9)
        assert not result.marginal
    # a sideways force or a twist: nothing can push against it
    for load in ([0, 1.0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 1.0]):
        result = load_factor(cs, load)
        assert result.marginal and result.bounds[1] <= 1e-9


def test_same_part_in_metres_and_millimetres():
    rng = np.random.default_rng(7)
    cs = random_contact_set(rng, ["pcwf"] * 4, mu=0.5, tilt=0.25)
    points = WrenchSlots.from_contacts(cs).support_points(rng.standard_normal((3, 6)))
    in_mm = ContactSet(
        tuple(
            Contact(c.position * 1000, c.inward_normal, c.type, c.mu, c.mu_s, c.f_max)
            for c in cs.contacts
        ),
        torque_scale=1e-3,
    )
    wrench = -points.mean(axis=0)  # inside the set: a factor above 1
    point = np.array([0.1, -0.2, 0.3])
    force, torque = wrench[:3], wrench[3:] - np.cross(point, wrench[:3])  # about the origin

    def case(unit):  # the same load written in metres (unit 1) or millimetres (unit 1000)
        entry = {"name": "a", "force": force.tolist(), "point": (unit * point).tolist()}
        return as_loads([{**entry, "torque": (unit * torque).tolist()}])

    k_m = load_factor(cs, case(1).wrenches(cs.reference_point, cs.torque_scale)[0])
    k_mm = load_factor(in_mm, case(1000).wrenches(in_mm.reference_point, in_mm.torque_scale)[0])
    assert k_m.load_factor > 1.0
    assert k_mm.load_factor == pytest.approx(k_m.load_factor, rel=1e-6)


def test_zero_load_is_refused():
    with pytest.raises(ValueError, match="load"):
        load_factor(opposite_pair(1.0), np.zeros(6))


def test_ring_of_frictional_contacts_holds_its_friction_against_gravity():
    # four horizontal pushes on a ring: only friction holds a vertical load, at most mu f_max
    # each; the optimum needs all four at f_max, balanced exactly (the LP's point alone leaves
    # a residual the verification must cancel)
    mu, f_max, weight = 0.3, 2.0, 1.7
    angles = np.arange(4) * np.pi / 2 + 0.1
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(4)], axis=1) * 42.4
    cs = ContactSet(
        tuple(Contact(p, -p, "pcwf", mu=mu, f_max=f_max) for p in ring), torque_scale=1 / 60
    )
    result = load_factor(cs, [0, 0, -weight, 0, 0, 0])
    expected = 4 * mu * f_max / weight
    assert result.converged and result.bounds[0] <= expected * (1 + 1e-12)
    assert result.bounds[1] >= expected * (1 - 1e-12)
    assert result.load_factor == pytest.approx(expected, rel=1e-6)


def test_element_sets_agree_with_the_socp():
    """Slots of several rows (the lamp's facets, every vertex a row): the factor of the elements'
    wrench set, which bounds every placement's on them."""
    import closure_nlp as c

    model = c.load_model(Path(__file__).resolve().parents[1] / "models" / "lamp.model.json")
    eligibility = c.Eligibility(model, c.contact_specs(4, type="pcwf"), torque_scale="auto")
    rng = np.random.default_rng(3)
    held = 0
    for j in range(12):
        slots = eligibility.slots(rng.integers(0, len(model.elements), 4).tolist())
        U = rng.standard_normal((3, 6))
        load = (
            -(rng.dirichlet(np.ones(3)) @ slots.support_points(U))
            if j % 2
            else rng.standard_normal(6)
        )
        result = load_factor(slots, load)
        reference, status = load_factor_cvxpy(slots, load)
        assert status == "optimal"
        natural = max(slots.row_scales()) / np.linalg.norm(load)
        slack = SOCP_ACCURACY * max(reference, natural)
        assert result.bounds[0] - slack <= reference <= result.bounds[1] + slack, j
        if not result.marginal:
            held += 1
            assert result.load_factor == pytest.approx(reference, rel=AGREE)
    assert held >= 4


def test_a_bracket_cut_short_still_contains_the_factor():
    """Stopped by ``max_iterations`` after new columns came in: the last LP's point is verified
    with those columns at zero weight, and the bracket still holds the full answer."""
    cs, load = random_case("sfce", 0)
    full = load_factor(cs, load)
    for cap in (1, 2, 3, 5):
        short = load_factor(cs, load, max_iterations=cap)
        assert short.bounds[0] <= full.load_factor * (1 + 1e-9)
        assert short.bounds[1] >= full.bounds[0] * (1 - 1e-9)
