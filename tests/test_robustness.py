"""Robust verdicts: every contact set within the tolerances of a robust one is force closure."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.base.tolerances import DEFAULT_TOLERANCES
from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import tolerance_unit
from closure_nlp.criterion.robustness import (
    ModelTolerance,
    is_robust,
    support_shift,
    tolerance_from_dict,
)
from closure_nlp.criterion.support_minimum import rho


def _tilted(n, angle, rng):
    """``n`` rotated by ``angle`` about a random axis perpendicular to it."""
    axis = np.cross(n, rng.standard_normal(3))
    axis /= np.linalg.norm(axis)
    return np.cos(angle) * n + np.sin(angle) * np.cross(axis, n)


def _perturbed(contacts: ContactSet, tol: ModelTolerance, rng, worst_at=None) -> ContactSet:
    """Each contact moved by at most ``tol``; with ``worst_at`` (a direction), the one of 40
    random moves that lowers its support value there the most."""
    out = []
    for c in contacts.contacts:
        options = []
        for _ in range(40 if worst_at is not None else 1):
            step = rng.standard_normal(3)
            step *= tol.position * rng.uniform(0.5, 1.0) ** (1 / 3) / np.linalg.norm(step)
            angle = np.radians(tol.normal_deg) * rng.uniform(0.5, 1.0)
            moved = Contact(
                c.position + step,
                _tilted(c.inward_normal, angle, rng),
                c.type,
                c.mu,
                c.mu_s,
                c.f_max,
            )
            options.append(moved)
        if worst_at is not None:
            values = [
                WrenchSlots.from_contacts(
                    ContactSet((o,), contacts.torque_scale, contacts.reference_point)
                ).support(worst_at[None])[0]
                for o in options
            ]
            options = [options[int(np.argmin(values))]]
        out.append(options[0])
    return ContactSet(tuple(out), contacts.torque_scale, contacts.reference_point)


def _case(seed: int, types):
    rng = np.random.default_rng(seed)
    for _ in range(50):
        contacts = random_contact_set(rng, types, mu=0.5, mu_s=0.2)
        result = rho(contacts)
        if result.force_closure:
            return contacts, result
    raise AssertionError("no force-closure set drawn")


def _scaled(contacts, result, share: float, halve: bool = False) -> ModelTolerance:
    """A tolerance (position 1: 20 of a unit part, 1 degree) scaled so that the shift (halved
    if ``halve``) is ``share`` of the certified capacity ``-hi``."""
    base = ModelTolerance(0.05, 1.0)
    shift = support_shift(contacts, base) * (0.5 if halve else 1.0)
    k = share * -result.bounds[1] / shift
    return ModelTolerance(base.position * k, base.normal_deg * k)


CASES = [(1, ["fpc"] * 7), (2, ["pcwf"] * 4), (3, ["sfce"] * 3), (4, ["fpc", "pcwf", "sfcl"])]


@pytest.mark.parametrize("seed, types", CASES)
def test_robust_sets_stay_force_closure_under_perturbation(seed, types):
    contacts, result = _case(seed, types)
    tol = _scaled(contacts, result, 0.9)
    shift = support_shift(contacts, tol)
    unit = tolerance_unit(WrenchSlots.from_contacts(contacts))
    assert is_robust(result, shift, unit, DEFAULT_TOLERANCES)
    rng = np.random.default_rng(seed)
    for k in range(8):
        moved = _perturbed(contacts, tol, rng, result.direction if k % 2 else None)
        assert rho(moved).force_closure


@pytest.mark.parametrize("kind", ["fpc", "pcwf", "sfcl", "sfce"])
@pytest.mark.parametrize("position, normal_deg", [(0.05, 0.0), (0.0, 2.0), (0.05, 2.0)])
def test_each_contact_moves_within_its_shift_and_the_shift_is_nearly_reached(
    kind, position, normal_deg
):
    """One contact moved at random within the tolerance: its support value never moves more
    than its shift in any of 3000 directions, and some move comes within 0.8 of it (a shift
    halved would be exceeded: the check has teeth)."""
    rng = np.random.default_rng(5)
    tol = ModelTolerance(position, normal_deg)
    contact = Contact(np.array([0.3, -0.5, 0.8]), np.array([0.2, 0.1, -1.0]), kind, 0.5, 0.2)
    one = ContactSet((contact,), 0.7)
    shift = support_shift(one, tol)
    U = rng.standard_normal((3000, 6))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    base = WrenchSlots.from_contacts(one).support(U)
    worst = 0.0
    for _ in range(150):
        step = rng.standard_normal(3)
        step *= position / np.linalg.norm(step)
        normal = _tilted(contact.inward_normal, np.radians(normal_deg), rng)
        moved = Contact(contact.position + step, normal, kind, 0.5, 0.2)
        values = WrenchSlots.from_contacts(ContactSet((moved,), 0.7)).support(U)
        worst = max(worst, float(np.abs(values - base).max()))
    assert worst <= shift * (1 + 1e-12)
    assert worst >= 0.8 * shift


def test_no_tolerance_means_force_closure():
    contacts, result = _case(2, ["pcwf"] * 4)
    assert support_shift(contacts, ModelTolerance()) == 0.0
    assert is_robust(result, 0.0, 1.0, DEFAULT_TOLERANCES) == result.force_closure


def test_shift_scales_with_the_part():
    """The same part in mm with torque scale / 1000 and mu_s x 1000: the same shift."""
    contacts, _ = _case(3, ["sfce"] * 3)
    big = ContactSet(
        tuple(
            Contact(1000 * c.position, c.inward_normal, c.type, c.mu, 1000 * c.mu_s, c.f_max)
            for c in contacts.contacts
        ),
        contacts.torque_scale / 1000,
    )
    tol = ModelTolerance(0.01, 0.5)
    assert support_shift(big, ModelTolerance(10.0, 0.5)) == pytest.approx(
        support_shift(contacts, tol), rel=1e-9
    )


def test_tolerance_input_is_checked():
    assert tolerance_from_dict({"position": 0.1}) == ModelTolerance(0.1, 0.0)
    assert not tolerance_from_dict(None)
    with pytest.raises(ValueError, match="tolerance.normal_deg"):
        tolerance_from_dict({"normal_deg": -1})
    with pytest.raises(ValueError, match="unknown"):
        tolerance_from_dict({"angle": 1})
    with pytest.raises(TypeError, match="tolerance.position"):
        tolerance_from_dict({"position": "1mm"})
    with pytest.raises(TypeError, match="tolerance"):
        tolerance_from_dict([0.1, 1.0])


def test_robust_rho_bounds_every_set_within_the_tolerance():
    """``robust_rho = hi + shift``: no contact set whose points and normals lie within the
    tolerance of the file's has a larger rho (checked on random such sets, by rho itself)."""
    import numpy as np

    from closure_nlp import Contact, ContactSet, ModelTolerance, rho
    from closure_nlp.contact.random_sets import random_contact_set

    rng = np.random.default_rng(11)
    tolerance = ModelTolerance(0.02, 3.0)
    for k in range(6):
        base = random_contact_set(rng, ["pcwf", "sfce", "pcwf", "fpc"], mu=0.5)
        given = rho(base, tolerance=tolerance)
        assert given.robust_rho == given.bounds[1] + given.shift
        assert given.to_dict()["robust_rho"] == given.robust_rho
        for _ in range(5):
            moved = []
            for c in base.contacts:
                step = rng.normal(size=3)
                step *= rng.uniform(0, tolerance.position) / np.linalg.norm(step)
                axis = np.cross(c.inward_normal, rng.normal(size=3))
                axis /= np.linalg.norm(axis)
                angle = np.radians(rng.uniform(0, tolerance.normal_deg))
                n = np.cos(angle) * c.inward_normal + np.sin(angle) * axis
                moved.append(Contact(c.position + step, n, c.type, c.mu, c.mu_s, c.f_max))
            assert rho(ContactSet(tuple(moved))).bounds[0] <= given.robust_rho + 1e-9, k
