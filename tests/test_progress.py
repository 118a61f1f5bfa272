"""Progress: every long step reports to the API's callback; the CLI draws it on a terminal only."""

from __future__ import annotations

import functools
import io
import sys

import pytest
import tqdm

from closure_nlp.base.progress import STAGES, ProgressLine
from closure_nlp.cli import main as cli
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import save_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.planning.plan import plan
from tests.shapes import box_model


def test_plan_reports_every_long_step():
    specs = contact_specs(2, type="sfce", mu=0.4, mu_s=0.5)
    hand = Eligibility(box_model(10.0), specs, torque_scale=0.1)
    events = []
    options = PlacementOptions(
        starts=2, extra_starts=0, neighbour_moves=0, bound_cells=3, time_budget=5.0
    )
    result = plan(hand, seeds=1, seed=1, placement=options, progress=lambda *e: events.append(e))
    stages = [e[0] for e in events]
    assert set(stages) <= set(STAGES)
    for stage in ("heuristic", "iterative", "placement round", "placement start"):
        assert stage in stages, stage
    assert [e[1] for e in events if e[0] == "placement start"] == [1, 2]
    assert [e[1] for e in events if e[0] == "certification"] == [0, 1]
    assert ("certification", 1, result.placement.exchange_rho) in events
    cells = [e for e in events if e[0] == "capacity bound"]
    if cells:  # the ceiling's cells, after the exchange method; the ceiling never rises
        assert events[-1] == cells[-1] and cells[-1][2] == result.placement.capacity_bound
        assert all(a[2] >= b[2] for a, b in zip(cells, cells[1:]))
    rounds = [e for e in events if e[0] == "placement round"]
    assert len(rounds) <= result.placement.rounds  # a round that predicts no gain ends silently
    iterative = [e for e in events if e[0] == "iterative"]
    # The steps report the search's values; the history's last entry is the final set's
    # certified value, which lies in its bounds.
    values = [v for _, v in result.iterative.history[1:]]
    assert [e[2] for e in iterative][:-1] == values[:-1]
    lo, hi = result.iterative.bounds
    assert lo <= values[-1] <= hi


def test_progress_line_gives_an_eta_when_the_total_is_known():
    out = io.StringIO()
    line = ProgressLine({"placement start": 4}, file=out)
    line("placement start", 1, -0.5)
    assert "placement start 1/4 (ETA" in line.bar.desc and "rho=-0.5" in line.bar.desc
    line("iterative", 3, -0.25)
    assert line.bar.desc.startswith("iterative 3 rho_hat=-0.25")
    line.close()


@pytest.fixture
def box_file(tmp_path):
    path = tmp_path / "box.model.json"
    save_model(box_model(), path)
    return str(path)


@pytest.mark.parametrize(("terminal", "quiet"), [(True, False), (True, True), (False, False)])
def test_cli_draws_progress_on_a_terminal_only(capsys, monkeypatch, box_file, terminal, quiet):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: terminal)
    # the box's selection can end within tqdm's refresh interval (0.1 s): draw every step
    monkeypatch.setattr(tqdm, "tqdm", functools.partial(tqdm.tqdm, mininterval=0))
    argv = ["select", box_file, "--contacts", "4", "--json"]
    code = cli.main(argv + (["--quiet"] if quiet else []))
    captured = capsys.readouterr()
    assert code == 0 and captured.out.startswith("{")
    if terminal and not quiet:
        assert "heuristic" in captured.err and "rho_hat=" in captured.err
    else:
        assert captured.err == ""
