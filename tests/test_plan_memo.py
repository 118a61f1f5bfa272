"""plan(memo=...) takes the iterative run and the placement of a set an earlier plan met from the
memo, and they are what computing them again gives (both steps are deterministic)."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning import single as planning
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import SelectionOptions
from tests.shapes import box_model

QUICK = PlacementOptions(bound=False, starts=1, extra_starts=0, neighbour_moves=0)


def hand() -> Eligibility:
    return Eligibility(box_model(10.0), contact_specs(4, type="pcwf", mu=0.4), torque_scale=0.1)


class CountingPlacer(Placer):
    def __init__(self, eligibility, options):
        super().__init__(eligibility, options)
        self.calls = []

    def __call__(self, elements, weights=None, progress=None, **kwargs):
        self.calls.append(tuple(elements))
        return super().__call__(elements, weights, progress, **kwargs)


@pytest.mark.slow
def test_a_plan_that_meets_a_known_set_reuses_its_steps(monkeypatch):
    iterative_runs = []
    real_iterative = planning.iterative

    def counting_iterative(eligibility, start, **kwargs):
        iterative_runs.append(tuple(start))
        return real_iterative(eligibility, start, **kwargs)

    monkeypatch.setattr(planning, "iterative", counting_iterative)
    eligibility, memo = hand(), {}
    placer = CountingPlacer(eligibility, QUICK)
    first = plan(eligibility, start=[0, 1], placer=placer, memo=memo)
    again = plan(eligibility, start=[0, 1], placer=placer, memo=memo)
    assert first.reused == () and again.reused == ("heuristic", "iterative", "placement")
    assert again.to_dict()["reused"] == ["heuristic", "iterative", "placement"]
    assert len(iterative_runs) == 1 and len(placer.calls) == 1
    assert again.iterative is first.iterative and again.placement is first.placement

    # Other selection options are other work: nothing is reused.
    other = SelectionOptions(restarts=7)
    plan(eligibility, start=[0, 1], placer=placer, memo=memo, selection=other)
    assert len(iterative_runs) == 2

    # The premise: computed again from nothing (new solvers), the same results; the memo holds
    # the first eligibility's results only, so a new one (even of the same part) reuses nothing.
    fresh = plan(hand(), start=[0, 1], placement=QUICK, memo=memo)
    assert fresh.reused == ()
    assert fresh.iterative.elements == again.iterative.elements
    assert fresh.placement.elements == again.placement.elements
    scale = max(1.0, abs(fresh.placement.rho))
    assert abs(fresh.placement.rho - again.placement.rho) <= 1e-9 * scale
    for a, b in zip(fresh.placement.contacts, again.placement.contacts):
        np.testing.assert_allclose(a.position, b.position, rtol=0, atol=1e-9 * 10.0)
    assert fresh.placement.bounds == pytest.approx(again.placement.bounds, abs=1e-9 * scale)


def test_memo_must_be_a_dict():
    with pytest.raises(TypeError, match="memo"):
        plan(hand(), memo=[])
