"""The API reference (``make docs``): pdoc builds it from the docstrings of the public names
(``closure_nlp.__all__``) without a single warning, and documents every one of them."""

from __future__ import annotations

import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import closure_nlp

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The reference, built as ``make docs`` builds it, in its own process (pdoc's settings are
    global), from this checkout."""
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    env.pop("PYTHONWARNINGS", None)
    done = subprocess.run(
        [sys.executable, "-m", "pdoc", "-d", "numpy", "-o", str(out), "closure_nlp"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert not done.stderr.strip(), f"pdoc warned:\n{done.stderr}"
    return out


def test_the_reference_builds_without_warnings(site):
    assert (site / "closure_nlp.html").is_file()
    assert (site / "index.html").is_file()


@pytest.mark.parametrize("name", closure_nlp.__all__)
def test_every_public_name_is_documented(site, name):
    """Each public name has its own entry in the reference; each class and function with its
    docstring (values such as ``__version__`` are listed by their value)."""
    page = (site / "closure_nlp.html").read_text(encoding="utf-8")
    entry = re.search(rf'<section id="{re.escape(name)}">(.*?)</section>', page, flags=re.S)
    assert entry, f"{name}: no entry in the reference"
    value = getattr(closure_nlp, name)
    assert not inspect.ismodule(value), f"{name}: the reference shows a module"
    if inspect.isclass(value) or inspect.isfunction(value):
        assert 'class="docstring"' in entry.group(1), f"{name}: documented without a docstring"
