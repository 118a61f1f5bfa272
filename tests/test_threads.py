"""rho, Eligibility, load factors and plan called from four threads at once give, bit for bit,
the answers of the same calls made one after another (every solver they share keeps one NLP per
thread, every LP is the calling thread's)."""

from __future__ import annotations

import functools
import threading
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.load_factor import load_factors
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.elements import load_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import SelectionOptions
from tests.shapes import box_model, random_model

QUICK = PlacementOptions(starts=1, extra_starts=0, neighbour_moves=0, max_rounds=5)
BLOCK = Path(__file__).resolve().parents[1] / "examples" / "block"


def without_time(value):
    """A result's dict with every timing removed (the one part that differs between runs)."""
    if isinstance(value, dict):
        return {k: without_time(v) for k, v in value.items() if k not in ("seconds", "timing")}
    if isinstance(value, (list, tuple)):
        return [without_time(v) for v in value]
    return value


def jobs(with_plan: bool):
    """Four lists of calls, each thread's: rho of contact sets (one default minimizer for all,
    and one shared minimizer of a wider bracket), rho_hat of element sets (one Eligibility for
    all) and, with ``with_plan``, a plan."""
    contact_sets = [
        random_contact_set(np.random.default_rng(seed), types)
        for seed in range(4)
        for types in (["pcwf"] * 4, ["sfce"] * 3, ["fpc"] * 7, ["fpc", "pcwf", "sfcl", "sfce"])
    ]
    model = random_model(np.random.default_rng(5), ["facet"] * 4 + ["segment"] * 2 + ["point"])
    shared = Eligibility(model, contact_specs(3, type="pcwf", mu=0.5))
    sets = [(0, 1, 2), (3, 4, 5), (0, 4, 6), (1, 2, 5), (2, 3, 6), (0, 5, 6), (1, 3, 4), (2, 4, 5)]
    box = Eligibility(box_model(10.0), contact_specs(4, type="pcwf", mu=0.4), torque_scale=0.1)

    def a_plan():
        return plan(box, seeds=1, seed=3, selection=SelectionOptions(), placement=QUICK)

    # the block's fixture: 3 locators in place, cutting loads
    block = load_model(BLOCK / "block.model.json")
    clamps = Eligibility(
        block, contact_specs(4, type="pcwf", mu=0.3), fixed=BLOCK / "base.contacts.json"
    )
    loads = BLOCK / "loads.json"
    on_block = functools.partial(
        load_factors, reference_point=block.reference_point, torque_scale=clamps.torque_scale
    )
    sides = [(33, 67, 66, 0), (33, 67, 0, 0), (67, 33, 66, 66), (0, 66, 33, 67)]
    calls = [
        [lambda c=c: rho(c) for c in contact_sets[4 * k : 4 * k + 4]]  # the same shapes at once
        + [lambda c=c: rho(c, tol=1e-3) for c in contact_sets[4 * k : 4 * k + 4]]
        + [lambda e=e: shared(e) for e in sets[k::4]]
        + [lambda c=c: load_factors(c, loads) for c in contact_sets[4 * k : 4 * k + 4]]
        + [lambda e=sides[k]: clamps(e), lambda e=sides[k]: on_block(clamps.slots(e), loads)]
        for k in range(4)
    ]
    if with_plan:
        calls[0].append(a_plan)
    return calls


def four_threads_against_serial(with_plan: bool) -> list:
    serial = [[without_time(call().to_dict()) for call in calls] for calls in jobs(with_plan)]
    work = jobs(with_plan)  # fresh objects: the threads build their own solvers from nothing
    answers: list = [None] * len(work)
    barrier = threading.Barrier(len(work))

    def run(k):
        barrier.wait()
        answers[k] = [without_time(call().to_dict()) for call in work[k]]

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(work))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert answers == serial
    return serial


def test_rho_and_eligibility_in_four_threads_give_the_serial_answers_bit_for_bit():
    four_threads_against_serial(with_plan=False)


@pytest.mark.slow
def test_a_plan_beside_three_threads_gives_the_serial_answers_bit_for_bit():
    serial = four_threads_against_serial(with_plan=True)
    assert serial[0][-1]["placement"]["force_closure"]  # the plan did place contacts
