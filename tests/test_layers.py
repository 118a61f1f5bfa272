"""The package's layers: each stage imports only the stages below it, and no modules of one
package import each other in a circle (the contracts in pyproject.toml, checked by
import-linter); users, docs and examples import only from the top-level API."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_import_contracts_hold():
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if lint is None:
        pytest.skip("import-linter is not installed (make install adds it)")
    done = subprocess.run([lint], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-3000:]
    assert "BROKEN" not in done.stdout and done.stdout.count("KEPT") >= 2


def _imports(text: str) -> list[str]:
    return re.findall(r"^\s*(?:from|import) (closure_nlp[\w.]*)", text, flags=re.M)


def test_examples_and_docs_import_only_the_public_api():
    files = [*ROOT.glob("examples/*.py"), ROOT / "README.md", *ROOT.glob("docs/*.md")]
    deep = {
        str(path.relative_to(ROOT)): sorted(
            {m for m in _imports(path.read_text()) if m != "closure_nlp"}
        )
        for path in files
    }
    assert {k: v for k, v in deep.items() if v} == {}


def test_every_public_name_loads():
    import closure_nlp

    for name in closure_nlp.__all__:
        assert getattr(closure_nlp, name) is not None, name
    with pytest.raises(AttributeError):
        closure_nlp.no_such_name  # noqa: B018


def test_a_sub_package_does_not_hide_a_public_name():
    """The stage's package (``closure_nlp.criterion``) is imported by the package's own modules;
    ``rho`` on the top level stays the function."""
    import closure_nlp.criterion.rho_hat  # noqa: F401
    from closure_nlp import rho

    assert callable(rho) and rho.__module__ == "closure_nlp.criterion.support_minimum"
