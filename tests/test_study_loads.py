"""Loads in studies: the ``loads`` and ``objective`` keys, and the factors in every row."""

import json

import numpy as np
import pandas as pd
import pytest

import closure_nlp as c
from closure_nlp.contact.loads import as_loads
from closure_nlp.criterion.crosscheck import load_factor_cvxpy
from closure_nlp.study import load_study, run_study
from closure_nlp.study.tasks import clear_cache
from tests.test_study import PLACEMENT, TINY, write_study

ONE = TINY.replace("mu = [0.2, 0.4]", "mu = 0.5").replace("seeds = 2", "seeds = 1")
CASES = [
    {"name": "down", "force": [0, 0, -1], "point": [0.5, 0, 1]},
    {"name": "twist", "force": [0, 0, 0], "torque": [0, 0, 0.3]},
]
INLINE = '\n[[loads.loads]]\nname = "down"\nforce = [0, 0, -1]\npoint = [0.5, 0, 1]\n'
INLINE += '[[loads.loads]]\nname = "twist"\nforce = [0, 0, 0]\ntorque = [0, 0, 0.3]\n'


def test_loads_inline_or_by_path_give_the_same_tasks(tmp_path):
    plain = load_study(write_study(tmp_path / "a", ONE + PLACEMENT))
    assert plain.loads is None and all("loads" not in t.inputs() for t in plain.tasks)
    inline = load_study(write_study(tmp_path / "b", ONE + INLINE + PLACEMENT))
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "loads.json").write_text(json.dumps({"loads": CASES}))
    by_path = load_study(write_study(tmp_path / "c", 'loads = "loads.json"\n' + ONE + PLACEMENT))
    assert inline.objective == by_path.objective == "loads"
    assert [t.task_id for t in inline.tasks] == [t.task_id for t in by_path.tasks]
    assert not {t.task_id for t in inline.tasks} & {t.task_id for t in plain.tasks}
    by_rho = load_study(write_study(tmp_path / "d", 'objective = "rho"\n' + ONE + INLINE))
    assert by_rho.objective == "rho" and by_rho.to_dict()["loads"]["loads"][1]["name"] == "twist"


@pytest.mark.parametrize(
    "head,needles",
    [
        ('objective = "rho"\n', ["objective", "loads key"]),
        ('objective = "most"\nloads = "x.json"\n', ["objective", "most"]),
        ('loads = "nowhere.json"\n', ["loads", "nowhere.json"]),
        ("loads = 3\n", ["loads", "3"]),
        ('loads = [{name = "a", force = [0, 0, 0]}]\n', ["loads", "zero"]),
        ('loads = [{name = "a", force = [1, 0, 0], pont = [0, 0, 0]}]\n', ["loads", "pont"]),
    ],
)
def test_bad_loads_in_a_study_are_refused_by_name(tmp_path, head, needles):
    path = write_study(tmp_path, head + ONE)
    with pytest.raises((ValueError, TypeError)) as info:
        load_study(path)
    for needle in needles:
        assert needle in str(info.value)


def test_study_rows_carry_the_certified_factors(tmp_path):
    study = load_study(write_study(tmp_path, ONE + INLINE + PLACEMENT + "bound = false\n"))
    clear_cache()
    result = run_study(study, tmp_path / "out", serial=True)
    assert result.failed == 0
    rows = pd.read_csv(tmp_path / "out" / "results.csv")
    [row] = rows.to_dict("records")
    assert row["objective"] == "loads" and row["force_closure"]
    assert row["load_factor_lo"] == row["load_factor"] <= row["load_factor_hi"]
    cases = json.loads(row["load_factors"])
    assert [case["name"] for case in cases] == ["down", "twist"]
    assert row["load_factor"] == pytest.approx(min(case["load_factor"] for case in cases))
    # each case's factor on the placed contacts, by the independent SOCP
    model = c.load_model(tmp_path / "box.model.json")
    placed = json.loads(row["placed_contacts"])
    contacts = c.ContactSet.from_arrays(
        np.array([p["position"] for p in placed]),
        np.array([p["inward_normal"] for p in placed]),
        type="pcwf",
        mu=0.5,
        f_max=row["f_max"],
        torque_scale=row["torque_scale"],
        reference_point=model.reference_point,
    )
    for case, load in zip(cases, as_loads(CASES).cases):
        wrench = load.wrench(contacts.reference_point, contacts.torque_scale)
        socp, status = load_factor_cvxpy(contacts, wrench)
        assert status == "optimal"
        lo, hi = case["bounds"]
        assert lo * (1 - 1e-6) <= socp <= hi * (1 + 1e-6)
