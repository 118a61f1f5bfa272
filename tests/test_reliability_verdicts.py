"""Verdicts never contradict the certified bracket they are reported with, whatever the
coefficients: ``mu``, ``mu_s`` and ``f_max`` from 1e-12 to 1e12 (``mu`` to its limit, 1e6), every
contact type, a few geometries."""

import itertools

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import (
    CertifyOptions,
    certified_bounds,
    tolerance_unit,
    verdicts,
)
from closure_nlp.criterion.sphere_branch_bound import BranchBoundOptions
from closure_nlp.criterion.support_minimum import rho

TOL = 1e-6
AXES = np.eye(3)
CORNERS = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
GEOMETRIES = {
    # six contacts on a unit sphere at +-e_k, pushing towards the centre
    "sphere6": [(s * AXES[k], -s * AXES[k]) for k in range(3) for s in (1.0, -1.0)],
    "tetra4": [(v, -v / np.linalg.norm(v)) for v in CORNERS],
    "pair2": [(AXES[2], -AXES[2]), (-AXES[2], AXES[2])],
}
TYPES = ("fpc", "pcwf", "sfcl", "sfce")
MU = (1e-12, 1.0, 1e6)
MU_S = (1e-12, 1.0, 1e12)
F_MAX = (1e-12, 1.0, 1e12)


def _contact_set(geometry, kind, mu, mu_s, f_max):
    pairs = GEOMETRIES[geometry]
    return ContactSet(tuple(Contact(p, n, kind, mu, mu_s, f_max) for p, n in pairs))


def _check(lo, hi, closure, marginal, zero):
    assert lo <= hi
    if closure:
        assert hi < -zero and not marginal
    elif marginal:
        assert hi >= -zero and lo <= zero
    else:  # neither: certainly not force closure
        assert lo > zero


@pytest.mark.parametrize(
    "lo, hi, expected",
    [
        (-2.0, -1.0, (True, False)),
        (-2.0, -0.5e-6, (False, True)),  # within the tolerance of zero: marginal
        (-2.0, 0.0, (False, True)),
        (-2.0, 3.0, (False, True)),  # straddles zero: undecided, never closure
        (0.5e-6, 1.0, (False, True)),
        (2e-6, 1.0, (False, False)),
    ],
)
def test_verdicts_of_a_bracket(lo, hi, expected):
    assert verdicts(lo, hi, TOL) == expected


# A small budget: the verdicts must agree with whatever bracket it leaves (rho() below runs the
# full budget on fewer sets).
SMALL = CertifyOptions(BranchBoundOptions(max_cells=400, extended_cells=400), max_iter=40)


@pytest.mark.parametrize("geometry", sorted(GEOMETRIES))
@pytest.mark.parametrize("kind", TYPES)
def test_extreme_coefficients_verdicts_agree_with_bounds(geometry, kind):
    for mu, mu_s, f_max in itertools.product(MU, MU_S, F_MAX):
        if kind == "fpc" and (mu, mu_s) != (1.0, 1.0):
            continue  # no friction: only f_max acts
        if kind == "pcwf" and mu_s != 1.0:
            continue  # no spin
        slots = WrenchSlots.from_contacts(_contact_set(geometry, kind, mu, mu_s, f_max))
        b = certified_bounds(slots, options=SMALL)
        assert np.isfinite([b.lo, b.hi]).all(), (mu, mu_s, f_max)
        _check(b.lo, b.hi, b.force_closure, b.marginal, TOL * tolerance_unit(slots))


# Full budget, the sets of the original report and their neighbours. Which converge: every
# f_max (the certificate is scale-free); mu 1e-12 and 1; mu_s up to 1. Not converged (valid,
# wider brackets, verdicts still theirs): mu = 1e6 (the normal force is 1e-6 of the friction:
# e.g. sphere6 PCwF [-3.94239e6, -3.93956e6]) and, for soft fingers, mu_s >= 1e6 (spin 1e6x the
# force rows: sphere6 SFCe mu 1, mu_s 1e6 [-5, -2]).
FULL = [
    ("sphere6", "sfce", 1e6, 1e12, 1.0, False),  # the reported set
    ("sphere6", "sfce", 1.0, 1.0, 1e12, True),
    ("sphere6", "pcwf", 1e-12, 1.0, 1e-12, True),
    ("tetra4", "pcwf", 1.0, 1.0, 1e-12, True),
    ("pair2", "sfce", 1.0, 1e-12, 1e12, True),
    ("pair2", "fpc", 1.0, 1.0, 1e-12, True),
]


@pytest.mark.slow
@pytest.mark.parametrize("geometry, kind, mu, mu_s, f_max, converges", FULL)
def test_extreme_coefficients_rho(geometry, kind, mu, mu_s, f_max, converges):
    contact_set = _contact_set(geometry, kind, mu, mu_s, f_max)
    result = rho(contact_set)
    lo, hi = result.bounds
    unit = tolerance_unit(WrenchSlots.from_contacts(contact_set))
    _check(lo, hi, result.force_closure, result.marginal, TOL * unit)
    assert lo <= result.rho <= hi
    assert result.robust is None  # no tolerance: the JSON says robust = force_closure
    assert result.converged == converges
