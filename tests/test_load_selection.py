"""Selection by load factors: the element set's factor bounds every placement's on it."""

import json
from pathlib import Path

import numpy as np
import pytest

import closure_nlp as c
from closure_nlp.cli.main import main
from closure_nlp.criterion.crosscheck import load_factor_cvxpy
from closure_nlp.placement.load_objective import LoadObjective
from closure_nlp.placement.place import Placer
from closure_nlp.selection.algorithms import run_selection
from closure_nlp.selection.load_value import LoadValue

from .shapes import LAMP_LOADS

ROOT = Path(__file__).resolve().parents[1]
LAMP = ROOT / "models" / "lamp.model.json"
LOADS = LAMP_LOADS
SOCP = 1e-6  # the SOCP's accuracy, relative


@pytest.fixture(scope="module")
def lamp():
    model = c.load_model(LAMP)
    eligibility = c.Eligibility(model, c.contact_specs(4, type="pcwf"), torque_scale="auto")
    return eligibility, LoadValue(eligibility, LoadObjective.of(eligibility, LOADS))


def test_selection_by_loads_bounds_the_placements_factors(lamp):
    eligibility, value = lamp
    result = run_selection(eligibility, "iterative", seed=0, value=value)
    assert result.eligible and result.bounds[0] <= result.rho_hat <= result.bounds[1]
    factors = [value.factor(v) for _, v in result.history]
    assert all(b >= a * (1 - 1e-9) for a, b in zip(factors, factors[1:]))  # never worse
    slots = eligibility.slots(result.elements)
    placed = Placer(eligibility, c.PlacementOptions(bound=False, starts=1), loads=LOADS)(
        list(result.elements)
    )
    cases = LoadObjective.of(eligibility, LOADS).loads.cases
    least_element, least_placed = np.inf, np.inf
    for case in cases:
        wrench = case.wrench(eligibility.model.reference_point, eligibility.torque_scale)
        on_elements, status = load_factor_cvxpy(slots, wrench)
        assert status == "optimal"
        on_contacts, status = load_factor_cvxpy(placed.contact_set, wrench)
        assert status == "optimal"
        assert on_contacts <= on_elements * (1 + SOCP)
        least_element = min(least_element, on_elements)
        least_placed = min(least_placed, on_contacts)
    lo, hi = -result.bounds[1] / value.unit, -result.bounds[0] / value.unit
    assert lo * (1 - SOCP) <= least_element <= hi * (1 + SOCP)
    assert least_placed <= hi * (1 + SOCP)  # the selection's factor bounds the placement's


def test_a_set_that_cannot_push_against_a_case_is_worth_zero(lamp):
    eligibility, _ = lamp
    e = 10
    normal = eligibility.model.elements[e].inward_normal
    # every contact on one facet pushes along its inward normal: none can pull the part back
    loads = {"loads": [{"name": "along", "force": list(normal), "point": [0, 0, 0]}]}
    value = LoadValue(eligibility, LoadObjective.of(eligibility, loads))
    found = value([e, e, e, e])
    assert found.rho_hat == 0.0 and not found.eligible and found.marginal
    assert found.bounds == (0.0, 0.0) and value.factor(found.rho_hat) == 0.0
    again = value([e, e, e, e])
    assert again is found and value.evaluations == 1  # asked twice, computed once


def run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_select_and_eligibility_report_the_element_sets_factors(tmp_path, capsys):
    from tests.test_formats_contract import FORMATS, code_spans, keys, missing

    path = tmp_path / "loads.json"
    path.write_text(json.dumps(LOADS))
    select = ["select", str(LAMP), "--contacts", "4", "--type", "pcwf", "--loads", str(path)]
    code, out, err = run([*select, "--json"], capsys)
    assert code == 0, err
    by_loads = json.loads(out)
    assert by_loads["objective"] == "loads"
    assert by_loads["history"][-1]["load_factor"] == pytest.approx(by_loads["load_factor"])
    code, out, err = run([*select, "--objective", "rho", "--json"], capsys)
    by_rho = json.loads(out)
    assert code == 0 and by_rho["objective"] == "rho" and "rho_hat" in by_rho["history"][0]
    # eligibility of the selected set: the same factors
    ids = ",".join(str(i) for i in by_loads["elements"])
    argv = ["eligibility", str(LAMP), "--elements", ids, "--type", "pcwf", "--loads", str(path)]
    code, out, err = run([*argv, "--json"], capsys)
    answer = json.loads(out)
    assert code == 0 and answer["load_factor"] == pytest.approx(by_loads["load_factor"], rel=1e-9)
    assert answer["rho_hat"] == pytest.approx(by_loads["rho_hat"], rel=1e-5)
    spans = code_spans(FORMATS.read_text(encoding="utf-8"))
    found = set()
    for data in (by_loads, by_rho, answer):
        keys(data, found)
    assert not missing(found, spans)
    code, out, err = run(["select", str(LAMP), "--contacts", "4", "--objective", "loads"], capsys)
    assert code == 2 and "--objective" in err


def test_placing_by_loads_where_the_centroids_hold_nothing_starts_from_rho(lamp):
    """The centroids of these elements hold no case at all (the least factor is flat at 0
    around them): the load placement starts from the rho placement and never ends below it."""
    from closure_nlp.criterion.load_factor import load_factors

    eligibility, _ = lamp
    elements = [39, 47, 42, 8]
    options = c.PlacementOptions(bound=False, starts=1)
    counts = [len(eligibility.model.elements[e].vertices) for e in elements]
    weights = [np.full(k, 1.0 / k) for k in counts]
    centroids = Placer(eligibility, options).contact_set(elements, weights)
    assert load_factors(centroids, LOADS).load_factor == 0.0
    by_rho = load_factors(Placer(eligibility, options)(elements).contact_set, LOADS)
    by_loads = load_factors(Placer(eligibility, options, loads=LOADS)(elements).contact_set, LOADS)
    assert by_loads.load_factor >= by_rho.load_factor > 0
