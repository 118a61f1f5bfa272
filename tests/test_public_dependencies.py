"""The package reaches numba and llvmlite through their public modules only: a private name
(a leading underscore) or an internal module would break with any release of theirs."""

import ast
from pathlib import Path

import closure_nlp

PUBLIC = {
    "numba": {"numba", "numba.extending", "numba.core.errors"},
    "llvmlite": {"llvmlite", "llvmlite.ir", "llvmlite.binding"},
}


def _imports(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.module, [alias.name for alias in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, []


def test_numba_and_llvmlite_are_used_through_their_public_modules_only():
    root = Path(closure_nlp.__file__).parent
    found, wrong = 0, []
    for path in sorted(root.rglob("*.py")):
        for module, names in _imports(ast.parse(path.read_text(), str(path))):
            package = module.split(".")[0]
            if package not in PUBLIC:
                continue
            found += 1
            if module not in PUBLIC[package] or any(n.startswith("_") for n in names):
                wrong.append(f"{path.relative_to(root)}: {module} {names}")
            text = path.read_text()
            if f"{package}.np." in text or f"{package}.core.types" in text:
                wrong.append(f"{path.relative_to(root)}: reaches into {package}'s internals")
    assert found > 10  # the kernels' imports were seen
    assert not wrong, wrong
