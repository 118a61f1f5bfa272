"""Verdicts do not depend on the length of a normal, on f_max or on torque_scale, over the whole
range the input accepts (property tests).

A normal's length is removed on input (exactly, without overflow). Scaling every f_max by c
scales the wrench set, so rho scales by c and the verdict stays; torque_scale maps the set by
diag(1, 1, 1, t, t, t), which keeps the origin inside or outside, so the verdict stays too.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from closure_nlp.base.validation import SCALE_RANGE, TORQUE_SCALE_RANGE
from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.scale import contact_specs

from .shapes import box_model

LOW, HIGH = np.log10(SCALE_RANGE[0]), np.log10(SCALE_RANGE[1])  # f_max
T_LOW, T_HIGH = np.log10(TORQUE_SCALE_RANGE[0]), np.log10(TORQUE_SCALE_RANGE[1])
SETTINGS = settings(
    max_examples=10,
    deadline=None,
    derandomize=True,  # the same examples every run
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
KINDS = st.sampled_from([["pcwf"] * 4, ["sfce"] * 3, ["fpc"] * 7, ["fpc", "pcwf", "sfcl", "sfce"]])


def base_set(seed, kinds):
    contact_set = random_contact_set(np.random.default_rng(seed), kinds)
    reference = rho(contact_set)
    assume(abs(reference.rho) > 1e-3)  # a marginal set may legitimately sit on the tolerance
    return contact_set, reference


def rebuilt(contact_set, *, normal_scale=1.0, f_max=None, torque_scale=None):
    return ContactSet(
        tuple(
            Contact(
                c.position,
                c.inward_normal * normal_scale,
                c.type,
                c.mu,
                c.mu_s,
                c.f_max if f_max is None else f_max,
            )
            for c in contact_set.contacts
        ),
        contact_set.torque_scale if torque_scale is None else torque_scale,
    )


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), kinds=KINDS, exponent=st.floats(-300, 300))
@example(seed=0, kinds=["fpc"] * 7, exponent=-300.0).via("the ends of the double range")
@example(seed=0, kinds=["fpc"] * 7, exponent=300.0).via("the ends of the double range")
def test_rho_invariant_to_the_length_of_the_normals(seed, kinds, exponent):
    contact_set, reference = base_set(seed, kinds)
    scaled = rho(rebuilt(contact_set, normal_scale=10.0**exponent))
    assert scaled.force_closure == reference.force_closure
    assert scaled.rho == pytest.approx(reference.rho, rel=1e-6, abs=1e-9)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), kinds=KINDS, exponent=st.floats(LOW, HIGH))
@example(seed=0, kinds=["pcwf"] * 4, exponent=LOW).via("the ends of the accepted range")
@example(seed=0, kinds=["pcwf"] * 4, exponent=HIGH).via("the ends of the accepted range")
def test_rho_verdict_invariant_to_f_max(seed, kinds, exponent):
    contact_set, reference = base_set(seed, kinds)
    c = 10.0**exponent
    scaled = rho(rebuilt(contact_set, f_max=c))
    assert np.isfinite(scaled.rho)
    assert scaled.force_closure == reference.force_closure
    assert scaled.rho == pytest.approx(c * reference.rho, rel=1e-5)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), kinds=KINDS, exponent=st.floats(T_LOW, T_HIGH))
@example(seed=0, kinds=["pcwf"] * 4, exponent=T_LOW).via("the ends of the accepted range")
@example(seed=0, kinds=["pcwf"] * 4, exponent=T_HIGH).via("the ends of the accepted range")
def test_rho_verdict_invariant_to_torque_scale(seed, kinds, exponent):
    contact_set, reference = base_set(seed, kinds)
    scaled = rho(rebuilt(contact_set, torque_scale=10.0**exponent))
    assert np.isfinite(scaled.rho)
    assert scaled.force_closure == reference.force_closure


@pytest.mark.slow  # 79 s: the fast suite stays near 10 minutes
@settings(SETTINGS, max_examples=4)  # the range ends below, and 4 draws (each certifies twice)
@given(
    f_exponent=st.floats(LOW, HIGH),
    t_exponent=st.floats(T_LOW, T_HIGH),
    ids=st.sampled_from([(0, 1, 2, 3), (0, 2, 4, 5), (0, 0, 1, 1)]),
)
@example(f_exponent=LOW, t_exponent=0.0, ids=(0, 1, 2, 3)).via("the ends of the accepted range")
@example(f_exponent=HIGH, t_exponent=0.0, ids=(0, 1, 2, 3)).via("the ends of the accepted range")
@example(f_exponent=0.0, t_exponent=T_LOW, ids=(0, 1, 2, 3)).via("the ends of the accepted range")
@example(f_exponent=0.0, t_exponent=T_HIGH, ids=(0, 1, 2, 3)).via("the ends of the accepted range")
def test_eligibility_verdict_invariant_to_f_max_and_torque_scale(f_exponent, t_exponent, ids):
    model = box_model()
    reference = Eligibility(model, contact_specs(4, mu=0.5), torque_scale=1.0)(list(ids))
    scaled = Eligibility(
        model, contact_specs(4, mu=0.5, f_max=10.0**f_exponent), torque_scale=10.0**t_exponent
    )(list(ids))
    assert np.isfinite(scaled.rho_hat)
    assert scaled.eligible == reference.eligible
