"""plan(..., seeds=N): the best of N seeds, the same over processes as one by one, with the spread;
a seed that fails or ends marginal does not stop the others; the budget stops new seeds."""

from __future__ import annotations

import json
import multiprocessing
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from closure_nlp.cli import main as cli
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import save_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.planning import seeds, single
from closure_nlp.planning.plan import plan
from closure_nlp.planning.single import PlanResult
from closure_nlp.selection.algorithms import SelectionOptions
from tests.shapes import box_model
from tests.test_threads import without_time

QUICK = PlacementOptions(starts=1, extra_starts=0, neighbour_moves=0, max_rounds=3)
FEW = SelectionOptions(restarts=2)


def hand() -> Eligibility:
    return Eligibility(box_model(10.0), contact_specs(4, type="pcwf", mu=0.4), torque_scale=0.1)


def patch_plan(monkeypatch, fake) -> None:
    """One seed's plan (``single.plan_one``) replaced by ``fake``, in the worker processes
    too: those are forked here whatever threads earlier tests left behind (a forkserver's
    workers would import the real plan)."""
    monkeypatch.setattr(single, "plan_one", fake)
    monkeypatch.setattr(single, "select_one", lambda *args, **kwargs: None)  # seed order
    monkeypatch.setattr(seeds, "_context", lambda: multiprocessing.get_context("fork"))
    # the fake placements have no elements to bound: they stay as they are
    monkeypatch.setattr(seeds, "_root", lambda placer, placed: placed)
    monkeypatch.setattr(seeds, "_searched", lambda placer, placed, progress: placed)


def comparable(result: PlanResult) -> dict:
    """Everything but timings, the memo's hits and the number of processes."""
    d = without_time(result.to_dict())
    d.pop("reused")
    d["seeds"].pop("workers")
    for run in d["seeds"]["runs"]:
        run.pop("reused")
    return d


@pytest.mark.slow  # six small plans
def test_seeds_over_processes_equal_the_seeds_one_by_one_and_the_spread_is_theirs():
    parallel = plan(hand(), seed=4, seeds=3, workers=2, selection=FEW, placement=QUICK)
    serial = plan(hand(), seed=4, seeds=3, workers=1, selection=FEW, placement=QUICK)
    assert comparable(parallel) == comparable(serial)
    spread = serial.to_dict()["seeds"]
    runs = spread["runs"]
    assert [r["seed"] for r in runs] == [4, 5, 6] and spread["workers"] == 1
    assert parallel.seeds.workers == 2
    rhos = [r["rho"] for r in runs]
    # the lowest rho, rhos within the certified accuracy of it tied and the lowest seed of the
    # tie chosen (the rule's own cases, with round-off ties: the fake plans' tests below)
    tie = 1e-6 * max(abs(min(rhos)), *(r["rho_unit"] for r in runs))
    best = min(r["seed"] for r in runs if r["force_closure"] and r["rho"] <= min(rhos) + tie)
    assert spread["chosen_seed"] == best
    assert spread["best_rho"] == serial.placement.rho == rhos[[4, 5, 6].index(best)]
    assert spread["median_rho"] == float(np.median(rhos))
    assert spread["worst_rho"] == max(rhos)
    assert spread["force_closure"] == sum(r["force_closure"] for r in runs) == 3
    assert spread["marginal"] == 0 and spread["failed"] == 0
    chosen = runs[[r["seed"] for r in runs].index(spread["chosen_seed"])]
    assert chosen["rho"] == serial.placement.rho
    assert chosen["elements"] == list(serial.placement.elements)
    met = {tuple(s["elements"]): s["seeds"] for s in spread["element_sets"]}
    assert sum(met.values()) == 3
    for r in runs:
        assert met[tuple(sorted(r["elements"]))] >= 1


def fake_result(
    rho: float, force_closure: bool, marginal: bool, elements, ceiling=None
) -> PlanResult:
    """A plan's result with only what the spread reads."""
    placement = SimpleNamespace(
        rho=rho,
        force_closure=force_closure,
        marginal=marginal,
        elements=tuple(elements),
        bounds=(rho, rho),
        capacity_bound=ceiling,
        contacts=(),
    )
    selection = SimpleNamespace(elements=tuple(elements))
    return PlanResult(selection, selection, placement, 0.0, (), ())


# seed -> what its plan does: ends with a result, ends marginal, fails
OUTCOMES = {
    0: fake_result(-0.2, True, False, [0, 1, 2, 3], ceiling=0.6),
    1: fake_result(0.0, False, True, [0, 1, 2, 4]),
    2: RuntimeError("no placement"),
    3: fake_result(-0.5, True, False, [3, 2, 1, 0], ceiling=0.55),
    4: fake_result(-0.1, True, False, [0, 1, 2, 3], ceiling=0.7),
}


def fake_plan(eligibility, placer, seed, **kwargs):
    outcome = OUTCOMES[seed]
    if isinstance(outcome, Exception):
        raise outcome
    return outcome


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failed_or_marginal_seed_does_not_stop_the_plan(monkeypatch, workers):
    patch_plan(monkeypatch, fake_plan)
    from closure_nlp.planning.seeds import plan_seeds

    best = plan_seeds(hand(), seed=0, seeds=5, workers=workers)
    spread = best.seeds.to_dict()
    assert best.placement.rho == -0.5 and spread["chosen_seed"] == 3
    assert (spread["force_closure"], spread["marginal"], spread["failed"]) == (3, 1, 1)
    assert spread["runs"][2] == {
        "seed": 2,
        "error": "RuntimeError: no placement",
        "seconds": spread["runs"][2]["seconds"],
    }
    assert (spread["best_rho"], spread["worst_rho"]) == (-0.5, 0.0)
    assert spread["median_rho"] == pytest.approx(-0.15, rel=1e-12)  # of -0.2, 0.0, -0.5, -0.1
    # each seed's ceiling covers every placement on its set: the lowest is the set's
    assert spread["element_sets"] == [
        {"elements": [0, 1, 2, 3], "seeds": 3, "best_rho": -0.5, "ceiling": 0.55},
        {"elements": [0, 1, 2, 4], "seeds": 1, "best_rho": 0.0, "ceiling": None},
    ]
    assert [r.get("capacity_bound") for r in spread["runs"]] == [0.6, None, None, 0.55, 0.7]
    assert "; 3 force closure, 1 marginal, 1 failed (seed 2);" in best.seeds.line()


def test_every_seed_failing_raises_the_first_error(monkeypatch):
    patch_plan(monkeypatch, lambda *a, **k: (_ for _ in ()).throw(ValueError("x")))
    with pytest.raises(ValueError, match="x"):
        plan(hand(), seeds=2, workers=1)


# seed -> its placement by the exchange method; seeds 1 and 4 end on the same contacts
SHARED = fake_result(-0.5, True, False, [3, 2, 1, 0])
PLACED = {
    0: fake_result(-0.2, True, False, [0, 1, 2, 3]),
    1: SHARED,
    2: fake_result(-0.4, True, False, [0, 1, 2, 4]),
    3: fake_result(-0.1, True, False, [0, 1, 3, 4]),
    4: SHARED,
}


def rooted(placer, placed):
    """A root cell whose climb lifts the placement on elements 0, 1, 2, 4 past the others."""
    lift = 0.3 if placed.elements == (0, 1, 2, 4) else 0.0
    return SimpleNamespace(**{**vars(placed), "rho": placed.rho - lift, "capacity_bound": 1.0})


@pytest.mark.parametrize("workers", [1, 2])
def test_the_better_half_of_the_seeds_get_the_root_cell_and_its_climb_may_choose(
    monkeypatch, workers
):
    """The seeds ranked first by the exchange method's rho (3 of 5) get the root cell, each
    placement once; a lift there changes the choice, and the others have no ceiling."""
    patch_plan(monkeypatch, lambda eligibility, placer, seed, **kwargs: PLACED[seed])
    monkeypatch.setattr(seeds, "_root", rooted)
    from closure_nlp.planning.seeds import plan_seeds

    best = plan_seeds(hand(), seed=0, seeds=5, workers=workers)
    spread = best.seeds.to_dict()
    assert spread["chosen_seed"] == 2 and best.placement.rho == pytest.approx(-0.7)
    assert [r["capacity_bound"] for r in spread["runs"]] == [None, 1.0, 1.0, None, 1.0]
    assert spread["runs"][1]["rho"] == spread["runs"][4]["rho"] == -0.5


def slow_plan(eligibility, placer, seed, **kwargs):
    time.sleep(0.4)
    return OUTCOMES[0]


@pytest.mark.parametrize("workers", [1, 2])
def test_the_budget_stops_new_seeds_and_the_report_says_so(monkeypatch, workers):
    patch_plan(monkeypatch, slow_plan)
    from closure_nlp.planning.seeds import plan_seeds

    spread = plan_seeds(hand(), seeds=6, workers=workers, budget=0.2).seeds
    assert len(spread.runs) == workers  # those started at once; none after the budget
    assert spread.requested == 6 and "of 6 (budget of 0.2 s spent)" in spread.line()


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"seeds": 0}, "seeds: expected an integer in"),
        ({"seeds": 2.0}, "seeds: expected an integer in"),
        ({"seeds": 2, "workers": 0}, "workers: expected an integer >= 1"),
        ({"seeds": 2, "budget": -1.0}, "budget: expected a positive number"),
        ({"seeds": 2, "budget": float("nan")}, "budget: expected a positive number"),
        ({"seeds": 2, "seed": -1}, "seed: seeds -1..0 must lie in"),
        ({"seeds": 1, "workers": 2}, "workers, budget: only with several seeds"),
    ],
)
def test_bad_seed_options_name_the_field(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        plan(hand(), **kwargs)


@pytest.mark.slow  # two small plans in two processes
def test_cli_plan_with_seeds_writes_the_spread(tmp_path, capsys):
    path = tmp_path / "box.model.json"
    save_model(box_model(10.0), path)
    out = tmp_path / "run"
    argv = [
        "plan",
        str(path),
        "--contacts",
        "4",
        "--mu",
        "0.4",
        "--seeds",
        "2",
        "--workers",
        "2",
        "--starts",
        "1",
        "--alternatives",
        "0",
        "--out",
        str(out),
        "--json",
        "--quiet",
    ]
    assert cli.main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    spread = data["seeds"]
    assert [r["seed"] for r in spread["runs"]] == [0, 1] and spread["run"] == 2
    assert data["placement"]["rho"] == spread["best_rho"]
    assert (out / "seeds.png").stat().st_size > 0
    summary = (out / "summary.md").read_text()
    assert "| seed | rho | verdict |" in summary and "(chosen)" in summary
    # the ceiling (on by default) of each element set: no placement on it holds more
    assert "| elements | seeds | best rho | ceiling |" in summary
    for row in spread["element_sets"]:
        on = [r for r in spread["runs"] if sorted(r["elements"]) == row["elements"]]
        assert row["ceiling"] == min(r["capacity_bound"] for r in on)
        assert row["ceiling"] >= max(-r["bounds"][1] for r in on)
    report = json.loads((out / "report.json").read_text())
    assert report["seeds"]["runs"] == spread["runs"] and report["options"]["seeds"] == 2


# Seeds 5 and 6 of a pistol plan once ended on the same placement in another contact order: a
# tie to 2e-13, in which round-off made the lower raw rho the other seed's.
TIE = (-1.035491704129848, -1.0354917041300218)


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e3])
def test_rhos_within_the_certified_accuracy_tie_and_the_lowest_seed_wins(scale):
    """The same part in other units (rho and wrench scale alike) chooses the same seed; the
    choice depends on the values only, not their order; a real difference still decides."""
    tied = [(6, True, TIE[1] * scale, scale), (5, True, TIE[0] * scale, scale)]
    assert TIE[1] < TIE[0]  # raw float order would pick seed 6
    assert tied[seeds.choose(tied)][0] == 5
    assert tied[::-1][seeds.choose(tied[::-1])][0] == 5
    apart = [(6, True, (TIE[0] - 1e-4) * scale, scale), (5, True, TIE[0] * scale, scale)]
    assert apart[seeds.choose(apart)][0] == 6
    # force closure first, even over a lower rho of a seed that is not
    mixed = [(1, False, -2.0 * scale, scale), (2, True, -1.0 * scale, scale)]
    assert mixed[seeds.choose(mixed)][0] == 2


def tied_plan(eligibility, placer, seed, **kwargs):
    """Seeds 0 and 1 tie (1 by round-off lower), seed 0 finishing last; seed 2 holds less."""
    time.sleep({0: 0.5, 1: 0.0, 2: 0.1}[seed])
    rho = {0: TIE[0], 1: TIE[1], 2: -0.9}[seed]
    return fake_result(rho, True, False, [0, 1, 2, 3][::-1] if seed else [0, 1, 2, 3])


@pytest.mark.parametrize("workers", [1, 2])
def test_a_tie_goes_to_the_lowest_seed_whatever_the_order_the_seeds_finish(monkeypatch, workers):
    patch_plan(monkeypatch, tied_plan)
    from closure_nlp.planning.seeds import plan_seeds

    best = plan_seeds(hand(), seed=0, seeds=3, workers=workers)
    spread = best.seeds.to_dict()
    assert spread["chosen_seed"] == 0 and best.placement.rho == TIE[0]
    assert spread["best_rho"] == TIE[0]
    assert [r["seed"] for r in spread["runs"]] == [0, 1, 2]  # in seed order, not finishing order
    assert all(r["rho_unit"] > 0 for r in spread["runs"])


SLEEP = {0: 0.1, 1: 0.4, 2: 0.8, 3: 0.0}


def memo_plan(eligibility, placer, seed, *, memo, **kwargs):
    """Adds one step to the memo, keyed as plan keys it, and tells the earlier seeds' steps it
    found there (as ``reused``). Seed 0 ends first, in one worker, which then runs seed 2;
    seed 3 starts when seed 1 ends, in the other worker."""
    time.sleep(SLEEP[seed])
    found = sorted(key[2][0] for key in memo if key[1] is eligibility)
    memo[("placement", eligibility, (seed,), None)] = seed
    result = fake_result(-0.1 - seed, True, False, [0, 1, 2, 3])
    return replace(result, reused=tuple(f"seed {k}" for k in found))


@pytest.mark.parametrize("workers", [1, 2])
def test_a_seed_takes_the_steps_every_earlier_seed_computed_in_any_process(monkeypatch, workers):
    patch_plan(monkeypatch, memo_plan)
    from closure_nlp.planning.seeds import plan_seeds

    spread = plan_seeds(hand(), seed=0, seeds=4, workers=workers).seeds
    reused = {run.seed: run.result.reused for run in spread.runs}
    assert "seed 0" in reused[3]  # computed in the other process
    assert reused[0] == ()


def test_memo_entries_cross_to_a_copy_of_the_eligibility():
    import pickle

    from closure_nlp.planning.single import adopt_memo, memo_entries

    here, other = hand(), hand()
    memo = {("placement", here, (0, 1, 2, 3), QUICK): "placed", ("x", other, (), None): "no"}
    entries = pickle.loads(pickle.dumps(memo_entries(memo, here)))
    assert entries == {("placement", (0, 1, 2, 3), QUICK): "placed"}
    theirs = {("placement", other, (0, 1, 2, 3), QUICK): "their own"}
    adopt_memo(theirs, other, {**entries, ("iterative", (1,), FEW): "run"})
    assert theirs == {
        ("placement", other, (0, 1, 2, 3), QUICK): "their own",  # kept, not overwritten
        ("iterative", other, (1,), FEW): "run",
    }


@pytest.mark.slow  # three small plans
def test_the_ceiling_searches_past_its_root_for_the_chosen_seed_alone():
    """With a cell budget, every seed's ceiling is its root cell and the chosen seed's placement
    gets the cells: its ceiling still bounds it, and no worse than that seed's own placement."""
    options = replace(QUICK, bound_cells=6)
    found = plan(hand(), seed=4, seeds=2, workers=1, selection=FEW, placement=options)
    runs = found.seeds.runs
    chosen = runs[found.seeds.chosen].result.placement
    assert found.placement is chosen and chosen.bound_nodes > 1
    others = [r.result.placement for r in runs if r.result.placement is not chosen]
    assert all(p.bound_nodes == 1 for p in others)
    assert chosen.capacity_bound >= -chosen.bounds[1] - 1e-9
    root = replace(QUICK, bound_cells=1)
    alone = plan(hand(), seeds=1, seed=runs[found.seeds.chosen].seed, selection=FEW, placement=root)
    assert chosen.rho <= alone.placement.rho + 1e-9


# seed -> (certified lower end of its selected set's rho_hat, rho its placement reaches, seconds)
FLOORED = {
    0: (-0.3, -0.2, 0.0),
    1: (-0.6, -0.5, 0.6),
    2: (-0.1, -0.05, 0.0),
    3: (-0.55, -0.4, 0.0),
    4: (-0.45, -0.45, 0.0),
}


def floored_plan(eligibility, placer, seed, *, beat=None, **kwargs):
    """A seed whose selection has the floor of FLOORED: it stops, as plan_one does, when that
    floor lies above the rho it is given to beat; the best seed (1) is the slowest."""
    floor, rho, seconds = FLOORED[seed]
    bar = None if beat is None else beat()
    if bar is not None and floor > bar:
        raise single.CannotWin((seed,) * 4, floor, bar)
    time.sleep(seconds)
    result = fake_result(rho, True, False, [seed] * 4)
    return replace(result, iterative=SimpleNamespace(elements=(seed,) * 4, bounds=(floor, 0.0)))


@pytest.mark.parametrize("workers", [1, 2])
def test_seeds_that_cannot_win_stop_after_their_selection_whatever_the_workers(
    monkeypatch, workers
):
    """Placed lowest floor first (1, 3, 4, 0, 2): once seed 1 holds -0.5, the sets whose floor
    lies above it (4, 0, 2) cannot win and are not placed; seed 3's (-0.55) can and is. With
    two workers seed 1 is still running when 4, 0 and 2 start: they run on and are stopped as
    one by one would."""
    patch_plan(monkeypatch, floored_plan)
    monkeypatch.setattr(single, "select_one", lambda el, seed, **kw: FLOORED[seed][0])
    from closure_nlp.planning.seeds import plan_seeds

    best = plan_seeds(hand(), seed=0, seeds=5, workers=workers)
    spread = best.seeds.to_dict()
    assert spread["chosen_seed"] == 1 and best.placement.rho == -0.5
    assert [r["seed"] for r in spread["runs"]] == [0, 1, 2, 3, 4]
    assert [r["seed"] for r in spread["runs"] if "stopped" in r] == [0, 2, 4]
    assert (spread["stopped"], spread["failed"], spread["run"]) == (3, 0, 5)
    stopped = spread["runs"][4]
    assert stopped["rho_hat_lo"] == -0.45 and stopped["selected"] == [4] * 4
    assert "cannot beat the rho -0.5 of a seed placed before it" in stopped["stopped"]
    assert "3 stopped after selection (their elements cannot beat" in best.seeds.line()
    assert spread["median_rho"] == pytest.approx(-0.45)  # of the placed seeds 1 and 3


def test_without_the_stop_rule_every_seed_is_placed(monkeypatch):
    patch_plan(monkeypatch, floored_plan)
    monkeypatch.setattr(single, "select_one", lambda el, seed, **kw: FLOORED[seed][0])
    from closure_nlp.planning.seeds import plan_seeds

    best = plan_seeds(hand(), seed=0, seeds=5, workers=2, stop=False)
    spread = best.seeds.to_dict()
    assert spread["chosen_seed"] == 1 and (spread["stopped"], spread["run"]) == (0, 5)
    assert [r["rho"] for r in spread["runs"]] == [FLOORED[k][1] for k in range(5)]
