"""However tight a certificate or small a tolerance, printed numbers stop at 7 significant
digits; words about robustness appear only when a tolerance is set."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from closure_nlp.base.formatting import bracket, certain, lengths
from closure_nlp.cli.main import main
from closure_nlp.cli.setup import placement_text
from closure_nlp.contact.accuracy import ModelTolerance
from closure_nlp.model.elements import load_model

MODELS = Path(__file__).resolve().parents[1] / "models"
VALUES = [0.0, 3e-12, -2.9e-6, -3.0001e-5, -0.3230110912345, 1.2, -12.3456789123, 12345.6789]


def significant(text: str) -> int:
    """Significant digits a fixed-point number shows (a zero shows none past its first)."""
    digits = text.lstrip("-").replace(".", "").lstrip("0")
    return max(len(digits), 1)


@pytest.mark.parametrize("value", VALUES)
def test_a_bracket_of_width_1e_15_shows_at_most_7_significant_digits(value):
    bounds = (value - 5e-16, value + 5e-16)
    for text in (certain(value, bounds), *bracket(bounds)):
        assert significant(text) <= 7, text
    assert float(certain(value, bounds)) == pytest.approx(value, abs=1e-6, rel=1e-6)


def test_zero_within_a_tiny_bracket_is_zero_to_six_decimals():
    assert certain(0.0, (-1e-15, 1e-15)) == "0.000000"
    assert certain(1.2, (1.2, 1.2)) == "1.200000"


def test_lengths_with_a_tolerance_near_1e_15_stop_at_7_significant_digits_of_the_part():
    lamp = load_model(MODELS / "lamp.model.json")  # mm, radius 60
    tight = replace(lamp, tolerance=ModelTolerance(position=1e-15, normal_deg=0.0))
    text = lengths([-40.16741361234567, 0.1234567891234], tight)
    assert text == "-40.16741 0.12346"  # 7 digits of 60 mm: 1e-5 mm
    metres = replace(
        tight, elements=tuple(replace(e, vertices=e.vertices / 1000) for e in lamp.elements)
    )
    assert lengths([-0.04016741361234567, 0.0001234567891234], metres) == "-0.04016741 0.00012346"


class _Contacts(list):
    """What placement_text reads of a contact set: its length and its contacts."""

    @property
    def contacts(self) -> tuple:
        return tuple(self)


def fake_result(robust=None, shift=0.0):
    """What placement_text reads of a placement: rho certified to 1e-15, one contact."""
    return SimpleNamespace(
        force_closure=True,
        marginal=False,
        robust=robust,
        shift=shift,
        rho=-0.3230110912345,
        bounds=(-0.3230110912350, -0.3230110912340),
        converged=True,
        start_rho=-0.1,
        seconds=1.0,
        capacity_bound=None,
        contacts=[SimpleNamespace(element=3, position=np.array([0.1234567891234, 0.0, -40.0]))],
        contact_set=_Contacts([None]),  # the one placed contact, none already in place
    )


def test_placement_text_shows_7_digits_and_no_robust_words_without_a_tolerance():
    lamp = load_model(MODELS / "lamp.model.json")
    bare = replace(lamp, tolerance=ModelTolerance())
    text = placement_text(fake_result(), bare)
    assert "robust" not in text
    rho = re.search(r"rho = (\S+)", text).group(1)
    assert rho == "-0.3230111"
    for number in re.findall(r"-?\d+\.\d+", text):
        assert significant(number) <= 7, (number, text)
    tight = replace(lamp, tolerance=ModelTolerance(position=1e-15, normal_deg=0.0))
    text = placement_text(fake_result(robust=True, shift=1e-15), tight)
    assert "robust within the model's tolerance" in text
    for number in re.findall(r"-?\d+\.\d+", text):
        assert significant(number) <= 7, (number, text)


def test_characterize_claims_robust_verdicts_only_with_a_tolerance(tmp_path, capsys):
    mesh = tmp_path / "box.stl"
    trimesh.creation.box((1.0, 2.0, 3.0)).export(mesh)  # exact: a tolerance of 0
    out = tmp_path / "box.model.json"
    assert main(["characterize", str(mesh), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "positions within 0 m" in text and "robust" not in text
    argv = ["characterize", str(mesh), "--out", str(out), "--position-tolerance", "0.001"]
    assert main(argv) == 0
    assert "verdicts are robust within it" in capsys.readouterr().out


def test_a_plans_total_says_what_the_first_compile_took(monkeypatch, capsys):
    """The plan's own total leaves the kernels' compile out; a cold start says it beside."""
    from closure_nlp.criterion import warm_up

    monkeypatch.setattr(warm_up, "warm_up", lambda *args, **kwargs: 12.3)
    lamp = Path(__file__).resolve().parents[1] / "models" / "lamp.model.json"
    argv = ["plan", str(lamp), "--contacts", "4", "--seeds", "1", "--starts", "1", "--no-bound"]
    assert main([*argv, "--quiet"]) == 0
    assert "(and 12.3 s compiling the kernels, once)" in capsys.readouterr().out
    monkeypatch.setattr(warm_up, "warm_up", lambda *args, **kwargs: None)  # from the cache
    assert main([*argv, "--quiet"]) == 0
    assert "compiling" not in capsys.readouterr().out
