"""The exchange method's restricted problem by sequential linear programming: the linearisation
of the support function in the weights, the solver against IPOPT, and its use by placement."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.contact.contact_set import ContactType
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import load_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.placement.placer import ElementFrame, ExchangeSLP, _unpadded
from closure_nlp.placement.restricted import ExchangeProblem
from closure_nlp.placement.sequential_lp import (
    ModelSLP,
    linearised_support,
    model_linearisation,
    restricted_model,
)

MODELS = Path(__file__).resolve().parents[1] / "models"
TYPES = [ContactType.FPC, ContactType.PCWF, ContactType.SFCL, ContactType.SFCE]


def _setup(name, elements, kinds, seed):
    """A placer on ``elements`` of an example model with one contact type each, random unit
    directions and random weights: (placer, frames, directions, rng)."""
    rng = np.random.default_rng(seed)
    model = load_model(MODELS / f"{name}.model.json")
    specs = tuple(contact_specs(1, type=kind, mu=0.4, model=model)[0] for kind in kinds)
    eligibility = Eligibility(model, specs)
    placer = Placer(eligibility, PlacementOptions(bound=False))
    frames = [ElementFrame.padded(model.elements[e], eligibility.torque_scale) for e in elements]
    U = rng.standard_normal((30, 6))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    return placer, frames, U, rng


def _true_values(placer, elements, weights, U):
    """``p(u_k; c)`` by the compiled support function of the contacts placed at ``weights``
    (unpadded): the path the placement's searches use, independent of the linearisation."""
    model = placer.eligibility.model
    real = [_unpadded(w, len(model.elements[e].vertices)) for w, e in zip(weights, elements)]
    return WrenchSlots.from_contacts(placer.contact_set(elements, real)).support(U)


def _random_weights(rng, frames):
    return [rng.dirichlet(np.full(len(f.G), 0.3)) for f in frames]


@pytest.mark.parametrize("seed", range(4))
def test_linearisation_is_exact_at_its_point_and_below_everywhere(seed):
    """``A @ c`` equals ``p(u_k; c)`` at the weights it was taken at, and ``A @ x`` is at most
    ``p(u_k; x)`` at any other weights: mixed contact types on facets, segments and points of
    the lamp and the pistol (the convexity of the support function in the weights)."""
    name, elements = [("lamp", [14, 10, 55, 47]), ("pistol", [6, 5, 1, 3])][seed % 2]
    rng0 = np.random.default_rng(100 + seed)
    kinds = [TYPES[i] for i in rng0.permutation(4)]
    placer, frames, U, rng = _setup(name, elements, kinds, seed)
    local = [frame.local(U) for frame in frames]
    # the contacts' types, friction and force bounds (their positions are not used)
    counts = [len(placer.eligibility.model.elements[e].vertices) for e in elements]
    centroids = [np.full(k, 1.0 / k) for k in counts]
    slot_specs = WrenchSlots.from_contacts(placer.contact_set(elements, centroids))
    for _ in range(5):
        c = _random_weights(rng, frames)
        values, A = linearised_support(local, c, slot_specs)
        true = _true_values(placer, elements, c, U)
        scale = max(1.0, np.abs(true).max())
        np.testing.assert_allclose(values, true, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(A @ np.concatenate(c), true, rtol=0, atol=1e-12 * scale)
        for _ in range(5):
            x = _random_weights(rng, frames)
            below = A @ np.concatenate(x)
            assert np.all(below <= _true_values(placer, elements, x, U) + 1e-12 * scale)


@pytest.mark.parametrize("kind", ["pcwf", "sfce"])
def test_sequential_lp_never_loses_and_keeps_ipopts_optimum(kind):
    """On random restricted problems: the SLP's value is the true ``min_k p(u_k; c)`` at its
    weights (never below its start's), its weights in their simplices and the trust region;
    started at IPOPT's optimum it keeps at least IPOPT's value (IPOPT's model is a restriction
    of the true support function, so its value is met there)."""
    elements = [14, 10, 55, 47]
    placer, frames, U, rng = _setup("lamp", elements, [kind] * 4, 7)
    rows = tuple(len(f.G) for f in frames)
    f_max = np.ones(4)
    ipopt = ExchangeProblem(rows, 32, 1e-10, 0.01)
    slp = ExchangeSLP()
    model = placer.eligibility.model
    for trial in range(4):
        weights = [rng.dirichlet(np.ones(len(model.elements[e].vertices))) for e in elements]
        slots = WrenchSlots.from_contacts(placer.contact_set(elements, weights))
        start = [np.pad(w, (0, k - len(w))) for w, k in zip(weights, rows)]
        radius = [0.1, 0.3, 1.0, 0.5][trial]
        before = _true_values(placer, elements, start, U).min()
        c, value = slp.solve(frames, slots, f_max, U, start, radius)
        scale = max(1.0, abs(before))
        assert value >= before - 1e-12 * scale
        assert value == pytest.approx(_true_values(placer, elements, c, U).min(), abs=1e-9 * scale)
        for ci, si in zip(c, start):
            assert ci.sum() == pytest.approx(1.0) and ci.min() >= 0.0
            assert np.abs(ci - si).max() <= radius + 1e-9
        c_ip, r = ipopt.solve(frames, slots, f_max, U, start, radius)
        c_ip = [np.maximum(ci, 0.0) / np.maximum(ci, 0.0).sum() for ci in c_ip]
        at_ipopt = _true_values(placer, elements, c_ip, U).min()
        assert at_ipopt >= r - 1e-7 * scale
        again, value_again = slp.solve(frames, slots, f_max, U, c_ip, radius / 2)
        assert value_again >= at_ipopt - 1e-12 * scale
        assert slp.steps >= 1


def test_placement_by_the_sequential_lp_builds_no_nlp():
    """``exchange_solver="slp"``: placement with friction solves its restricted problems by the
    sequential LP (no CasADi NLP built); the default keeps IPOPT with friction and HiGHS's LP
    without; both never end worse than their start, and the result says which ran."""
    model = load_model(MODELS / "lamp.model.json")
    eligibility = Eligibility(model, contact_specs(4, type="pcwf", mu=0.2))
    options = PlacementOptions(bound=False, starts=1, extra_starts=0, neighbour_moves=0)
    asked = dataclasses.replace(options, exchange_solver="slp")
    placer = Placer(eligibility, asked)
    fast = placer([14, 10, 55, 47])
    assert fast.exchange_solver == "slp" and fast.to_dict()["exchange_solver"] == "slp"
    assert not any(isinstance(p, ExchangeProblem) for p in placer._problems.values())
    assert fast.rho <= fast.start_rho and fast.rounds > 0
    general = Placer(eligibility, options)
    slow = general([14, 10, 55, 47])
    assert slow.exchange_solver == "mixed" and slow.rho <= slow.start_rho
    soft = Eligibility(model, contact_specs(4, type="sfce", mu=0.2, model=model))
    assert Placer(soft, asked).exchange_solver() == "slp"
    frictionless = Eligibility(model, contact_specs(7, type="sfce", mu=0.0, mu_s=0.0))
    assert Placer(frictionless, options).exchange_solver() == "highs"


def _placed_with_problem_kinds(placer, elements):
    """The placement of ``elements`` and the class of every restricted problem it built."""
    used = []
    build = placer._problem

    def recorded(rows, count, *args):
        problem = build(rows, count, *args)
        used.append(type(problem))
        return problem

    placer._problem = recorded
    return placer(elements), used


def test_sequential_lp_then_ipopt_ends_on_ipopt_rounds():
    """``exchange_solver="slp-ipopt"``: the run's rounds are the sequential LP's until one of
    them does not pay off, IPOPT's from then on, so the run ends where IPOPT's rounds end it;
    the placement never ends worse than its start."""
    model = load_model(MODELS / "lamp.model.json")
    eligibility = Eligibility(model, contact_specs(4, type="pcwf", mu=0.2))
    options = PlacementOptions(
        bound=False, starts=1, extra_starts=0, neighbour_moves=0, exchange_solver="slp-ipopt"
    )
    result, used = _placed_with_problem_kinds(Placer(eligibility, options), [14, 10, 55, 47])
    assert result.exchange_solver == "slp-ipopt" and result.rho <= result.start_rho
    switch = used.index(ExchangeProblem)
    assert switch > 0 and set(used[:switch]) == {ExchangeSLP}
    assert set(used[switch:]) == {ExchangeProblem}


def _model_problem(placer, elements, frames, rng, U):
    """Random start weights on ``elements`` (padded) and the contacts there."""
    model = placer.eligibility.model
    rows = tuple(len(f.G) for f in frames)
    weights = [rng.dirichlet(np.ones(len(model.elements[e].vertices))) for e in elements]
    slots = WrenchSlots.from_contacts(placer.contact_set(elements, weights))
    return slots, [np.pad(w, (0, k - len(w))) for w, k in zip(weights, rows)]


@pytest.mark.parametrize("kind", ["pcwf", "sfce"])
def test_model_slp_solves_ipopts_restricted_problem(kind):
    """``ModelSLP`` solves the restricted problem of ``ExchangeProblem`` itself: IPOPT's ``r`` is
    the model's value at IPOPT's weights (the same subsets and friction pieces), and the LP
    steps never lose, from there or from the start weights; they end in the simplices and the
    trust region, with a value met by the true support function there, and on most problems at
    IPOPT's weights. All tolerances relative to the wrench scale (the largest support value)."""
    elements = [14, 10, 55, 47]
    placer, frames, U, rng = _setup("lamp", elements, [kind] * 4, 11)
    rows = tuple(len(f.G) for f in frames)
    f_max = np.ones(4)
    ipopt = ExchangeProblem(rows, 32, 1e-10, 0.01)
    slp = ModelSLP(0.01)
    local = [frame.local(U) for frame in frames]
    same = 0
    for trial in range(6):
        slots, start = _model_problem(placer, elements, frames, rng, U)
        radius = [0.1, 0.3, 1.0, 0.5, 0.2, 0.05][trial]
        scale = np.abs(slots.support(U)).max()
        _, mask, pieces = restricted_model(slots, f_max, U, 0.01)
        before = model_linearisation(local, start, mask, pieces, f_max)[0].min()
        c, value = slp.solve(frames, slots, f_max, U, start, radius)
        assert value >= before - 1e-12 * scale and slp.steps >= 1
        assert value == pytest.approx(
            model_linearisation(local, c, mask, pieces, f_max)[0].min(), abs=1e-12 * scale
        )
        assert _true_values(placer, elements, c, U).min() >= value - 1e-12 * scale
        for ci, si in zip(c, start):
            assert ci.sum() == pytest.approx(1.0) and ci.min() >= 0.0
            assert np.abs(ci - si).max() <= radius + 1e-9
        c_ip, r = ipopt.solve(frames, slots, f_max, U, start, radius)
        c_ip = [np.maximum(ci, 0.0) / np.maximum(ci, 0.0).sum() for ci in c_ip]
        at_ipopt = model_linearisation(local, c_ip, mask, pieces, f_max)[0].min()
        assert at_ipopt == pytest.approx(r, abs=1e-7 * scale)
        again, value_again = slp.solve(frames, slots, f_max, U, c_ip, radius)
        assert value_again >= at_ipopt - 1e-12 * scale
        # the same position (offsets in the element's size), not only the same value: where the
        # optimum is not unique, inside the optimal face as IPOPT's
        moved = max(np.linalg.norm(f.offsets.T @ (a - b)) for f, a, b in zip(frames, c, c_ip))
        same += abs(value - r) <= 1e-7 * scale and moved <= 1e-4
    assert same >= 4  # a different local optimum now and then (4 of 125 on a lamp plan)


@pytest.mark.parametrize("seed", range(3))
def test_model_linearisation_is_the_restricted_model_at_its_point(seed):
    """At the weights the restricted model was chosen at, its value is the sum of the chosen
    contacts' support values (:func:`restricted_model`, the compiled support function), and
    ``A @ c`` is that value: contacts of several vertex counts (the pistol's 24-, 18- and
    4-vertex facets, padded: linearised in groups) of mixed types."""
    elements = [6, 5, 1, 3]
    kinds = [TYPES[i] for i in np.random.default_rng(seed).permutation(4)]
    placer, frames, U, rng = _setup("pistol", elements, kinds, seed)
    local = [frame.local(U) for frame in frames]
    f_max = np.array([spec.f_max for spec in placer.eligibility.specs])
    for _ in range(3):
        slots, start = _model_problem(placer, elements, frames, rng, U)
        P, mask, pieces = restricted_model(slots, f_max, U, 0.01)
        values, A = model_linearisation(local, start, mask, pieces, f_max)
        expected = (mask * P.T).sum(axis=0)
        scale = max(1.0, np.abs(P).max())
        np.testing.assert_allclose(values, expected, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(A @ np.concatenate(start), values, rtol=0, atol=1e-12 * scale)


def test_mixed_solver_gives_exploring_runs_to_the_model_slp():
    """The default with friction (``"mixed"``): the first start's run solves its restricted
    problems by IPOPT, the further starts' runs by the model's sequential LP; without friction
    the linear programme; ``"slp-model"`` asked for: every run by the sequential LP."""
    model = load_model(MODELS / "lamp.model.json")
    eligibility = Eligibility(model, contact_specs(4, type="pcwf", mu=0.2))
    options = PlacementOptions(
        bound=False, starts=2, extra_starts=0, neighbour_moves=0, max_rounds=8
    )
    result, used = _placed_with_problem_kinds(Placer(eligibility, options), [14, 10, 55, 47])
    assert result.exchange_solver == "mixed" and result.rho <= result.start_rho
    switch = used.index(ModelSLP)
    assert switch > 0 and set(used[:switch]) == {ExchangeProblem}
    assert set(used[switch:]) == {ModelSLP}
    only = Placer(eligibility, dataclasses.replace(options, exchange_solver="slp-model"))
    assert only([14, 10, 55, 47]).exchange_solver == "slp-model"
    assert all(isinstance(p, ModelSLP) for p in only._problems.values())
