"""Load factors where a plan reports: its seconds, report.json, summary.md and pictures."""

import time
from pathlib import Path

import pytest

import closure_nlp as c
from closure_nlp.placement.place import Placer
from closure_nlp.planning import load_steering

ROOT = Path(__file__).resolve().parents[1]
LAMP = ROOT / "models" / "lamp.model.json"
LOADS = {
    "units": {"force": "N"},
    "loads": [
        {"name": "gravity", "force": [0, 0, -1], "point": [0, 0, -20]},
        {"name": "push_x", "force": [0.5, 0, 0], "point": [0, 0, 10]},
    ],
}
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
