"""Heuristic and iterative element selection, through the API and the CLI."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from closure_nlp.cli import main as cli
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import Element, Model, load_model, save_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.selection.algorithms import SelectionOptions, heuristic, iterative, run_selection
from tests.shapes import corner_model


def _ring_model(count: int = 12) -> Model:
    """Square facets around a 12-gon prism's side, plus its two caps: a ring of neighbours."""
    angles = 2 * np.pi * np.arange(count) / count
    rim = np.column_stack([np.cos(angles), np.sin(angles)])
    elements, adjacency = [], []
    for k in range(count):
        a, b = rim[k], rim[(k + 1) % count]
        quad = [[*a, -0.5], [*b, -0.5], [*b, 0.5], [*a, 0.5]]
        mid = (a + b) / 2
        elements.append(Element("facet", quad, [-mid[0], -mid[1], 0.0]))
        adjacency += [(k, (k + 1) % count), (k, count), (k, count + 1)]
    elements.append(Element("facet", [[*p, -0.5] for p in rim], [0, 0, 1]))
    elements.append(Element("facet", [[*p, 0.5] for p in rim[::-1]], [0, 0, -1]))
    return Model(tuple(elements), tuple(adjacency), "ring")


@pytest.fixture(scope="module")
def ring():
    model = _ring_model()
    return Eligibility(model, contact_specs(3, type="pcwf", mu=0.3), torque_scale=1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_heuristic_finds_eligible_sets(ring, seed):
    result = heuristic(ring, seed=seed)
    assert result.eligible and result.rho_hat < 0
    assert len(result.elements) == 3
    assert result.rho_hat == pytest.approx(ring(result.elements).rho_hat, abs=1e-7)
    assert [k for k, _ in result.history] == list(range(len(result.history)))


def test_heuristic_certifies_each_complete_set_once_and_steers_partial_ones(monkeypatch):
    """A complete set goes straight to the certified path (light seed search, then the
    certificate) instead of a full search followed by a certificate: each such set is
    evaluated once, certified, and the verdict that ends the rounds is the certified one.
    Partial sets (not yet m elements) are searched alone, without a certificate."""
    eligibility = Eligibility(
        _ring_model(), contact_specs(3, type="pcwf", mu=0.3), torque_scale=1.0
    )
    calls, original = [], Eligibility.__call__

    def spy(self, elements, *args, **kwargs):
        result = original(self, elements, *args, **kwargs)
        calls.append((len(elements), result.bounds is not None))
        return result

    monkeypatch.setattr(Eligibility, "__call__", spy)
    for seed in range(3):
        calls.clear()
        result = heuristic(eligibility, seed=seed, options=SelectionOptions(initial=1))
        assert result.eligible and result.bounds[1] < 0
        complete = [certified for size, certified in calls if size == 3]
        assert complete and all(complete)  # certified when evaluated, not searched first
        assert not any(certified for size, certified in calls if size < 3)


@pytest.mark.slow  # 162 s: the fast suite stays near 10 minutes
def test_iterative_ends_in_a_local_minimum(ring):
    """No single swap of a contact's element for a neighbour lowers rho_hat (brute force)."""
    start = [0, 1, 2]  # three neighbouring side facets: a poor start
    result = iterative(ring, start)
    assert result.rho_hat <= ring(start).rho_hat
    # The search's steps never go up; the last entry is the certified value of the final set,
    # which can only be weaker than the search's own (a certificate finds lower support values).
    values = [v for _, v in result.history]
    assert all(b <= a for a, b in zip(values[:-1], values[1:-1]))
    assert result.history[-1][1] == result.rho_hat
    lo, hi = result.bounds
    assert lo <= result.rho_hat <= hi  # (a ring: its weakest directions may form a continuum)
    model = ring.model
    for i, e in enumerate(result.elements):
        for n in model.neighbours(e):
            trial = list(result.elements)
            trial[i] = n
            assert ring(trial).rho_hat >= result.rho_hat - 1e-6, (i, n)


def test_iterative_improves_a_bad_start_and_counts_its_work(ring):
    first = ring([0, 1, 12])
    result = iterative(ring, [0, 1, 12])
    assert result.rho_hat < first.rho_hat - 1e-3
    assert result.eligible
    assert result.evaluations + result.screened >= 1 + len(result.history) - 1
    assert result.to_dict()["screened"] == result.screened
    assert result.seconds > 0
    # Sets only screened are offered as candidates: never a fully evaluated one, lowest light
    # value first, and each light value no higher than the set's full rho_hat. From this start
    # every screen that could not win stopped early (no candidate), so a second start, whose
    # run leaves one, checks them too.
    evaluated = {tuple(sorted(e)) for e, _ in result.eligible_sets}
    other = iterative(ring, [0, 4, 13])
    assert other.candidate_sets, "the ring's neighbours include screened eligible sets"
    for run in (result, other):
        done = {tuple(sorted(e)) for e, _ in run.eligible_sets}
        values = [v for _, v in run.candidate_sets]
        assert values == sorted(values) and all(v < 0 for v in values)
        for elements, value in run.candidate_sets:
            assert tuple(sorted(elements)) not in done
            assert value <= ring(elements, certify=False).rho_hat + 1e-9 * max(1.0, abs(value))
    # Sets whose screen stopped once it showed they could not win: neither evaluated nor ranked,
    # and indeed no better than the result (up to the search's own accuracy)
    candidates = {tuple(sorted(e)) for e, _ in result.candidate_sets}
    assert result.unranked_sets, "the ring's screens stop early"
    for elements, _ in result.unranked_sets:
        key = tuple(sorted(elements))
        assert key not in evaluated and key not in candidates
        assert ring(elements, certify=False).rho_hat >= result.history[-2][1] - 1e-6


def test_run_selection_chains_heuristic_then_iterative(ring):
    first = heuristic(ring, seed=4)
    both = run_selection(ring, "iterative", seed=4)
    assert both.rho_hat <= first.rho_hat + 1e-9
    assert both.evaluations > first.evaluations
    with pytest.raises(ValueError, match="algorithm"):
        run_selection(ring, "greedy")


def test_heuristic_restarts_and_reports_failure():
    """No contacts on three facets around a corner are eligible: every round fails, the best
    set comes back not eligible."""
    eligibility = Eligibility(corner_model(), contact_specs(7, type="fpc"), torque_scale=1.0)
    result = heuristic(eligibility, seed=0, options=SelectionOptions(restarts=3))
    assert not result.eligible and result.rounds == 3
    assert result.rho_hat >= 0


def test_given_start_is_used(ring):
    result = heuristic(ring, start=[5])
    assert result.elements[0] == 5
    with pytest.raises(ValueError, match=r"start\[0\]: element id 99"):
        heuristic(ring, start=[99])
    with pytest.raises(ValueError, match="initial"):
        heuristic(ring, options=SelectionOptions(initial=3))
    with pytest.raises(ValueError, match="restarts"):
        SelectionOptions(restarts=0)


def test_progress_callback_sees_every_step(ring):
    seen = []
    result = iterative(ring, [0, 4, 8], progress=lambda *a: seen.append(a))
    assert [s for _, s, _ in seen] == [k for k, _ in result.history[1:]]
    assert all(name == "iterative" for name, _, _ in seen)


# --- CLI -------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ring_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("ring") / "ring.model.json"
    save_model(_ring_model(), path)
    return str(path)


def _run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_eligibility_and_select(capsys, ring_file):
    code, out, _ = _run(capsys, "eligibility", ring_file, "--elements", "0,4,8", "--json")
    data = json.loads(out)
    assert code == 0 and data["eligible"] and data["elements"] == [0, 4, 8]
    assert set(data) >= {"rho_hat", "eligible", "direction"}
    code, out, _ = _run(
        capsys, "select", ring_file, "--contacts", "3", "--algorithm", "iterative", "--json"
    )
    data = json.loads(out)
    assert code == 0 and data["eligible"]
    assert set(data) >= {"elements", "rho_hat", "eligible", "history", "seconds"}
    assert data["history"][0]["iteration"] == 0
    code, out, _ = _run(
        capsys, "select", ring_file, "--contacts", "3", "--type", "sfce,sfce,pcwf", "--quiet"
    )
    assert code == 0 and "rho_hat" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--elements", "0,x"], "--elements: expected comma-separated element ids"),
        (["--elements", "0,99"], r"--elements\[1\]: element id 99 out of range"),
        (["--elements", "0,1", "--mu", "-1"], r"contacts\[0\]\.mu: must be >= 0"),
        (["--elements", "0,1", "--type", "glue"], "unknown contact type 'glue'"),
        (["--elements", "0,1", "--mu", "0.1,0.2,0.3"], "--mu: expected 1 or 2 values"),
        (["--elements", "0,1", "--torque-scale", "0"], "--torque-scale: must be >= 1e-15"),
    ],
)
def test_cli_bad_input(capsys, ring_file, argv, message):
    code, out, err = _run(capsys, "eligibility", ring_file, *argv)
    assert code == 2 and out == ""
    assert err.startswith("error:") and len(err.strip().splitlines()) == 1
    assert re.search(message, err), err


def test_cli_select_failure_is_exit_1(capsys, tmp_path):
    path = tmp_path / "box.model.json"
    save_model(corner_model(), path)
    code, out, err = _run(capsys, "select", str(path), "--contacts", "7", "--type", "fpc")
    assert code == 1 and "no eligible element set" in err


def test_screens_that_stop_early_change_no_decision(ring, monkeypatch):
    """The iterative run's screens stop once a set is shown unable to win: the run takes the
    same steps to the same set as with screens that search to the end."""
    from closure_nlp.criterion import support_minimum as quality
    from closure_nlp.criterion.support_minimum import SupportMinimizer, SupportMinProblem

    runs = []  # local solver runs, IPOPT's or the compiled minimiser's
    solve = SupportMinProblem.solve
    monkeypatch.setattr(SupportMinProblem, "solve", lambda *a: runs.append(1) or solve(*a))
    local = quality._local_minimum
    monkeypatch.setattr(quality, "_local_minimum", lambda *a: runs.append(1) or local(*a))
    start = [0, 1, 12]
    early = iterative(ring, start)
    early_runs, runs[:] = len(runs), []
    search = SupportMinimizer.__call__
    monkeypatch.setattr(
        SupportMinimizer,
        "__call__",
        lambda self, slots, warm=None, stop_below=None: search(self, slots, warm),
    )
    full = iterative(ring, start)
    assert early.elements == full.elements and early.history == full.history
    assert early.rho_hat == full.rho_hat and early.screened == full.screened
    assert early_runs < len(runs)  # and the early stops did spare local solver runs


SHAFT = "examples/studies/models/stepped_shaft.model.json"
# Iterative results of two seeds on the stepped shaft (7 FPC, torque scale 1): wrench flats are
# elements 6-11, the other elements lie on surfaces of revolution or on planes normal to the axis
ONE_FLAT = [74, 81, 33, 1, 10, 70, 40]  # only element 10 is a flat
TWO_FLATS = [66, 8, 6, 30, 0, 61, 56]


def _axial_torques(model, elements):
    """Torque about the shaft's axis (z) of a unit normal force at every vertex of each element:
    (p x n)_z, straight from the geometry."""
    out = []
    for e in elements:
        el = model.elements[e]
        n = el.inward_normal
        out.append(np.array([p[0] * n[1] - p[1] * n[0] for p in el.vertices]))
    return out


@pytest.mark.parametrize("torque_scale", [1.0, 1e-3, 1e3])
def test_a_lone_frictionless_contact_on_a_flat_makes_a_set_hopeless(torque_scale):
    """ONE_FLAT: only the flat's contact has torque about the axis (the geometry says so), of
    either sign along the flat, so rho_hat calls the set eligible while one contact there gives
    one sign: no placement is force closure. lone_contact names that contact, at any torque
    scale; with two flats, or with friction on the flat's contact, it names none."""
    from closure_nlp.model.elements import load_model
    from closure_nlp.selection.algorithms import lone_contact

    model = load_model(SHAFT)
    torques = _axial_torques(model, ONE_FLAT)
    size = max(np.abs(t).max() for t in torques)
    assert all(np.abs(t).max() <= 1e-12 * size for k, t in enumerate(torques) if k != 4)
    assert torques[4].min() < 0 < torques[4].max()  # both signs along the flat
    fpc = Eligibility(model, contact_specs(7, type="fpc"), torque_scale=torque_scale)
    assert lone_contact(fpc, ONE_FLAT) == 4
    assert lone_contact(fpc, TWO_FLATS) is None
    if torque_scale == 1.0:
        assert fpc(ONE_FLAT).eligible  # the relaxation cannot tell
    specs = list(contact_specs(7, type="fpc"))
    specs[4] = contact_specs(1, type="pcwf", mu=0.3)[0]
    assert lone_contact(Eligibility(model, specs, torque_scale=torque_scale), ONE_FLAT) is None


def test_full_searches_that_stop_early_change_no_decision_nor_the_plans_pool(monkeypatch):
    """The iterative run's full searches of neighbours stop once a set is shown unable to win
    (its value at or above the bar or the step's candidate): the run takes the same steps, and
    the plan's pool of further sets (:class:`~closure_nlp.planning.single._Pool`, which finishes
    those searches from the same start) is the same, value for value, as with searches to the
    end."""
    from closure_nlp.planning.single import _Pool

    model = load_model(SHAFT)
    eligibility = Eligibility(model, contact_specs(7, type="fpc"), torque_scale=1.0)
    start = [73, 82, 30, 0, 10, 69, 59]  # the heuristic's set of seed 0; ONE_FLAT is the result
    early = iterative(eligibility, start)
    assert early.elements == tuple(ONE_FLAT)
    assert early.unfinished_sets, "some full searches stop early on the shaft"
    for elements, warm in early.unfinished_sets:  # indeed no better than the result
        full_value = eligibility(elements, warm, certify=False).rho_hat
        assert full_value >= early.rho_hat
    pool = _Pool(eligibility)
    pool.add(early)
    early_pool = list(iter(pool.pop, None))
    call, evaluated = Eligibility.__call__, {}

    def to_the_end(self, elements, *args, stop_above=None, **kwargs):
        found = call(self, elements, *args, **kwargs)
        evaluated[tuple(sorted(elements))] = (found.rho_hat, tuple(found.elements))
        return found

    monkeypatch.setattr(Eligibility, "__call__", to_the_end)
    full = iterative(eligibility, start)
    assert early.elements == full.elements and early.history == full.history
    assert early.evaluations == full.evaluations
    # every set the run searched to the end, eligible and not the result, lowest value first
    evaluated.pop(tuple(sorted(full.elements)))
    expected = sorted(item for item in evaluated.values() if item[0] < 0)
    proven = [(tuple(e), v) for e, v, is_proven in early_pool if is_proven]
    assert proven == [(e, v) for v, e in expected]


def test_the_plans_pool_searches_a_stopped_set_only_once_it_could_come_next(monkeypatch):
    """A stopped screen's value never lies above its light value, so the pool gives the next
    set after searching only the sets that could come before it, and, drained, every set in
    the order of their values with every stopped screen finished."""
    from closure_nlp.criterion.robustness import robust_value
    from closure_nlp.planning import single

    eligibility = Eligibility(load_model(SHAFT), contact_specs(7, type="fpc"), torque_scale=1.0)
    run = iterative(eligibility, [73, 82, 30, 0, 10, 69, 59])
    assert len(run.unranked_floors) == len(run.unranked_sets) > 0
    searched, light = [], single.light_rho_hat
    monkeypatch.setattr(
        single, "light_rho_hat", lambda *args, **kw: searched.append(1) or light(*args, **kw)
    )
    pool = single._Pool(eligibility)
    pool.add(run)
    first = pool.pop()
    assert len(searched) < len(run.unranked_sets) // 2
    drained = [first, *iter(pool.pop, None)]
    assert len(searched) == len(run.unranked_sets)
    steer = [robust_value(v, eligibility.shift(e)) for e, v, _ in drained]
    assert steer == sorted(steer)
    for (elements, warm), floor in zip(run.unranked_sets, run.unranked_floors):
        value, _ = light(eligibility, elements, warm)
        assert value >= floor


def test_a_certified_rho_hat_has_no_early_stop(ring):
    with pytest.raises(ValueError, match="stop_above"):
        ring([0, 4, 13], stop_above=-0.1)
