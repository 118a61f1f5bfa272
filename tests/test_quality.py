"""rho(0, W_c^M): analytic cases, the global minimum against an independent reference, bad input."""

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet, contact_set_from_dict
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.support_minimum import rho
from tests import reference


def one(kind, position=(0, 0, 0), normal=(0, 0, 1), **kw):
    return Contact(list(position), list(normal), kind, **kw)


# --- analytic cases --------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["fpc", "pcwf", "sfcl", "sfce"])
def test_single_contact_at_origin_is_at_distance_f_max(kind):
    # W_1 is centred on (n f_max, 0): its hull contains that point, the nearest to the origin.
    result = rho(ContactSet((one(kind, f_max=2.5),)))
    assert result.rho == pytest.approx(2.5, abs=1e-8)
    assert not result.force_closure
    np.testing.assert_allclose(result.direction, [0, 0, -1, 0, 0, 0], atol=1e-6)


def test_single_fpc_off_origin_distance_by_hand():
    # wrench (n, r x n) = (0, 0, 1, 0, -1, 0): distance sqrt(2)
    result = rho(ContactSet((one("fpc", position=(1, 0, 0)),)))
    assert result.rho == pytest.approx(np.sqrt(2), abs=1e-8)


def test_two_fpc_same_normal_distance_is_the_nearer_wrench():
    # W^M = {w, w, 2w} with w = (0,0,1,0,0,0): hull is the segment [w, 2w]
    result = rho(ContactSet((one("fpc"), one("fpc"))))
    assert result.rho == pytest.approx(1.0, abs=1e-8)


@pytest.mark.parametrize("kind", ["pcwf", "fpc"])
def test_two_opposite_contacts_have_no_interior(kind):
    cs = ContactSet((one(kind, (0, 0, 1), (0, 0, -1)), one(kind, (0, 0, -1), (0, 0, 1))))
    result = rho(cs)
    assert result.rho == 0.0
    assert not result.force_closure


@pytest.mark.parametrize("kind", ["sfce", "sfcl"])
def test_two_opposite_soft_fingers_hold(kind):
    # Paper section 3.2: m SFCs have an interior when n_i . (r_1 - r_2) != 0; with the spin
    # moment two opposite soft fingers are force closure, unlike two point contacts.
    cs = ContactSet((one(kind, (0, 0, 1), (0, 0, -1)), one(kind, (0, 0, -1), (0, 0, 1))))
    assert rho(cs).force_closure


def test_box_held_by_seven_fpcs_is_force_closure():
    data = {
        "torque_scale": 0.1,
        "defaults": {"type": "fpc"},
        "contacts": [
            {"position": p, "inward_normal": n}
            for p, n in [
                ([2, 2, 0], [0, 0, 1]),
                ([8, 2, 0], [0, 0, 1]),
                ([5, 8, 0], [0, 0, 1]),
                ([5, 5, 6], [0, 0, -1]),
                ([0, 3, 3], [1, 0, 0]),
                ([10, 7, 3], [-1, 0, 0]),
                ([3, 0, 3], [0, 1, 0]),
                ([7, 10, 3], [0, -1, 0]),
            ]
        ],
    }
    eight = contact_set_from_dict(data)
    assert rho(eight).force_closure
    # Without the top clamp nothing pushes down: not force closure, rho >= 0.
    data["contacts"].pop(3)
    assert rho(contact_set_from_dict(data)).rho >= 0


def test_reported_rho_is_the_support_function_at_the_direction():
    cs = random_contact_set(np.random.default_rng(2), ["pcwf"] * 4)
    result = rho(cs)
    assert np.linalg.norm(result.direction) == pytest.approx(1.0, abs=1e-12)
    assert result.direction @ result.support_point == pytest.approx(-result.rho, abs=1e-12)
    ref = reference.support(result.direction, reference.from_contact_set(cs))
    assert -result.rho == pytest.approx(ref, abs=1e-12)


# --- the global minimum, against the independent reference -----------------------------------

TYPES = ["fpc", "pcwf", "sfcl", "sfce"]
CASES = [(kind, m, seed) for kind in TYPES + ["mixed"] for m in range(2, 8) for seed in (0, 1)]


def make(kind, m, seed):
    rng = np.random.default_rng(1000 * m + seed + 17 * len(kind))
    types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    return random_contact_set(rng, types, mu=0.5, mu_s=0.3, tilt=0.25)


@pytest.mark.slow
@pytest.mark.parametrize("kind,m,seed", CASES)
def test_rho_agrees_with_reference(kind, m, seed):
    cs = make(kind, m, seed)
    ref_value, _ = reference.reference_min(reference.from_contact_set(cs), samples=800, starts=6)
    got = rho(cs)
    tol = 1e-6 * max(1.0, abs(ref_value))
    # -rho is the support function, by the paper's formulas, at the unit direction we return ...
    assert reference.support(got.direction, reference.from_contact_set(cs)) == pytest.approx(
        -got.rho, abs=1e-12 if got.rho else 1e-8
    )
    # ... so it bounds the minimum from above; the reference's minimum must not be lower.
    assert -got.rho <= ref_value + tol


def test_reference_suite_covers_both_signs():
    signs = [rho(make(*c)).force_closure for c in CASES]
    assert 0.2 < np.mean(signs) < 0.8


def test_finds_the_global_minimum_of_a_narrow_basin():
    """A 5-SFCe grasp with a narrow global basin. One IPOPT start with IPOPT's default barrier
    used to end 1e-3 above it; since the search runs on the set scaled to unit size, that weaker
    search no longer misses here (nor on 23 other seeded 5-contact sets), so only the answer is
    checked: the certified rho equals the independent reference's minimum."""
    cs = make("sfce", 5, 1)
    ref_value, _ = reference.reference_min(reference.from_contact_set(cs), samples=2000, starts=10)
    result = rho(cs)
    assert -result.rho == pytest.approx(ref_value, abs=1e-6)
    assert -ref_value <= result.bounds[1] + 1e-9  # any direction bounds rho from below


# --- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"position": [0, 0, np.nan]}, "position"),
        ({"position": [0, 0, np.inf]}, "position"),
        ({"position": [0, 0]}, "position"),
        ({"inward_normal": [0, 0, 0]}, "inward_normal"),
        ({"type": "magnet"}, "type"),
        ({"mu": -0.1}, "mu"),
        ({"mu_s": -1}, "mu_s"),
        ({"f_max": -1}, "f_max"),
        ({"f_max": 0}, "f_max"),
    ],
)
def test_bad_contact_raises_value_error_naming_field(kwargs, match):
    args = {"position": [0, 0, 0], "inward_normal": [0, 0, 1], **kwargs}
    with pytest.raises(ValueError, match=match):
        Contact(**args)


def test_bad_types_raise_type_error():
    with pytest.raises(TypeError, match="position"):
        Contact("abc", [0, 0, 1])
    with pytest.raises(TypeError, match="mu"):
        Contact([0, 0, 0], [0, 0, 1], mu="0.2")
    with pytest.raises(TypeError, match="contact_set"):
        rho([Contact([0, 0, 0], [0, 0, 1])])


@pytest.mark.parametrize("scale", [0, -1, np.nan])
def test_bad_torque_scale(scale):
    with pytest.raises(ValueError, match="torque_scale"):
        ContactSet((one("fpc"),), scale)


def test_empty_contact_set():
    with pytest.raises(ValueError, match="contacts"):
        ContactSet(())


@pytest.mark.parametrize(
    "data,match",
    [
        ({}, "contacts"),
        ({"contacts": []}, "contacts"),
        ({"contacts": [{"position": [0, 0, 0]}]}, "inward_normal"),
        ({"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1], "muu": 1}]}, "muu"),
        (
            {
                "contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1]}],
                "defaults": {"mu": -1},
            },
            r"contacts\[0\]\.mu",
        ),
        ({"contacts": "none"}, "contacts"),
    ],
)
def test_bad_file_content(data, match):
    with pytest.raises((ValueError, TypeError), match=match):
        contact_set_from_dict(data)


def test_defaults_and_overrides():
    cs = contact_set_from_dict(
        {
            "defaults": {"type": "sfce", "mu": 0.3},
            "contacts": [
                {"position": [0, 0, 1], "inward_normal": [0, 0, -2]},
                {"position": [0, 0, -1], "inward_normal": [0, 0, 1], "type": "fpc", "mu_s": 0.1},
            ],
        }
    )
    a, b = cs.contacts
    assert (a.type.value, a.mu, a.mu_s, b.type.value, b.mu, b.mu_s) == (
        "sfce",
        0.3,
        0.2,
        "fpc",
        0.3,
        0.1,
    )
    np.testing.assert_allclose(a.inward_normal, [0, 0, -1])


def test_nlp_cache_keeps_the_most_recent_shapes(monkeypatch):
    """Shapes beyond MAX_PROBLEMS evict the least recently used one; answers do not change."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion import support_minimum as quality

    monkeypatch.setattr(quality, "MAX_PROBLEMS", 2)
    minimizer = quality.SupportMinimizer(solver="ipopt")  # the NLPs are IPOPT's
    sets = [
        WrenchSlots.from_contacts(random_contact_set(np.random.default_rng(m), ["pcwf"] * m))
        for m in (3, 4, 5)
    ]
    first = minimizer(sets[0]).value
    minimizer(sets[1])
    minimizer(sets[0])  # used again: now the most recent
    minimizer(sets[2])  # evicts the 4-contact shape
    keys = [quality.SupportMinProblem.key(s) for s in sets]
    assert list(minimizer._problems) == [keys[0], keys[2]]
    assert minimizer(sets[0]).value == first


def test_several_warm_starts_and_errors_that_name_the_row():
    from closure_nlp.criterion.support_minimum import _warm_starts, search_rho

    starts = _warm_starts([[3, 0, 0, 0, 0, 4], [0, 0, 0, 0, 0, 1e-200]])  # tiny: no underflow
    np.testing.assert_allclose(starts, [[0.6, 0, 0, 0, 0, 0.8], [0, 0, 0, 0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(_warm_starts([0, 2, 0, 0, 0, 0]), [[0, 1, 0, 0, 0, 0]])
    pair = (Contact([0, 0, 1], [0, 0, -1], "sfce"), Contact([0, 0, -1], [0, 0, 1], "sfce"))
    cs = ContactSet(pair)
    for bad, field in (
        ([[1, 0, 0, 0, 0, 0], [1, 0]], r"warm_start\[1\]: expected 6 numbers"),  # ragged rows
        ([[1, 0, 0, 0, 0, 0], [0] * 6], r"warm_start\[1\]: zero vector"),
        ([0] * 6, r"warm_start: zero vector"),
    ):
        with pytest.raises(ValueError, match=field):
            search_rho(cs, warm_start=bad)


def test_a_search_asked_for_a_threshold_stops_once_it_is_shown():
    """``stop_below``: the caller asks only whether min p <= bar. Above the minimum the search
    returns before IPOPT with a true support value at or below the bar (in any units); below the
    minimum it is the full search, unchanged."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.support_minimum import SupportMinimizer

    minimizer = SupportMinimizer(solver="ipopt")
    for seed, kinds in ((3, ["pcwf"] * 4), (4, ["sfce", "sfcl", "pcwf"])):
        cs = random_contact_set(np.random.default_rng(seed), kinds, mu=0.5, mu_s=0.3)
        for scale in (1.0, 1e3):  # the bar is in the set's units, like the values
            slots = WrenchSlots.from_contacts(cs).scaled(scale)
            full = minimizer(slots)
            assert full.stats.ipopt_runs >= 1
            bar = full.value + 0.2 * scale
            early = minimizer(slots, stop_below=bar)
            assert early.value <= bar and early.stats.ipopt_runs == 0
            assert early.value == pytest.approx(slots.support(early.direction)[0], rel=1e-12)
            below = minimizer(slots, stop_below=full.value - 0.2 * scale)
            assert below.value == full.value
            np.testing.assert_array_equal(below.direction, full.direction)


def test_a_run_into_a_minimum_already_found_does_not_use_up_the_budget():
    """Seven PCwF on the L-bracket where a placement's round search (two IPOPT runs) reported
    rho -1.4014: both runs started in the warm directions' basins and ended in one local
    minimum, and the global basin's start, whose descent ended higher, got no run. A run that
    finds no new minimum no longer counts against the budget: the search reaches the certified
    rho. With each run counted (runs_per_basin = 1) it misses."""
    import dataclasses
    import json
    from pathlib import Path

    from closure_nlp.criterion import support_minimum as quality
    from closure_nlp.placement.placer import ROUND_SEARCH

    data = json.loads((Path(__file__).parent / "data" / "l_bracket_round_miss.json").read_text())
    contact_set = contact_set_from_dict(data["contact_set"])
    judge = quality.SupportMinimizer(search=ROUND_SEARCH, solver="ipopt")
    lo, hi = rho(contact_set).bounds
    found = quality.search_rho(contact_set, minimizer=judge, warm_start=data["warm_start"])
    assert lo - 1e-6 * abs(lo) <= found.rho <= hi  # the global minimum, to the bracket
    every_run = judge.with_search(dataclasses.replace(ROUND_SEARCH, runs_per_basin=1))
    missed = quality.search_rho(contact_set, minimizer=every_run, warm_start=data["warm_start"])
    assert missed.rho < lo - 0.05  # that rule's answer: 8% over-stated


@pytest.mark.parametrize("kinds", [["pcwf", "fpc", "sfcl"], ["sfce", "pcwf"]])
def test_support_min_nlp_constraints_are_the_slots_epigraph(kinds):
    """The support-minimum NLP's constraints at a random point against numpy from the slots:
    per vertex row ``s_r**2 - q(d_r)`` for each piece, then ``P_i - f_r (d_r0 + s_r)``, the
    ``z`` and ``t`` rows, the sum and ``|u|**2``. Every row has its own force bound and
    friction weights, so a row reading another row's parameters is seen; padded slots repeat
    their last row."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.support_minimum import SupportMinProblem

    rng = np.random.default_rng(7)
    counts = [3, 1, 5][: len(kinds)]  # vertex rows per slot: 3 and 5 are padded
    slots = WrenchSlots.build(
        (rng.standard_normal((k, 6, 4)), kind, 0.3, 0.2, 1.0) for k, kind in zip(counts, kinds)
    )
    slots.f_max[:] = rng.uniform(0.5, 2.0, len(slots.f_max))
    slots.pieces[:] *= rng.uniform(0.5, 2.0, (len(slots.pieces), 1, 1))
    problem = SupportMinProblem(*SupportMinProblem.key(slots))
    m, n_s, n_P = len(counts), problem._n_s, problem._n_P
    x = rng.standard_normal(6 + n_s + n_P + m + 2)
    g = problem._solver.get_function("nlp_g")(x, problem.parameters(slots))
    u, s, P = x[:6], iter(x[6 : 6 + n_s]), iter(x[6 + n_s : 6 + n_s + n_P])
    z, (t, total) = x[6 + n_s + n_P : -2], x[-2:]
    expected, rows, at = [], problem._rows(slots), 0
    for i, (pieces, size) in enumerate(zip(problem.n_pieces, problem.rows_per_slot)):
        values = []
        for r in rows[at : at + size]:
            d = slots.G[r].T @ u
            if pieces:
                s_r = next(s)
                expected += [s_r**2 - np.sum(w * d**2) for w in slots.pieces[r, :pieces]]
                values.append(slots.f_max[r] * (d[0] + s_r))
            else:
                values.append(slots.f_max[r] * d[0])
        at += size
        P_i = values[0] if size == 1 else next(P)
        if size > 1:
            expected += [P_i - v for v in values]
        expected += [z[i] - P_i, t - P_i - (total - z[i])]
    expected += [total - z.sum(), u @ u]
    assert (n_s, n_P) == (
        sum(problem.rows_per_slot[i] for i in range(m) if problem.n_pieces[i]),
        sum(k > 1 for k in problem.rows_per_slot),
    )
    np.testing.assert_allclose(np.asarray(g).ravel(), expected, rtol=1e-12, atol=1e-12)


def test_support_min_nlp_built_without_the_parameters_gradient_takes_the_same_iterates(
    monkeypatch,
):
    """Built without CasADi's gradient for the parameters' multipliers (``NLPSOL_OPTIONS``),
    the support-minimum NLP takes the same iterations to the same direction, to the bit."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion import support_minimum as quality

    cs = random_contact_set(np.random.default_rng(3), ["pcwf", "sfce", "sfcl", "fpc"], mu=0.4)
    slots = WrenchSlots.from_contacts(cs)
    key = quality.SupportMinProblem.key(slots)
    lean = quality.SupportMinProblem(*key)
    lean_only = ("calc_lam_p", "no_nlp_grad")
    full_options = {k: v for k, v in quality.NLPSOL_OPTIONS.items() if k not in lean_only}
    monkeypatch.setattr(quality, "NLPSOL_OPTIONS", full_options)
    full = quality.SupportMinProblem(*key)
    assert full._solver.has_function("nlp_grad") and not lean._solver.has_function("nlp_grad")
    for u0 in np.random.default_rng(4).standard_normal((3, 6)):
        u0 /= np.linalg.norm(u0)
        (u, iterations, status, _), (u_full, iterations_full, status_full, _) = (
            problem.solve(slots, u0) for problem in (lean, full)
        )
        np.testing.assert_array_equal(u, u_full)
        assert (iterations, status) == (iterations_full, status_full) and iterations > 0


@pytest.mark.parametrize("solver", ["ipopt", "compiled"])
@pytest.mark.parametrize("kinds", [["pcwf"] * 3, ["fpc"] * 5, ["sfce", "sfcl"], ["sfcl", "pcwf"]])
def test_outside_the_set_one_ipopt_run_finds_the_distance(kinds, solver):
    """With the origin outside W, a local minimum with p < 0 is the global one (-p is concave
    and positive there): the search stops after its first such run, and its value is the
    distance that cvxpy computes on its own, in any units, to the search's accuracy: about 1e-6
    of the wrench scale (s**2 >= q within IPOPT's 1e-12 leaves s short by up to 1e-6 at a cone's
    apex; all six runs of that rule agreed with the first to that accuracy)."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.certificate import tolerance_unit
    from closure_nlp.criterion.crosscheck import distance_cvxpy
    from closure_nlp.criterion.support_minimum import SupportMinimizer

    minimizer = SupportMinimizer(solver=solver)
    checked = 0
    for seed in range(6):
        cs = random_contact_set(np.random.default_rng(seed), kinds, mu=0.4, mu_s=0.2)
        for scale in (1.0, 1e3):
            slots = WrenchSlots.from_contacts(cs).scaled(scale)
            found = minimizer(slots)
            if found.value >= 0:
                continue  # force closure: not this test's regime
            distance = distance_cvxpy(slots)
            assert -found.value == pytest.approx(distance, abs=2e-6 * tolerance_unit(slots))
            assert found.stats.ipopt_runs == (1 if solver == "ipopt" else 0)
            checked += 1
    assert checked >= 4


def test_a_search_alone_ends_with_one_ipopt_run_from_the_compiled_runs_best():
    """solver="auto": the compiled minimiser from every start, then one IPOPT run from the best
    direction (``ipopt_polish``), whose lower value is kept; without the polish the compiled
    runs alone, and no IPOPT run at all."""
    import dataclasses

    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.support_minimum import SearchOptions, SupportMinimizer

    polished = SupportMinimizer(search=SearchOptions(ipopt_starts=2))
    alone = polished.with_search(SearchOptions(ipopt_starts=2, ipopt_polish=False))
    held = 0
    for seed in range(4):
        cs = random_contact_set(np.random.default_rng(seed), ["pcwf"] * 4, mu=0.5)
        slots = WrenchSlots.from_contacts(cs)
        a, b = polished(slots), alone(slots)
        assert a.stats.ipopt_runs == 1 and b.stats.ipopt_runs == 0
        assert b.stats.solver in ("local", "descent")
        assert a.value <= b.value  # the polish keeps the lower value: the same starts and runs
        ref = reference.support(a.direction, reference.from_contact_set(cs))
        assert a.value == pytest.approx(ref, abs=1e-12 * max(1.0, abs(ref)))
        held += a.value > 0
    assert held >= 1  # force closure among them: the regime where the polish matters
    with pytest.raises((TypeError, ValueError), match="ipopt_polish"):
        dataclasses.replace(SearchOptions(), ipopt_polish="yes")
