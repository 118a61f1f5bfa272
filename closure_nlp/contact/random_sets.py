"""Seeded random contact sets for benchmarks, comparisons and tests.

Contacts lie on a random ellipsoid-like body with inward normals tilted by noise, so a share of
the sets is force closure and a share is not, for every contact type.
"""

from __future__ import annotations

import numpy as np

from closure_nlp.contact.contact_set import Contact, ContactSet, ContactType
from closure_nlp.contact.wrenches import WrenchSlots


def random_contact_set(
    rng: np.random.Generator,
    types,
    *,
    mu: float = 0.5,
    mu_s: float = 0.2,
    tilt: float = 0.3,
    torque_scale: float = 1.0,
) -> ContactSet:
    """One random set with the given contact type sequence (strings or ContactType)."""
    types = [ContactType.parse(t) for t in types]
    m = len(types)
    points = rng.standard_normal((m, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    points *= rng.uniform(0.5, 1.5, (m, 1)) * np.array([1.0, 0.8, 0.6])
    normals = -points / np.linalg.norm(points, axis=1, keepdims=True)
    normals += tilt * rng.standard_normal((m, 3))
    return ContactSet(
        tuple(Contact(points[i], normals[i], types[i], mu=mu, mu_s=mu_s) for i in range(m)),
        torque_scale,
    )


BENCH_CASES = {
    "4 PCwF": ["pcwf"] * 4,
    "4 SFCe": ["sfce"] * 4,
    "7 FPC": ["fpc"] * 7,
    "4 mixed": ["fpc", "pcwf", "sfcl", "sfce"],
}


def random_load(rng: np.random.Generator, contact_set: ContactSet, inside: bool) -> np.ndarray:
    """A load (6,) for load-factor comparisons: ``inside``, minus a point inside the contacts'
    wrench set times 0.3 to 2 (a factor of about 1 or more); otherwise a random wrench (often
    one the contacts cannot hold at all)."""
    if not inside:
        return rng.standard_normal(6)
    points = WrenchSlots.from_contacts(contact_set).support_points(rng.standard_normal((3, 6)))
    return -(rng.dirichlet(np.ones(3)) @ points) * rng.uniform(0.3, 2.0)
