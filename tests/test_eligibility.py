"""rho_hat = rho(0, What_c^M) of element sets: an independent reference, containment, padding."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from closure_nlp.contact.contact_set import ContactSet
from closure_nlp.criterion.certificate import certified_bounds
from closure_nlp.criterion.crosscheck import force_closure_cvxpy
from closure_nlp.criterion.rho_hat import Eligibility, padded_rows, rho_hat
from closure_nlp.criterion.support_minimum import SupportMinProblem, rho
from closure_nlp.model.elements import load_model
from closure_nlp.model.scale import contact_specs
from tests import reference
from tests.shapes import box_model, random_model

TYPES = ["fpc", "pcwf", "sfcl", "sfce"]
KINDS = ["facet", "segment", "point"]


def _independent(model, eligibility, elements):
    """The reference's view: raw vertices and normals of the chosen elements."""
    return reference.from_elements(
        [model.elements[e].vertices for e in elements],
        [model.elements[e].inward_normal for e in elements],
        [(s.type.value, s.mu, s.mu_s, s.f_max) for s in eligibility.specs],
        eligibility.torque_scale,
    )


def _case(seed, kind_mix, types):
    rng = np.random.default_rng(seed)
    m = len(types)
    model = random_model(rng, [kind_mix[i % len(kind_mix)] for i in range(m + 2)])
    specs = contact_specs(m, type=list(types), mu=0.5, mu_s=0.1, f_max=1.0)
    elements = rng.permutation(len(model))[:m].tolist()
    return model, Eligibility(model, specs, torque_scale=1.0), elements


CASES = [
    (seed, kinds, types)
    for seed, (kinds, types) in enumerate(
        [
            (["facet"], ["pcwf"] * 4),
            (["facet"], ["fpc"] * 7),
            (["segment"], ["sfce"] * 3),
            (["segment", "point"], ["sfcl"] * 4),
            (["point"], ["pcwf"] * 4),
            (["facet", "segment", "point"], ["fpc", "pcwf", "sfcl", "sfce"]),
            (["facet", "point"], ["sfce"] * 2),
            (["facet", "segment"], ["pcwf", "pcwf", "sfce"]),
        ]
    )
]


# Cases 2-6 (every element kind and contact type among them) take a few seconds in all; the
# others, over a minute (case 0: 4 PCwF on facets, the reference's minimum), run with the slow.
SLOW_CASES = {0, 1, 7}


@pytest.mark.parametrize(
    ("seed", "kinds", "types"),
    [pytest.param(*c, marks=pytest.mark.slow) if c[0] in SLOW_CASES else c for c in CASES],
)
def test_rho_hat_agrees_with_independent_reference(seed, kinds, types):
    model, eligibility, elements = _case(seed, kinds, types)
    result = eligibility(elements)
    slots = _independent(model, eligibility, elements)
    # The value we report is the reference support function at our direction ...
    assert (
        -result.rho_hat
        == pytest.approx(
            reference.support(result.direction, slots), abs=1e-9 * max(1, abs(result.rho_hat))
        )
        or result.rho_hat == 0.0
    )
    # ... and no direction the reference finds is lower. IPOPT's barrier keeps each epigraph
    # variable s >= sqrt(q) about sqrt(tol) = 1e-6 above a cone's apex (d_ot = 0), so a minimum
    # with k contacts at their apex is reached to about k * 1e-6 * f_max.
    ref_value, _ = reference.reference_min(slots, samples=800, starts=6)
    assert -result.rho_hat <= ref_value + 1e-6 * len(types) * max(1.0, abs(ref_value))


MODELS = Path(__file__).resolve().parents[1] / "models"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "kind", "eligible_set"),
    [("lamp", "pcwf", [48, 0, 53, 34]), ("cup", "sfcl", [24, 31, 20, 3]), ("pistol", "fpc", None)],
)
def test_rho_hat_of_model_elements_lies_within_certified_bounds(name, kind, eligible_set):
    """The cross-check methods (cvxpy SOCP, qhull inner polytope) on the union of vertex sets."""
    model = load_model(MODELS / f"{name}.model.json")
    m = 7 if kind == "fpc" else 4
    eligibility = Eligibility(
        model, contact_specs(m, type=kind, mu=0.2, mu_s=0.2), torque_scale=1.0
    )
    rng = np.random.default_rng(3)
    sets = [rng.choice(len(model), m).tolist() for _ in range(3)]
    for elements in [*([eligible_set] if eligible_set else []), *sets]:
        result = eligibility(elements)
        slots = eligibility.slots(elements)
        lo, hi = certified_bounds(slots, result.direction)
        tol = 1e-6 * max(1.0, abs(result.rho_hat))
        assert lo - tol <= result.rho_hat <= hi + tol, (elements, result.rho_hat, lo, hi)
        if abs(result.rho_hat) > 1e-6:
            assert force_closure_cvxpy(slots) is result.eligible
        if elements is eligible_set:
            assert result.eligible  # the README's example set


@pytest.mark.parametrize("kind", TYPES)
def test_contacts_inside_elements_are_never_better(kind):
    """W_c^M lies in What_c^M: rho of contacts anywhere on the elements >= rho_hat."""
    rng = np.random.default_rng(11)
    model = random_model(rng, ["facet", "facet", "segment", "point", "facet"])
    m = 4
    specs = contact_specs(m, type=kind, mu=0.4, mu_s=0.1)
    elements = [0, 1, 2, 4]
    bound = Eligibility(model, specs, torque_scale=1.0).__call__(elements).rho_hat
    for _ in range(4):
        contacts = []
        for i, e in enumerate(elements):
            element = model.elements[e]
            w = rng.dirichlet(np.ones(len(element.vertices)))
            contacts.append(specs[i].at(element.position(w), element.inward_normal))
        value = rho(ContactSet(tuple(contacts))).rho
        assert value >= bound - 1e-6 * max(1.0, abs(bound))


def test_point_elements_give_the_contacts_rho():
    """A point element is a contact: rho_hat of points equals rho of contacts there."""
    rng = np.random.default_rng(5)
    model = random_model(rng, ["point"] * 4)
    specs = contact_specs(4, type="sfce", mu=0.5, mu_s=0.2)
    result = rho_hat(model, [0, 1, 2, 3], specs, torque_scale=1.0)
    contacts = [s.at(e.vertices[0], e.inward_normal) for s, e in zip(specs, model.elements)]
    assert result.rho_hat == pytest.approx(rho(ContactSet(tuple(contacts))).rho, abs=1e-7)


def test_box_faces_analytic():
    """4 PCwF on the 4 side faces of a cube; on one face only the set lies above the origin."""
    model = box_model(1.0)
    eligibility = Eligibility(model, contact_specs(4, type="pcwf", mu=0.5), torque_scale=1.0)
    side = eligibility([0, 1, 2, 3])
    assert side.eligible and side.rho_hat < 0
    one_face = eligibility([4, 4, 4, 4])
    # Every wrench of a face with normal +z has force_z = f_n = 1 and |force_xy| <= mu:
    # the nearest point of the set is (0, 0, 1, torque 0) at distance 1 from the origin.
    assert not one_face.eligible
    assert one_face.rho_hat == pytest.approx(1.0, abs=1e-7)
    assert abs(one_face.direction[2]) == pytest.approx(1.0, abs=1e-6)


def test_padding_keeps_support_values():
    rng = np.random.default_rng(3)
    model = random_model(rng, ["facet"] * 6)
    eligibility = Eligibility(model, contact_specs(3, type="sfcl"), torque_scale=1.0)
    elements = [0, 2, 5]
    padded = eligibility.slots(elements)
    # the slots hold the vertex rows as they are; the NLP pads them to bucket sizes, sorted by
    # size (one NLP shape for every order of the same elements)
    assert sorted(padded.rows_per_slot) == sorted(len(model.elements[e].vertices) for e in elements)
    key = SupportMinProblem.key(padded)
    assert key[1] == tuple(sorted(padded_rows(len(model.elements[e].vertices)) for e in elements))
    assert SupportMinProblem.key(eligibility.slots(elements[::-1])) == key
    U = rng.standard_normal((50, 6))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    slots = _independent(model, eligibility, elements)
    expected = [reference.support(u, slots) for u in U]
    np.testing.assert_allclose(padded.support(U), expected, rtol=1e-12, atol=1e-12)
    # the padded NLP's start is the epigraph at u: its slot values are p's
    problem = eligibility.minimizer.problem(padded)
    x0 = problem.initial_guess(padded, U[0])
    np.testing.assert_allclose(x0[-2], padded.support(U[:1])[0], rtol=1e-6, atol=1e-6)


def test_bad_element_lists():
    model = box_model()
    eligibility = Eligibility(model, contact_specs(2), torque_scale=1.0)
    with pytest.raises(ValueError, match=r"elements: expected 2 element ids"):
        eligibility([0, 1, 2])
    with pytest.raises(ValueError, match=r"elements\[1\]: element id 6 out of range"):
        eligibility([0, 6])
    with pytest.raises(TypeError, match=r"elements\[0\]"):
        eligibility(["a", 1])
    with pytest.raises(TypeError, match="specs"):
        Eligibility(model, ["pcwf"], torque_scale=1.0)
    with pytest.raises(ValueError, match=r"contacts\[1\]\.mu: must be >= 0"):
        contact_specs(2, mu=[0.2, -0.1])
    with pytest.raises(ValueError, match="mu: expected one value or 2 values"):
        contact_specs(2, mu=[0.2, 0.1, 0.3])


def test_model_based_api_uses_the_command_lines_defaults(capsys):
    """``Eligibility`` defaults to the CLI's torque scale and ``contact_specs(model=)`` to its
    mu_s: 1 / R and 0.01 R, R the largest distance of a vertex from the reference point (computed
    here from the file's vertices); the CLI's rho_hat of the same set is the API's."""
    import json

    from closure_nlp.cli.main import main

    path = MODELS / "cup.model.json"
    cup = load_model(path)
    vertices = np.concatenate([e.vertices for e in cup.elements])
    radius = np.max(np.linalg.norm(vertices - np.asarray(cup.reference_point), axis=1))
    hand = Eligibility(cup, contact_specs(4, type="sfce", model=cup))
    assert hand.torque_scale == pytest.approx(1 / radius, rel=1e-12)
    assert [s.mu_s for s in hand.specs] == pytest.approx([0.01 * radius] * 4, rel=1e-12)
    # without a model, and with explicit values, the values given are kept
    assert {s.mu_s for s in contact_specs(2, type="sfce")} == {0.2}
    assert {s.mu_s for s in contact_specs(2, type="sfce", mu_s=0.05, model=cup)} == {0.05}
    assert Eligibility(cup, hand.specs, torque_scale=1.0).torque_scale == 1.0
    api = hand([24, 31, 20, 3])
    argv = ["eligibility", str(path), "--elements", "24,31,20,3", "--type", "sfce", "--json"]
    assert main(argv) == 0
    cli = json.loads(capsys.readouterr().out)
    assert cli["torque_scale"] == hand.torque_scale and cli["mu_s"] == hand.specs[0].mu_s
    assert cli["rho_hat"] == pytest.approx(api.rho_hat, rel=1e-9)
