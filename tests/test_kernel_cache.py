"""Where the compiled kernels are cached, and the one-time compile notice."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(code, env, cwd):
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=cwd, timeout=600
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()


def _env(**extra):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    return {**env, **extra}


def test_a_read_only_install_caches_in_the_user_cache(tmp_path, monkeypatch):
    from closure_nlp import kernels

    package = Path(kernels.__file__).resolve().parent
    real_access = os.access

    def access(path, mode):  # the package's folder read-only, as in a system-wide install
        if Path(path).resolve() in (package, package / "__pycache__") and mode == os.W_OK:
            return False
        return real_access(path, mode)

    monkeypatch.setattr(kernels.os, "access", access)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    kernels._cache_dir_fallback()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "cache" / "closure_nlp" / "numba")
    assert (tmp_path / "cache" / "closure_nlp" / "numba").is_dir()
    # a folder the user chose is kept
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    kernels._cache_dir_fallback()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")
    # writable: numba's own cache beside the sources, nothing set
    monkeypatch.setattr(kernels.os, "access", real_access)
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    kernels._cache_dir_fallback()
    assert "NUMBA_CACHE_DIR" not in os.environ


@pytest.mark.slow  # a cold compile of every kernel
def test_a_cold_cache_compiles_once_and_says_so(tmp_path):
    code = (
        "from closure_nlp.kernels import warm_up\n"
        "lines = []\n"
        "first = warm_up(lines.append)\n"
        "print(first is not None and first > 0, len(lines))\n"
        "print(lines[0].startswith('compiling'), lines[-1].startswith('compiled'))\n"
        "print(warm_up(lines.append) is None, len(lines))\n"
    )
    env = _env(PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    assert _run(code, env, tmp_path) == ["True 2", "True True", "True 2"]
    # a new process finds everything in the disk cache: nothing to say
    again = "from closure_nlp.kernels import warm_up\nlines = []\n"
    again += "print(warm_up(lines.append) is None, len(lines))\n"
    assert _run(again, env, tmp_path) == ["True 0"]
