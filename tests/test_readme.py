"""The README's tour reproduces: every command and every Python snippet prints what the README
shows under it (seconds aside), and a snippet and the command that does the same give the same
numbers to the digits printed (the API and the CLI share their defaults)."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from closure_nlp.cli.main import main

from . import doc_blocks

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def shown(language: str) -> list[tuple[str, str]]:
    return doc_blocks.shown(README, language)


COMMANDS = [code.strip() for code, _ in shown("sh")]
SNIPPETS = [code for code, _ in shown("python")]


def _slow_if_plan(items, key):
    return [
        pytest.param(i, marks=pytest.mark.slow, id=key(x))
        if "plan" in x
        else pytest.param(i, id=key(x))
        for i, x in enumerate(items)
    ]


def _normal(text: str, out_dir: Path | None = None) -> list[str]:
    return doc_blocks.normal(text, out_dir, "out/lamp")


def test_the_readme_shows_commands_and_snippets():
    assert len(COMMANDS) >= 3 and len(SNIPPETS) >= 2
    assert all(c.startswith("closure-nlp ") and "\n" not in c for c in COMMANDS)


@pytest.mark.parametrize("index", _slow_if_plan(COMMANDS, lambda c: c.split()[1]))
def test_command_prints_what_the_readme_shows(index, monkeypatch, tmp_path, capsys):
    command, expected = shown("sh")[index]
    argv = shlex.split(command)[1:]
    out_dir = None
    if "--out" in argv:  # the README's out/lamp, written to a fresh folder here
        k = argv.index("--out") + 1
        out_dir = tmp_path / "lamp"
        argv[k] = str(out_dir)
    monkeypatch.chdir(ROOT)
    assert main(argv) == 0
    printed = capsys.readouterr().out
    if "plan" in argv:
        assert doc_blocks.same_plan(_normal(printed, out_dir), _normal(expected))
    else:
        assert _normal(printed, out_dir) == _normal(expected)
    if out_dir is not None:  # the summary: no float noise, no mu_s for point contacts
        summary = (out_dir / "summary.md").read_text()
        value = re.search(r"\brho = (\S+) \(force closure\)", printed).group(1)
        assert f"rho = {value} (force closure)" in summary
        assert "mu_s" not in summary and not re.search(r"\d{9}", summary)


@pytest.mark.parametrize("index", _slow_if_plan(SNIPPETS, lambda s: f"snippet{SNIPPETS.index(s)}"))
def test_snippet_prints_what_the_readme_shows(index, monkeypatch):
    code, expected = shown("python")[index]
    monkeypatch.chdir(ROOT)
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        exec(compile(code, f"README snippet {index}", "exec"), {"__name__": "readme"})
    if "plan(" in code:
        assert doc_blocks.same_plan(_normal(buffer.getvalue()), _normal(expected))
    else:
        assert _normal(buffer.getvalue()) == _normal(expected)


def _numbers(outputs, label: str) -> list[str]:
    """Every ``label = NUMBER`` printed in ``outputs``."""
    return [m for out in outputs for m in re.findall(rf"\b{label} = (-?\d+\.\d+)", out)]


def test_snippets_and_commands_give_the_same_numbers():
    """The README's Python numbers equal its command-line numbers to the digits the snippet
    prints (the tests above hold both to what the code prints)."""
    commands = [out for _, out in shown("sh")]
    snippets = [out for _, out in shown("python")]
    pairs = 0
    for label in ("rho_hat", "rho"):
        api = _numbers(snippets, label)
        cli = _numbers(commands, label)
        for value in api:
            digits = len(value.split(".")[1])
            assert any(f"{float(c):.{digits}f}" == value for c in cli), (label, value, cli)
            pairs += 1
    assert pairs >= 3
