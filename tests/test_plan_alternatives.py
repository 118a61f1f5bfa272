"""plan() places further eligible element sets when placement fails, and says what it tried.

A placer that declares its first placements failed (a test double around the real one) drives
the fallback on a box, where every placement really is force closure.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import SelectionOptions, _multiset
from tests.shapes import box_model, corner_model

QUICK = PlacementOptions(bound=False, starts=1, extra_starts=0, neighbour_moves=0, certify=False)


class FailingFirst(Placer):
    """The real placer, but its first ``failures`` results are reported as not force closure."""

    def __init__(self, eligibility, failures: int):
        super().__init__(eligibility, QUICK)
        self.failures, self.calls = failures, []

    def __call__(self, elements, weights=None, progress=None, **kwargs):
        result = super().__call__(elements, weights, progress, **kwargs)
        self.calls.append(tuple(elements))
        if len(self.calls) <= self.failures:
            return replace(result, force_closure=False, rho=abs(result.rho) + 1.0)
        return result


@pytest.fixture(scope="module")
def hand():
    return Eligibility(box_model(10.0), contact_specs(4, type="pcwf", mu=0.4), torque_scale=0.1)


@pytest.mark.slow
def test_next_sets_are_placed_until_one_is_force_closure(hand):
    placer, events = FailingFirst(hand, failures=2), []
    result = plan(
        hand, seeds=1, seed=1, placer=placer, alternatives=4, progress=lambda *e: events.append(e)
    )
    assert result.force_closure and result.failure() is None
    assert [e[1:] for e in events if e[0] == "alternative"] == [
        (k, a.rho) for k, a in enumerate(result.attempts[1:], 1)
    ]
    assert len(result.attempts) == 3 == len(placer.calls)
    assert [a.force_closure for a in result.attempts] == [False, False, True]
    assert result.attempts[0].source == "iterative"
    assert result.attempts[0].elements == result.iterative.elements
    assert result.placement.elements == result.attempts[2].elements
    keys = {_multiset(hand, a.elements) for a in result.attempts}
    assert len(keys) == 3  # never the same multiset twice
    assert all(a.rho_hat < 0 for a in result.attempts)  # only eligible sets
    assert [a["source"] for a in result.to_dict()["attempts"]] == [
        a.source for a in result.attempts
    ]


@pytest.mark.slow
def test_budget_and_reason_when_none_works(hand):
    result = plan(hand, seeds=1, seed=1, placer=FailingFirst(hand, failures=10), alternatives=2)
    assert not result.force_closure and len(result.attempts) == 3
    assert "3 element set(s) tried (3 eligible)" in result.failure()
    assert result.placement.rho == min(a.rho for a in result.attempts)
    alone = plan(hand, seeds=1, seed=1, placer=FailingFirst(hand, failures=10), alternatives=0)
    assert len(alone.attempts) == 1
    with pytest.raises(ValueError, match="alternatives"):
        plan(hand, seed=1, alternatives=-1)


def test_no_eligible_set_is_the_reason():
    """The heuristic's restarts already failed: no further runs, the reason says why."""
    hand = Eligibility(corner_model(), contact_specs(7, type="fpc"), torque_scale=1.0)
    result = plan(hand, seeds=1, seed=0, selection=SelectionOptions(restarts=3), placement=QUICK)
    assert not result.force_closure and len(result.attempts) == 1
    assert result.failure().startswith("no eligible element set found")


def test_the_pool_ranks_unranked_sets_by_their_light_value(hand):
    """Screens that stopped once a set could not win leave it without a light value; the plan's
    pool of further sets gives it one (the light search the screen would have run), keeps the
    eligible ones and ranks them with the rest, lowest first."""
    from closure_nlp.criterion.support_minimum import signed_distance
    from closure_nlp.planning.single import _Pool
    from closure_nlp.selection.algorithms import SCREEN_SEARCH, heuristic, iterative

    run = iterative(hand, heuristic(hand, seed=1).elements)
    assert run.unranked_sets
    pool = _Pool(hand)
    pool.add(run)
    pool = list(iter(pool.pop, None))
    assert [v for _, v, _ in pool] == sorted(v for _, v, _ in pool)
    unproven = [(v, tuple(e)) for e, v, proven in pool if not proven]
    assert unproven == sorted(unproven)  # equal values in the order of the elements
    light = hand.minimizer.with_search(SCREEN_SEARCH)
    ranked = {tuple(e): v for e, v, proven in pool if not proven}
    for elements, warm in run.unranked_sets:
        slots = hand.slots(elements)
        value = signed_distance(light(slots, warm), slots, light.tolerances)
        assert ranked.get(tuple(elements)) == (value if value < 0 else None)


@pytest.mark.slow
def test_the_ceiling_is_computed_once_for_the_placement_returned(hand, monkeypatch):
    """With the ceiling on, the sets placed before one holds get the exchange method alone: the
    plan bounds the placement it returns, once, from that placement's start elements."""
    from closure_nlp.placement import ceiling as placement_bound

    calls = []
    real = placement_bound.bounded

    def counting(placer, elements, result, t0, progress=None):
        calls.append((tuple(elements), result.rho))
        return real(placer, elements, result, t0, progress)

    monkeypatch.setattr(placement_bound, "bounded", counting)
    placer = FailingFirst(hand, failures=1)
    placer.options = replace(QUICK, bound=True, bound_cells=1)
    result = plan(hand, seeds=1, seed=1, placer=placer, alternatives=4)
    assert len(result.attempts) == 2 and result.force_closure
    assert calls == [(result.attempts[1].elements, result.placement.rho)]
    assert result.placement.capacity_bound is not None
    assert result.placement.capacity_bound >= -result.placement.bounds[1]  # a ceiling
    assert result.placement.seconds >= result.placement.bound_seconds > 0


def test_sets_no_placement_can_hold_are_not_placed(hand, monkeypatch):
    """Alternatives that lone_contact proves hopeless are skipped (here every set is declared
    so, with a double); selection.placeable off places them as before. (The new selection
    runs, which skip them alike, are left out: they cost most of a plan.)"""
    from closure_nlp.planning import single as planning

    monkeypatch.setattr(planning, "lone_contact", lambda eligibility, elements: 0)
    monkeypatch.setattr(planning, "FRESH_RUNS", 0)  # the iterative run's own sets only
    skipped = plan(hand, seeds=1, seed=1, placer=FailingFirst(hand, failures=10), alternatives=1)
    assert len(skipped.attempts) == 1  # the iterative result alone
    placed = plan(
        hand,
        seed=1,
        seeds=1,
        placer=FailingFirst(hand, failures=10),
        alternatives=1,
        selection=SelectionOptions(placeable=False),
    )
    assert len(placed.attempts) == 2
