"""``--loads`` and ``--objective`` on the command line: keys, text, errors, steering."""

import json
from pathlib import Path

import pytest

from closure_nlp.cli.main import main

from .shapes import LAMP_LOADS

ROOT = Path(__file__).resolve().parents[1]
BOX = ROOT / "examples" / "box_7fpc.contacts.json"
LAMP = ROOT / "models" / "lamp.model.json"
LOADS = LAMP_LOADS


@pytest.fixture
def loads_file(tmp_path):
    path = tmp_path / "loads.json"
    path.write_text(json.dumps(LOADS))
    return str(path)


def run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_rho_reports_each_case_and_the_least(loads_file, capsys):
    code, out, err = run(["rho", str(BOX), "--loads", loads_file, "--json"], capsys)
    assert code == 0 and err == ""
    answer = json.loads(out)
    cases = answer["loads"]
    assert [c["name"] for c in cases] == ["gravity", "push_x", "twist"]
    for case in cases:
        lo, hi = case["bounds"]
        assert lo == case["load_factor"] <= hi <= lo * (1 + 1e-6) + 1e-12
    assert answer["load_factor"] == min(c["load_factor"] for c in cases)
    code, out, _ = run(["rho", str(BOX), "--loads", loads_file], capsys)
    assert code == 0 and "load factor" in out and "push_x" in out


@pytest.mark.parametrize(
    "content,needle",
    [
        ('{"loads": [{"name": "a", "force": [0, 0, NaN]}]}', "loads[0].force"),
        ('{"loads": [{"name": "a", "force": [0, 0, 0]}]}', "zero"),
        ('{"loads": [{"name": "a", "force": [1, 0, 0], "pont": [0, 0, 0]}]}', "pont"),
        ("{not json", "JSON"),
    ],
)
def test_bad_loads_exit_2_naming_the_field(tmp_path, capsys, content, needle):
    path = tmp_path / "bad.json"
    path.write_text(content)
    code, out, err = run(["rho", str(BOX), "--loads", str(path)], capsys)
    assert code == 2 and out == "" and needle in err and err.startswith("error:")
    assert len(err.strip().splitlines()) == 1


def test_objective_loads_needs_loads(capsys):
    code, out, err = run(
        ["place", str(LAMP), "--elements", "36,10,40,14", "--type", "pcwf", "--objective", "loads"],
        capsys,
    )
    assert code == 2 and out == "" and "--objective" in err


@pytest.mark.slow
def test_steering_by_loads_holds_at_least_as_much_as_steering_by_rho(loads_file, capsys):
    place = ["place", str(LAMP), "--elements", "36,10,40,14", "--type", "pcwf", "--json"]
    code, out, _ = run([*place, "--loads", loads_file, "--objective", "rho"], capsys)
    by_rho = json.loads(out)
    code_l, out, _ = run([*place, "--loads", loads_file], capsys)
    by_loads = json.loads(out)
    assert code == code_l == 0
    assert by_rho["objective"] == "rho" and by_loads["objective"] == "loads"
    assert by_loads["load_factor"] >= by_rho["load_factor"]
    assert by_loads["load_factor"] > 1.1 * by_rho["load_factor"]  # it gains here, measurably


def test_the_keys_loads_bring_are_in_formats_md(loads_file, capsys):
    from tests.test_formats_contract import FORMATS, code_spans, keys, missing

    spans = code_spans(FORMATS.read_text(encoding="utf-8"))
    found = set()
    code, out, _ = run(["rho", str(BOX), "--loads", loads_file, "--json"], capsys)
    keys(json.loads(out), found)
    argv = ["place", str(LAMP), "--elements", "36,10,40,14", "--type", "pcwf", "--starts", "1"]
    code, out, _ = run([*argv, "--loads", loads_file, "--json", "--no-bound"], capsys)
    keys(json.loads(out), found)
    assert not missing(found, spans)


@pytest.mark.slow
def test_steering_does_not_depend_on_the_loads_size():
    """The same cases 100 times larger steer the same way: factors 100 times smaller."""
    import closure_nlp as c
    from closure_nlp.criterion.load_factor import load_factors
    from closure_nlp.placement.place import Placer

    model = c.load_model(LAMP)
    eligibility = c.Eligibility(model, c.contact_specs(4, type="pcwf"), torque_scale="auto")
    options = c.PlacementOptions(bound=False, starts=1, neighbour_moves=0)
    big = {"loads": [{**case} for case in LOADS["loads"]]}
    for case in big["loads"]:
        case["force"] = [100 * x for x in case["force"]]
        if "torque" in case:
            case["torque"] = [100 * x for x in case["torque"]]
    least = []
    for loads in (LOADS, big):
        placed = Placer(eligibility, options, loads=loads)([36, 10, 40, 14])
        least.append(load_factors(placed.contact_set, loads).load_factor)
    assert least[1] * 100 == pytest.approx(least[0], rel=1e-4)
