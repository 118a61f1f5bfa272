"""docs/formats.md is the user contract, checked against the command line itself.

Every subcommand and every long option of the parser must be named in formats.md, and every key
of every JSON answer (nested keys and keys of dicts inside lists included), of a plan's
``report.json``, of a study's ``study.json`` and every column of its ``results.csv`` must appear
in backticks there. The commands run on small bundled inputs with the smallest budgets.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
from pathlib import Path

import pytest

from closure_nlp.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
FORMATS = ROOT / "docs" / "formats.md"
LAMP = ROOT / "models" / "lamp.model.json"
BOX_CONTACTS = ROOT / "examples" / "box_7fpc.contacts.json"
# A tolerance on every command, so that the keys only a tolerance brings are seen too.
TOLERANCE = ["--position-tolerance", "0.05", "--normal-tolerance", "0.5"]


# --- what formats.md documents ------------------------------------------------------------------


def code_spans(text: str) -> list[str]:
    """The inline code spans (single backticks) of a Markdown text, fenced blocks left out."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.findall(r"`([^`\n]+)`", text)


def documented(name: str, spans: list[str]) -> bool:
    """Whether ``name`` appears in a code span as a whole word (not inside a longer name or a
    flag: ``position`` is not documented by ``--position-tolerance``). A span ``prefix_*``
    documents ``prefix_X`` for every documented ``X``."""
    word = re.compile(rf"(?<![\w-]){re.escape(name)}(?![\w-])")
    if any(word.search(span) for span in spans):
        return True
    for span in spans:
        for prefix in re.findall(r"(?<![\w-])(\w+_)\*", span):
            if name.startswith(prefix) and documented(name[len(prefix) :], spans):
                return True
    return False


@pytest.fixture(scope="module")
def spans() -> list[str]:
    return code_spans(FORMATS.read_text(encoding="utf-8"))


def missing(names, spans) -> list[str]:
    return sorted({n for n in names if not documented(n, spans)})


def test_the_checker_sees_a_missing_key():
    spans = code_spans("keys `rho`, `bounds` (and `heuristic_*`), `--gap G`\n```\nhidden\n```\n")
    assert documented("rho", spans) and documented("heuristic_bounds", spans)
    assert documented("--gap", spans)
    assert not documented("hidden", spans)  # fenced blocks do not count
    assert not documented("gap", spans)  # a flag is not a key
    assert not documented("heuristic_gap", spans)
    assert not documented("rh", spans)


# --- the parser: commands and flags ---------------------------------------------------------------


def commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    [sub] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def test_every_command_and_flag_is_in_formats_md(spans):
    text = FORMATS.read_text(encoding="utf-8")
    found = commands()
    expected = {"rho", "eligibility", "select", "place", "plan", "characterize", "show", "study"}
    assert expected <= set(found)
    absent = [name for name in found if f"closure-nlp {name}" not in text]
    flags = {
        option
        for parser in [build_parser(), *found.values()]
        for action in parser._actions
        for option in action.option_strings
        if option.startswith("--") and option != "--help"
    }
    absent += missing(flags, spans)
    assert not absent, f"not in docs/formats.md: {absent}"


# --- the keys of every answer ---------------------------------------------------------------------


def keys(value, into: set | None = None) -> set[str]:
    """Every key of ``value``: of its dicts, at any depth, inside lists too."""
    into = set() if into is None else into
    if isinstance(value, dict):
        for key, item in value.items():
            into.add(str(key))
            keys(item, into)
    elif isinstance(value, list):
        for item in value:
            keys(item, into)
    return into


def run_json(capsys, argv: list[str], status: int = 0) -> list[dict]:
    capsys.readouterr()
    code = main([*argv, "--json", "--quiet"])
    out = capsys.readouterr().out
    assert code == status, out
    return [json.loads(line) for line in out.splitlines() if line.strip()]


@pytest.fixture(autouse=True)
def _agg(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.setenv("MPLBACKEND", "Agg")


def assert_documented(found: set[str], spans, where: str) -> None:
    absent = missing(found, spans)
    assert not absent, f"keys of {where} not in backticks in docs/formats.md: {absent}"


def test_rho_eligibility_select_keys(capsys, spans):
    found = set()
    for answer in run_json(capsys, ["rho", str(BOX_CONTACTS), *TOLERANCE]):
        keys(answer, found)
    for answer in run_json(capsys, ["eligibility", str(LAMP), "--elements", "48,9,53,26"]):
        keys(answer, found)
    for answer in run_json(
        capsys, ["eligibility", str(LAMP), "--elements", "48,9,53,26", *TOLERANCE]
    ):
        keys(answer, found)
    for algorithm in ("heuristic", "iterative"):
        argv = ["select", str(LAMP), "--contacts", "4", "--algorithm", algorithm, *TOLERANCE]
        for answer in run_json(capsys, argv):
            keys(answer, found)
    assert_documented(found, spans, "rho, eligibility and select")


def tiny_mesh(folder: Path) -> Path:
    """A small closed mesh: a box with a cylinder beside it, merged (facets and segments)."""
    import trimesh

    box = trimesh.creation.box(extents=(20.0, 20.0, 10.0))
    rod = trimesh.creation.cylinder(radius=4.0, height=30.0, sections=24)
    rod.apply_translation((12.0, 0.0, 0.0))
    mesh = trimesh.util.concatenate([box, rod])
    path = folder / "part.stl"
    mesh.export(path)
    return path


def test_characterize_and_show_keys(capsys, spans, tmp_path):
    mesh = tiny_mesh(tmp_path)
    model = tmp_path / "part.model.json"
    argv = ["characterize", str(mesh), "--out", str(model), "--units", "mm", "--merge-bodies"]
    found = keys(run_json(capsys, argv))
    found |= keys(run_json(capsys, ["show", str(model), "--out", str(tmp_path / "part.png")]))
    argv = ["show", str(LAMP), "--contacts", str(BOX_CONTACTS), "--out", str(tmp_path / "l.png")]
    found |= keys(run_json(capsys, argv))
    assert_documented(found, spans, "characterize and show")


def test_place_keys(capsys, spans, tmp_path):
    out = tmp_path / "placed.contacts.json"
    argv = ["place", str(LAMP), "--elements", "48,9,53,26", "--starts", "1", "--out", str(out)]
    found = keys(run_json(capsys, [*argv, *TOLERANCE]))
    found |= keys(json.loads(out.read_text()))
    assert_documented(found, spans, "place and its --out")


def test_plan_keys(capsys, spans, tmp_path):
    """Two seeds (in one worker process) for the seeds' spread, with a tolerance."""
    out = tmp_path / "plan"
    argv = ["plan", str(LAMP), "--contacts", "4", "--seeds", "2", "--workers", "1"]
    argv += ["--starts", "1", "--out", str(out), *TOLERANCE]
    found = keys(run_json(capsys, argv))
    found |= keys(json.loads((out / "report.json").read_text()))
    found |= keys(json.loads((out / "contacts.json").read_text()))
    assert_documented(found, spans, "plan, report.json and contacts.json")


STUDY = """name = "tiny"
models = ["box.model.json"]
contacts = 4
mu = 0.2
seeds = 1

[placement]
starts = 1
"""


def test_study_keys(capsys, spans, tmp_path):
    from closure_nlp.model.elements import save_model
    from tests.shapes import box_model

    save_model(box_model(), tmp_path / "box.model.json")
    study = tmp_path / "tiny.toml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    found = keys(run_json(capsys, ["study", str(study), "--out", str(out), "--serial"]))
    found |= keys(json.loads((out / "study.json").read_text()))
    with open(out / "results.csv", newline="") as f:
        found |= set(next(csv.reader(f)))
    assert_documented(found, spans, "study --json, study.json and results.csv")
