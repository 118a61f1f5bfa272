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
COMMANDS = [
    pytest.param(page, i, marks=[pytest.mark.slow] if "plan" in code else [], id=f"{page.stem}-{i}")
    for page in HOWTOS
    for i, (code, _) in enumerate(doc_blocks.shown(page, "sh"))
]


def _outputs(argv: list[str], tmp_path: Path) -> dict[str, Path]:
    """Point every ``--out`` at a fresh place under ``tmp_path``; the page's name -> that place."""
    renamed = {}
    for k, flag in enumerate(argv[:-1]):
        if flag == "--out":
            given = argv[k + 1]
            renamed[given] = tmp_path / Path(given).name
            argv[k + 1] = str(renamed[given])
    return renamed


def test_there_are_howtos_with_commands():
    assert HOWTOS
    for page in HOWTOS:
        commands = doc_blocks.shown(page, "sh")
        assert commands, page
        assert all(c.strip().startswith("closure-nlp ") for c, _ in commands), page


@pytest.mark.parametrize(("page", "index"), COMMANDS)
def test_howto_command_prints_what_the_page_shows(page, index, monkeypatch, tmp_path, capsys):
    command, expected = doc_blocks.shown(page, "sh")[index]
    argv = shlex.split(command.strip())[1:]
    renamed = _outputs(argv, tmp_path)
    monkeypatch.chdir(ROOT)
    assert main(argv) == 0
    printed = capsys.readouterr().out
    for given, actual in renamed.items():
        printed = printed.replace(str(actual), given)
        assert actual.exists(), given
    if "plan" in argv:
        assert doc_blocks.same_plan(doc_blocks.normal(printed), doc_blocks.normal(expected))
    else:
        assert doc_blocks.normal(printed) == doc_blocks.normal(expected)


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
