"""Load factors where a plan reports: its seconds, report.json, summary.md and pictures."""

import json
import time
from pathlib import Path

import pytest

import closure_nlp as c
from closure_nlp.placement.place import Placer
from closure_nlp.planning import load_steering

from .shapes import LAMP_LOADS

ROOT = Path(__file__).resolve().parents[1]
LAMP = ROOT / "models" / "lamp.model.json"
LOADS = {**LAMP_LOADS, "loads": LAMP_LOADS["loads"][:2]}  # without the twist
QUICK = c.PlacementOptions(bound=False, starts=1, neighbour_moves=0)


@pytest.fixture(scope="module")
def lamp_plan():
    model = c.load_model(LAMP)
    eligibility = c.Eligibility(model, c.contact_specs(4, type="pcwf"), torque_scale="auto")
    return eligibility, c.plan(eligibility, seed=0, placement=QUICK)


def test_plan_seconds_count_the_load_steering(lamp_plan, monkeypatch):
    eligibility, planned = lamp_plan
    place = Placer.__call__

    def slow(self, *args, **kwargs):  # each re-placement 0.3 s longer
        time.sleep(0.3)
        return place(self, *args, **kwargs)

    monkeypatch.setattr(load_steering.Placer, "__call__", slow)
    t0 = time.perf_counter()
    steered = load_steering.steer_by_loads(eligibility, planned, LOADS, QUICK)
    elapsed = time.perf_counter() - t0
    assert steered.seconds - planned.seconds >= 0.3  # at least one set re-placed
    assert steered.seconds - planned.seconds <= elapsed


def run(args, capsys):
    from closure_nlp.cli.main import main

    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def loads_file(tmp_path):
    path = tmp_path / "loads.json"
    path.write_text(json.dumps(LOADS))
    return str(path)


@pytest.mark.slow
def test_plan_report_carries_the_factors(tmp_path, loads_file, capsys):
    out = tmp_path / "plan"
    argv = ["plan", str(LAMP), "--contacts", "4", "--type", "pcwf", "--seeds", "1"]
    argv += ["--starts", "1", "--no-bound", "--loads", loads_file, "--out", str(out), "--json"]
    code, text, err = run(argv, capsys)
    assert code == 0, err
    answer = json.loads(text)
    report = json.loads((out / "report.json").read_text())
    assert [c["name"] for c in report["loads"]] == ["gravity", "push_x"]
    assert report["load_factor"] == answer["load_factor"] > 0
    assert report["options"]["objective"] == "loads"
    assert report["options"]["loads"]["loads"][0]["name"] == "gravity"
    # the factors are those of the contacts written, by the independent SOCP
    from closure_nlp.criterion.crosscheck import load_factor_cvxpy
    from closure_nlp.report.plan_report import load_contacts

    contacts = load_contacts(out / "contacts.json")
    loads = c.load_loads(loads_file)
    for case, entry in zip(loads.cases, report["loads"]):
        wrench = case.wrench(contacts.reference_point, contacts.torque_scale)
        socp, status = load_factor_cvxpy(contacts, wrench)
        assert status == "optimal"
        assert entry["bounds"][0] <= socp * (1 + 1e-5) and socp <= entry["bounds"][1] * (1 + 1e-5)
    summary = (out / "summary.md").read_text()
    assert "Load factors" in summary and "| push_x |" in summary
    assert (out / "placement.png").stat().st_size > 0


def test_load_arrows_one_per_case_with_factors_in_the_legend():
    from closure_nlp.criterion.load_factor import LoadFactor, LoadFactors
    from closure_nlp.report.drawing import draw_loads, draw_model, pyplot

    model = c.load_model(LAMP)
    loads = dict(
        LOADS, loads=[*LOADS["loads"], {"name": "twist", "force": [0, 0, 0], "torque": [0, 0, 1]}]
    )
    plt = pyplot()
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    draw_model(model, None, ax)
    factor = LoadFactor(2.5, (2.5, 2.5), False, True, None)
    factors = LoadFactors(("gravity", "push_x", "twist"), (factor, factor, factor))
    assert draw_loads(ax, loads, model, factors) == 2  # the torque alone has no arrow
    gids = [a.get_gid() for a in ax.collections if (a.get_gid() or "").startswith("load:")]
    assert sorted(gids) == ["load:gravity", "load:push_x"]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "push_x (load factor 2.5)" in labels and "twist (load factor 2.5)" in labels
    plt.close(fig)


def test_show_draws_the_loads(tmp_path, loads_file, capsys, monkeypatch):
    from closure_nlp.report import drawing

    drawn = []
    original = drawing.draw_loads

    def spy(*args, **kwargs):
        drawn.append(original(*args, **kwargs))
        return drawn[-1]

    monkeypatch.setattr(drawing, "draw_loads", spy)
    png = tmp_path / "lamp.png"
    code, out, err = run(["show", str(LAMP), "--out", str(png), "--loads", loads_file], capsys)
    assert code == 0 and png.stat().st_size > 0 and drawn == [2]
    code, out, err = run(
        ["show", str(LAMP), "--out", str(tmp_path / "s.glb"), "--loads", loads_file], capsys
    )
    assert code == 2 and "--loads" in err and not (tmp_path / "s.glb").exists()
