"""Reading a Markdown page's fenced blocks and comparing what a command prints with what the page
shows under it: shared by the README's tour and the how-tos."""

from __future__ import annotations

import re
from pathlib import Path

SECONDS = re.compile(r"\d+(\.\d+)? s\b")
NUMBER = re.compile(r"-?\d+\.\d+")


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """``(language, body)`` of every fenced block, in order."""
    return re.findall(r"^```(\w*)\n(.*?)^```\s*$", text, flags=re.S | re.M)


def shown(page: Path, language: str) -> list[tuple[str, str]]:
    """``(code, output)``: each ``language`` block followed at once by a ``text`` block."""
    blocks = fenced_blocks(page.read_text())
    return [
        (code, out)
        for (lang, code), (next_lang, out) in zip(blocks, blocks[1:])
        if lang == language and next_lang == "text"
    ]


def normal(text: str, out_dir: Path | None = None, shown_as: str = "") -> list[str]:
    """Lines without the seconds (they depend on the machine) and with the output folder named
    as on the page (``shown_as``)."""
    if out_dir is not None:
        text = text.replace(str(out_dir), shown_as)
    return [SECONDS.sub("<s>", line).rstrip() for line in text.strip().splitlines()]


def same_plan(printed: list[str], expected: list[str]) -> bool:
    """A plan's lines against the page's: the same words and integers (elements, counts);
    decimals within 2% or 0.6 (mm on parts of 60 mm and more). The placement is a local search:
    another CPU rounds the compiled kernels' and BLAS's sums differently in the last bits, and it
    can end at a nearby optimum (-0.516038 on one machine, -0.514620 on another, on the lamp)."""
    if len(printed) != len(expected):
        return False
    for got, want in zip(printed, expected):
        if NUMBER.sub("#", got) != NUMBER.sub("#", want):
            return False
        for a, b in zip(map(float, NUMBER.findall(got)), map(float, NUMBER.findall(want))):
            if abs(a - b) > max(0.02 * abs(b), 0.6):
                return False
    return True
