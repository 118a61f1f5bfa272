"""The how-tos in docs/ reproduce: every command prints what the page shows under it (seconds
aside; a plan's decimals within the placement's machine-to-machine spread), and every picture the
page shows is drawn by one of its commands."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from closure_nlp.cli.main import main

from . import doc_blocks

ROOT = Path(__file__).resolve().parents[1]
HOWTOS = sorted((ROOT / "docs").glob("howto-*.md"))
PAGES = [
    pytest.param(page, marks=[pytest.mark.slow] if "closure-nlp plan" in page.read_text() else [])
    for page in HOWTOS
]


def _redirect(argv: list[str], renamed: dict[str, Path], tmp_path: Path) -> None:
    """Every ``--out`` to a fresh place under ``tmp_path`` (recorded in ``renamed``), and every
    argument under an earlier command's output to where that output went."""
    for k, arg in enumerate(argv):
        for given, actual in renamed.items():
            if arg == given or arg.startswith(given + "/"):
                argv[k] = str(actual) + arg[len(given) :]
        if k and argv[k - 1] == "--out":
            renamed[arg] = tmp_path / f"{len(renamed)}-{Path(arg).name}"
            argv[k] = str(renamed[arg])


def test_there_are_howtos_with_commands():
    assert len(HOWTOS) >= 2
    for page in HOWTOS:
        commands = doc_blocks.shown(page, "sh")
        assert commands, page
        assert all(c.strip().startswith("closure-nlp ") for c, _ in commands), page


@pytest.mark.parametrize("page", PAGES)
def test_howto_commands_print_what_the_page_shows(page, monkeypatch, tmp_path, capsys):
    """The page's commands in order (a later one may read what an earlier one wrote)."""
    monkeypatch.chdir(ROOT)
    renamed: dict[str, Path] = {}
    for command, expected in doc_blocks.shown(page, "sh"):
        argv = shlex.split(command.strip())[1:]
        _redirect(argv, renamed, tmp_path)
        assert main(argv) == 0, command
        printed = capsys.readouterr().out
        for given, actual in renamed.items():
            printed = printed.replace(str(actual), given)
            assert actual.exists(), given
        if "plan" in argv:
            assert doc_blocks.same_plan(doc_blocks.normal(printed), doc_blocks.normal(expected))
        else:
            assert doc_blocks.normal(printed) == doc_blocks.normal(expected), command


@pytest.mark.parametrize("page", HOWTOS, ids=lambda p: p.stem)
def test_every_picture_shown_is_drawn_by_a_command(page):
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", page.read_text())
    assert pictures, page
    drawn = {
        (page.parent / Path(a)).resolve().name
        for code, _ in doc_blocks.shown(page, "sh")
        for a in shlex.split(code.strip())
        if a.endswith(".png")
    }
    for picture in pictures:
        assert (page.parent / picture).exists(), picture
        assert Path(picture).name in drawn, picture


SNIPPETS = [
    pytest.param(page, i, marks=pytest.mark.slow, id=f"{page.stem}-python{i}")
    for page in HOWTOS
    for i, (lang, _) in enumerate(doc_blocks.fenced_blocks(page.read_text()))
    if lang == "python"
]


@pytest.mark.parametrize(("page", "index"), SNIPPETS)
def test_howto_python_runs(page, index, monkeypatch, capsys):
    """The page's Python runs as written and prints a number where it prints one."""
    lang, code = doc_blocks.fenced_blocks(page.read_text())[index]
    monkeypatch.chdir(ROOT)
    exec(compile(code, f"{page.name} block {index}", "exec"), {"__name__": "howto"})
    printed = capsys.readouterr().out
    if "print(" in code:
        assert doc_blocks.NUMBER.search(printed), printed
