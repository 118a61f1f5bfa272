"""Selection and placement steer by the robust value (rho or rho_hat plus the support shift
within each element's tolerance) when the model carries one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from closure_nlp.contact.accuracy import ModelTolerance
from closure_nlp.contact.contact_set import Contact, ContactSet, ContactType
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.robustness import to_be_robust, to_be_robust_text
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.characterize import characterize_mesh
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.selection.algorithms import heuristic, iterative


@pytest.fixture(scope="module")
def can():
    """A faceted can: exact caps, side facets that stand for a curved surface (about 11
    degrees of normal each)."""
    mesh = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=16)
    model = characterize_mesh(mesh, units="m").model
    return Eligibility(model, contact_specs(4, type="pcwf", mu=0.5))


def test_an_element_sets_shift_is_the_one_its_certificate_carries(can):
    rng = np.random.default_rng(0)
    n = len(can.model.elements)
    tolerant = [i for i, e in enumerate(can.model.elements) if e.tolerance]
    assert tolerant and len(tolerant) < n
    for _ in range(5):
        ids = [int(i) for i in rng.integers(0, n, 4)]
        found = can(ids)
        assert can.shift(ids) == pytest.approx(found.shift, rel=1e-12, abs=1e-15)
    assert can.shift([tolerant[0]] * 4) > 0.0


def test_fixed_contacts_count_in_an_element_sets_shift(can):
    """A contact already in place on a tolerant element adds its own share to every set's."""
    side = next(i for i, e in enumerate(can.model.elements) if e.tolerance)
    element = can.model.elements[side]
    spot = Contact(element.centroid, element.inward_normal, ContactType.PCWF, mu=0.5)
    specs = contact_specs(3, type="pcwf", mu=0.5)
    held, free = Eligibility(can.model, specs, fixed=[spot]), Eligibility(can.model, specs)
    rng = np.random.default_rng(1)
    for _ in range(3):
        ids = [int(i) for i in rng.integers(0, len(can.model.elements), 3)]
        found = held(ids)
        assert held.shift(ids) == pytest.approx(found.shift, rel=1e-12, abs=1e-15)
        assert held.shift(ids) > free.shift(ids)


@pytest.mark.slow
def test_iterative_selection_ends_where_no_swap_raises_the_capacity_left(can):
    """No single swap for a neighbour has a lower certified robust value (hi + shift) than
    the set the iterative algorithm returns."""
    first = heuristic(can, seed=3)
    found = iterative(can, first.elements)
    best = can(found.elements)
    assert best.eligible
    value = best.rho_hat + best.shift
    slack = 1e-5 * max(1.0, abs(value))
    for i, e in enumerate(found.elements):
        for n in can.model.neighbours(e):
            trial = list(found.elements)
            trial[i] = n
            other = can(trial)
            assert other.bounds[1] + other.shift >= value - slack, (trial, other.rho_hat)


@pytest.mark.slow
def test_placement_keeps_at_least_the_starts_capacity_left(can):
    """The placement's certified robust value is never above that of contacts at the
    elements' centroids (the start it reports), the tolerance counted."""
    elements = list(iterative(can, heuristic(can, seed=3).elements).elements)
    placed = Placer(can, PlacementOptions(bound=False))(elements)
    model = can.model
    start = ContactSet(
        tuple(
            spec.at(model.elements[e].vertices.mean(axis=0), model.elements[e].inward_normal)
            for spec, e in zip(can.specs, elements)
        ),
        can.torque_scale,
        model.reference_point,
        can.contact_tolerance(elements),
    )
    centred = rho(start)
    assert placed.robust_rho <= centred.robust_rho + 1e-6 * max(1.0, abs(centred.robust_rho))
    again = rho(placed.contact_set)
    assert again.shift == pytest.approx(placed.shift, rel=1e-12)


def _not_robust_set():
    """Four held PCwF contacts (random) with a normal tolerance too wide for them."""
    rng = np.random.default_rng(4)
    while True:
        contacts = random_contact_set(rng, ["pcwf"] * 4)
        if rho(contacts).force_closure:
            break
    tolerance = (ModelTolerance(0.01, 30.0),) + (ModelTolerance(0.0, 1.0),) * 3
    return dataclasses.replace(contacts, tolerance=tolerance)


def test_the_tolerance_that_would_make_contacts_robust_makes_them_robust():
    """The factor and each contact's own tolerance that ``to_be_robust`` names are checked by
    the certified rho of the set carrying them: robust at them, not robust a little above."""
    contacts = _not_robust_set()
    found = rho(contacts)
    assert found.force_closure and found.robust is False
    advice = to_be_robust(contacts, found.bounds)
    assert 0.0 < advice["factor"] < 1.0
    assert advice["shift"] == pytest.approx(found.shift, rel=1e-12)

    def robust_with(tolerances) -> bool:
        return rho(dataclasses.replace(contacts, tolerance=tuple(tolerances))).robust

    own = contacts.tolerance
    f = advice["factor"]
    assert robust_with([ModelTolerance(t.position * f, t.normal_deg * f) for t in own])
    g = f * 1.01
    assert not robust_with([ModelTolerance(t.position * g, t.normal_deg * g) for t in own])
    alone = [c for c in advice["contacts"] if c["factor"] is not None]
    assert alone  # the 30-degree contact carries most of the shift
    assert advice["contacts"][advice["costliest"]]["shift"] == max(
        c["shift"] for c in advice["contacts"]
    )
    for entry in alone:
        i = entry["contact"]
        shrunk = list(own)
        shrunk[i] = ModelTolerance(**entry["tolerance"])
        assert robust_with(shrunk)
        k = entry["factor"] * 1.01
        shrunk[i] = ModelTolerance(own[i].position * k, own[i].normal_deg * k)
        assert not robust_with(shrunk)
    text = to_be_robust_text(advice)
    assert "robust if every contact's tolerance were" in text and "alone were within" in text
    assert (
        to_be_robust(dataclasses.replace(contacts, tolerance=ModelTolerance()), found.bounds)
        is None
    )
