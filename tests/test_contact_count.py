"""The early count check: contacts that can never give force closure are refused before any search.

Theorem. Let K_1, ..., K_m be convex cones in R^n, none of them a linear subspace, with
K_1 + ... + K_m = R^n. Then dim span K_1 + ... + dim span K_m >= n + 1.

Proof. Let V_i = span K_i and d_i = dim V_i. R^n = sum K_i lies in sum V_i, so sum d_i >= n.
Suppose sum d_i = n. Then R^n = V_1 (+) ... (+) V_m is a direct sum, and the projection P onto
V_1 along V_2 (+) ... (+) V_m is linear with P(K_i) = {0} for i >= 2 and P(x) = x on V_1. So
V_1 = P(R^n) = P(K_1) + ... + P(K_m) = K_1, and K_1 is a linear subspace: a contradiction. []

Application (n = 6). Force closure means 0 is interior to the wrench set sum_i W_i, with
W_i = G_i (F_i cut at f_n <= f_max) and 0 in every W_i; that holds iff the cones K_i = G_i F_i
sum to R^6. F_i (the friction cone of the contact's type) is pointed: f_n >= 0, and f_n = 0 forces
f = 0; it is not {0}. G_i is injective: its force rows are the orthonormal frame (n, o, t) on
(f_n, f_o, f_t), and its spin column is (0, torque_scale * n) with torque_scale > 0. So K_i is a
nonzero pointed cone, not a subspace, and dim span K_i = dim span F_i = 1 (normal force) + 2 if
mu > 0 (tangential friction) + 1 if a soft finger has mu_s > 0 (spin). By the theorem the
dimensions must sum to at least 7: 7 frictionless contacts, 3 point contacts with friction
(2 * 3 = 6 < 7), 2 soft fingers (1 * 4 < 7), and for mixed sets the sum itself. The bound is
reached: the tests below exhibit force-closure sets at exactly these counts.

One more case passes the count yet never holds: two point contacts (no spin) at p_1, p_2 and a
frictionless third (3 + 3 + 1 = 7). The moment about the line through p_1 along a (p_2 - p_1, or
any a if p_1 = p_2), phi(w) = a . (tau / torque_scale - p_1 x f), is linear, zero on K_1 and K_2
(forces through points of that line), and on K_3 = {t g_3 : t >= 0} takes values of one sign
only. Force closure needs phi(K_1 + K_2 + K_3) = R, so it is impossible.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.cli import main as cli
from closure_nlp.contact.contact_set import Contact, ContactSet, load_contact_set
from closure_nlp.contact.count import (
    closure_count_problem,
    require_closure_count,
    wrench_dimensions,
)
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.criterion.crosscheck import force_closure_cvxpy
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import save_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import heuristic, iterative
from tests.shapes import box_model

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _specs(types, mu=0.3, mu_s=0.1):
    return contact_specs(len(types), type=list(types), mu=mu, mu_s=mu_s)


@pytest.mark.parametrize(("kind", "fewest"), [("fpc", 7), ("pcwf", 3), ("sfcl", 2), ("sfce", 2)])
def test_fewest_contacts_of_one_type(kind, fewest):
    assert closure_count_problem(_specs([kind] * fewest)) is None
    problem = closure_count_problem(_specs([kind] * (fewest - 1)))
    assert problem is not None and f"at least {fewest} are needed" in problem


def test_parameters_that_remove_friction_count():
    """mu = 0 leaves only the normal force; a soft finger with mu_s = 0 is a point contact."""
    assert wrench_dimensions(contact_specs(1, type="pcwf", mu=0.0)[0]) == 1
    assert wrench_dimensions(contact_specs(1, type="sfce", mu=0.2, mu_s=0.0)[0]) == 3
    assert wrench_dimensions(contact_specs(1, type="sfcl", mu=0.0, mu_s=0.2)[0]) == 2
    assert closure_count_problem(contact_specs(6, type="pcwf", mu=0.0)) is not None
    assert closure_count_problem(contact_specs(7, type="pcwf", mu=0.0)) is None
    assert closure_count_problem(contact_specs(2, type="sfce", mu=0.2, mu_s=0.0)) is not None


@pytest.mark.parametrize(
    "types",
    [
        ["pcwf", "fpc", "fpc", "fpc"],  # 3 + 3 = 6
        ["sfce", "fpc", "fpc"],  # 4 + 2 = 6
        ["sfcl", "fpc"],
        ["fpc"] * 6,
        ["pcwf", "pcwf"],
        ["pcwf", "sfce", "fpc"],  # mu_s = 0 below: a point contact; 3 + 3 + 1, the line rule
        ["pcwf", "pcwf", "fpc"],
    ],
)
def test_refused_sets_are_never_force_closure(types):
    """The proofs, checked on random placements by the independent cvxpy decision."""
    mu_s = 0.0 if types == ["pcwf", "sfce", "fpc"] else 0.2
    problem = closure_count_problem(_specs(types, mu_s=mu_s))
    assert problem is not None and "can never give force closure" in problem
    rng = np.random.default_rng(7)
    for _ in range(40):
        contact_set = random_contact_set(rng, types, mu=0.8, mu_s=mu_s, tilt=0.6)
        assert not force_closure_cvxpy(contact_set)


def _ring(count, kinds):
    angles = 2 * np.pi * np.arange(count) / count
    return [
        Contact([np.cos(a), np.sin(a), 0.0], [-np.cos(a), -np.sin(a), 0.0], k)
        for a, k in zip(angles, kinds)
    ]


def test_the_bound_is_reached():
    """Force-closure sets at exactly the necessary counts: the check refuses nothing possible."""
    up, down = [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]
    below = [[np.cos(a), np.sin(a), -1.0] for a in 2 * np.pi * np.arange(3) / 3]
    examples = {
        "3 pcwf": _ring(3, ["pcwf"] * 3),
        "2 sfce": [Contact(up, down, "sfce"), Contact(down, up, "sfce")],
        "sfcl + pcwf": [Contact(up, down, "sfcl", mu_s=0.2), Contact(down, up, "pcwf")],
        "sfce + 3 fpc": [Contact(up, down, "sfce", mu=0.5)]
        + [Contact(p, up, "fpc") for p in below],
        "7 fpc": list(load_contact_set(EXAMPLES / "box_7fpc.contacts.json").contacts),
    }
    for name, contacts in examples.items():
        assert closure_count_problem([c.spec for c in contacts]) is None, name
        assert force_closure_cvxpy(ContactSet(tuple(contacts))), name
    # pcwf + 4 fpc (3 + 4 = 7): a random placement does it (about 3 in 100 do)
    rng = np.random.default_rng(7)
    types = ["pcwf", "fpc", "fpc", "fpc", "fpc"]
    assert closure_count_problem(_specs(types)) is None
    assert any(
        force_closure_cvxpy(random_contact_set(rng, types, mu=0.8, tilt=0.6)) for _ in range(200)
    )


def test_api_refuses_before_any_search_and_rho_hat_still_answers():
    eligibility = Eligibility(box_model(), contact_specs(6, type="fpc"), torque_scale=1.0)
    for call in (
        lambda: heuristic(eligibility, seed=0),
        lambda: iterative(eligibility, [0, 1, 2, 3, 4, 5]),
        lambda: Placer(eligibility),
        lambda: plan(eligibility, seeds=1, seed=0),
    ):
        with pytest.raises(ValueError, match="6 frictionless contacts .* at least 7"):
            call()
    assert eligibility.evaluations == 0  # nothing was searched
    assert np.isfinite(eligibility([0, 1, 2, 3, 4, 5]).rho_hat)
    with pytest.raises(ValueError, match="^--contacts: "):
        require_closure_count(eligibility.specs, "--contacts")


@pytest.fixture
def box_file(tmp_path):
    path = tmp_path / "box.model.json"
    save_model(box_model(), path)
    return str(path)


@pytest.mark.parametrize(
    "argv",
    [
        ["select", "{m}", "--contacts", "6", "--type", "fpc"],
        ["plan", "{m}", "--contacts", "2", "--type", "pcwf", "--out", "{out}"],
        ["place", "{m}", "--elements", "0,1", "--type", "pcwf,sfce", "--mu", "0.3,0"],
    ],
)
def test_cli_exits_2_with_the_reason(capsys, box_file, tmp_path, argv):
    out = tmp_path / "out"
    code = cli.main([a.format(m=box_file, out=out) for a in argv])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == "" and not out.exists()
    assert captured.err.startswith("error: ") and "can never give force closure" in captured.err
    assert f" {argv[2]}: " in captured.err  # the flag is named
    assert len(captured.err.strip().splitlines()) == 1


def test_cli_eligibility_and_rho_still_answer(capsys, box_file, tmp_path):
    code = cli.main(["eligibility", box_file, "--elements", "0,1,2", "--type", "fpc", "--json"])
    assert code == 0 and "rho_hat" in json.loads(capsys.readouterr().out)
    path = tmp_path / "two.contacts.json"
    path.write_text(json.dumps(ContactSet(tuple(_ring(2, ["pcwf"] * 2))).to_dict()))
    code = cli.main(["rho", str(path), "--json"])
    assert code == 0 and not json.loads(capsys.readouterr().out)["force_closure"]


def test_study_with_an_impossible_grid_point_is_refused(tmp_path, capsys):
    save_model(box_model(), tmp_path / "box.model.json")
    path = tmp_path / "s.toml"
    path.write_text('models = "box.model.json"\ntype = ["pcwf", "fpc"]\ncontacts = 4\n')
    code = cli.main(["study", str(path), "--out", str(tmp_path / "out"), "--serial"])
    err = capsys.readouterr().err
    assert code == 2 and "4 frictionless contacts (fpc)" in err and "at least 7" in err
    assert not (tmp_path / "out").exists()
