"""Numbers as printed: a certified value to its bracket's digits, lengths to the model's accuracy,
no float noise, no ``-0.000``, no parameter that plays no part."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from closure_nlp.base.formatting import bracket, certain, fixed, length, lengths
from closure_nlp.cli.main import main
from closure_nlp.model.elements import load_model

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_a_value_rounding_to_zero_has_no_sign():
    assert fixed(-0.00001, 4) == "0.0000"
    assert fixed(-0.0, 2) == "0.00"
    assert fixed(-0.00006, 4) == "-0.0001"


@pytest.mark.parametrize(
    "bounds, value, text",
    [
        ((-0.5249791, -0.5249786), -0.5249791, "-0.524979"),  # width 5e-7: six decimals
        ((-3.0001e-5, -2.9999e-5), -3.0001e-5, "-0.00003000"),  # never -0.0000
        ((-0.31, -0.27), -0.31, "-0.3"),  # an unconverged bracket says little
    ],
)
def test_a_certified_value_shows_the_digits_its_bracket_pins_down(bounds, value, text):
    assert certain(value, bounds) == text
    lo, hi = bracket(bounds)
    assert len(lo.split(".")[1]) == len(text.split(".")[1]) + 1
    assert float(lo) <= value + 1e-15 and (lo != hi or bounds[0] == bounds[1])


def test_lengths_follow_the_part_not_the_unit():
    """The lamp in mm and the same lamp in metres show the same physical digits."""
    lamp = load_model(MODELS / "lamp.model.json")  # radius 60 mm: 1e-4 R = 6 um -> 0.001 mm
    assert length(-40.1674136, lamp) == "-40.167"
    shrunk = tuple(replace(e, vertices=e.vertices / 1000) for e in lamp.elements)
    metres = replace(lamp, elements=shrunk)
    assert metres.radius == pytest.approx(0.06)
    assert lengths([-0.0401674136, 4.7e-12], metres) == "-0.040167 0.000000"


def test_the_command_line_prints_mu_s_only_for_soft_fingers(capsys):
    lamp = str(MODELS / "lamp.model.json")
    assert main(["eligibility", lamp, "--elements", "48,0,53,34"]) == 0
    point = capsys.readouterr().out
    assert "mu_s" not in point and "torque scale 0.0166667" in point
    assert main(["eligibility", lamp, "--elements", "48,0,53,34", "--type", "sfce"]) == 0
    soft = capsys.readouterr().out
    assert "mu_s 0.6 mm (auto: 0.01 x radius)" in soft
    # rho_hat to its bracket's digits: the value rounds the bracket, the bounds show one more
    found = re.search(r"rho_hat = (\S+) .*certified (\S+) <= rho_hat <= (\S+)", soft)
    value, lo, hi = found.groups()
    decimals = len(value.split(".")[1])
    assert len(lo.split(".")[1]) == len(hi.split(".")[1]) == decimals + 1
    assert float(lo) - 0.5 * 10**-decimals <= float(value) <= float(hi) + 0.5 * 10**-decimals
    assert float(hi) - float(lo) <= 1.1 * 10**-decimals
