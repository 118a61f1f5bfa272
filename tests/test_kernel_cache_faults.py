"""The compiled kernels through a damaged, unwritable or missing disk cache, and the compile
helper's end with its parent: each in fresh processes, with a cache folder of the test's."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# A small group of kernels, one of them calling others (Wolfe's nearest point calls the least
# squares and the array helpers): what a compile of the package does, in seconds.
SMALL_GROUP = """
import numpy as np
from numba import types
from closure_nlp import kernels
f1, f2 = (types.Array(types.float64, d, "C") for d in (1, 2))
group = (("arrays", "dot"), ("nearest_point", "min_norm_point"))
kernels.COMPILE_GROUPS = (group, ())
kernels.signatures = lambda: {group[0]: (f1, f1), group[1]: (f2, types.float64)}
from closure_nlp.kernels import arrays, nearest_point
def run():
    x = nearest_point.min_norm_point(np.array([[1.0, 1.0], [1.0, -1.0]]), 1e-12)
    return [float(arrays.dot(np.arange(3.0), np.arange(3.0))), np.round(x[0], 9).tolist()]
def counts():
    both = (arrays.dot, nearest_point.min_norm_point)
    hits = sum(sum(k.stats.cache_hits.values()) for k in both)
    return hits, sum(sum(k.stats.cache_misses.values()) for k in both)
"""


def _env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "TMPDIR")}
    return {**env, "PYTHONPATH": str(ROOT), **extra}


def _run(code, env, cwd):
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=cwd, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout.strip().splitlines(), out.stderr


def _compile_small(extra=""):
    return (
        SMALL_GROUP + extra + "lines = []\n"
        "kernels.compile_group(0, notify=lines.append)\n"
        "print(run())\n"
        "print(counts())\n"
        "print(lines)\n"
    )


def _damage(folder, how):
    index = sorted(folder.rglob("nearest_point.min_norm_point-*.nbi"))
    data = sorted(folder.rglob("nearest_point.min_norm_point-*.nbc"))
    assert index and data
    if how == "truncated data":
        data[0].write_bytes(data[0].read_bytes()[:100])
    elif how == "empty data":
        data[0].write_bytes(b"")
    elif how == "empty index":
        index[0].write_bytes(b"")
    else:
        index[0].write_bytes(os.urandom(300))


@pytest.mark.parametrize("how", ["truncated data", "empty data", "empty index", "random index"])
def test_a_damaged_cached_kernel_is_dropped_and_compiled_again_once(tmp_path, how):
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    code = _compile_small()
    answer = "[5.0, [1.0, 0.0]]"
    assert _run(code, env, tmp_path)[0] == [answer, "(0, 2)", "[]"]  # compiled, cached
    _damage(tmp_path / "numba", how)
    lines, stderr = _run(code, env, tmp_path)
    assert lines[0] == answer
    notices = eval(lines[2])
    assert len(notices) == 1 and notices[0].startswith("warning: a damaged compiled kernel")
    assert "Traceback" not in stderr
    # healed: the next process loads both, and says nothing
    assert _run(code, env, tmp_path)[0] == [answer, "(2, 0)", "[]"]


@pytest.mark.slow  # a cold compile of the kernels of rho, then a compile again
def test_a_damaged_cache_heals_at_the_warm_up_with_one_warning(tmp_path):
    code = (
        "import warnings\n"
        "from closure_nlp.criterion.warm_up import warm_up\n"
        "with warnings.catch_warnings(record=True) as seen:\n"
        "    warnings.simplefilter('always')\n"
        "    seconds = warm_up(rho_only=True)\n"
        "print(seconds is not None, [str(w.message)[:25] for w in seen])\n"
    )
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    assert _run(code, env, tmp_path)[0] == ["True []"]
    assert _run(code, env, tmp_path)[0] == ["False []"]
    for data in (tmp_path / "numba").rglob("branch_bound.advance-*.nbc"):
        data.write_bytes(data.read_bytes()[:1000])
    assert _run(code, env, tmp_path)[0] == ["True ['a damaged compiled kernel']"]
    assert _run(code, env, tmp_path)[0] == ["False []"]


# No temporary folder (gettempdir raises) and no folder numba can write for its cache (numba
# tries each by creating a temporary file in it).
NO_FOLDERS = """
import os, tempfile
def refuse(*args, **kwargs):
    raise PermissionError(13, "Permission denied (read-only)")
tempfile.tempdir = None
tempfile._candidate_tempdir_list = lambda: ["/nonexistent-closure-nlp-tmp"]
tempfile.mkdtemp = refuse
"""


def test_without_any_writable_folder_the_kernels_compile_in_memory(tmp_path):
    code = (
        NO_FOLDERS
        + (
            "tempfile.TemporaryFile = refuse\n"
            "real_access = os.access\n"
            "def access(path, mode, **k):\n"
            "    return False if mode == os.W_OK else real_access(path, mode)\n"
            "os.access = access\n"
            "import warnings\n"
            "warnings.simplefilter('always')\n"
            "with warnings.catch_warnings(record=True) as seen:\n"
            "    from closure_nlp import kernels\n"
            "    print(kernels.CACHE, kernels.cached())\n"
            "    print(kernels.cached(), kernels._marks_folder())\n"
            "print(len(seen), str(seen[0].message)[:30])\n"
        )
        + _compile_small()
        + "print(os.environ.get('NUMBA_CACHE_DIR'))\n"
    )
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    env = _env(XDG_CACHE_HOME=str(blocked / "cache"), HOME=str(blocked / "home"))
    lines, stderr = _run(code, env, tmp_path)
    assert lines[:3] == ["False False", "False None", "1 no writable folder for the com"]
    assert lines[3:6] == ["[5.0, [1.0, 0.0]]", "(0, 2)", "[]"]  # compiled in memory
    assert lines[6] == "None"


def test_without_a_temporary_folder_the_compile_runs_in_one_process(tmp_path):
    code = (
        NO_FOLDERS
        + (
            "from closure_nlp import kernels\n"
            "print(kernels.CACHE, kernels._marks_folder())\n"
            "kernels.ENTRY_POINTS = {}\n"
            "lines = []\n"
        )
        + SMALL_GROUP
        + ("kernels.compile_in_parallel(notify=lines.append)\nprint(run(), counts(), lines)\n")
    )
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    lines, _ = _run(code, env, tmp_path)
    assert lines == ["True None", "[5.0, [1.0, 0.0]] (0, 2) []"]


# Every write under the cache folder fails as on a full disk (numba writes each file through
# ``open``), after the package has found its folder.
FULL_DISK = """
import builtins, errno, os
real_open = builtins.open
def open_(file, mode="r", *args, **kwargs):
    if any(c in mode for c in "wax+") and str(file).startswith(os.environ["NUMBA_CACHE_DIR"]):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return real_open(file, mode, *args, **kwargs)
builtins.open = open_
"""


def test_a_full_cache_disk_compiles_in_memory_and_says_so_once(tmp_path):
    code = _compile_small(FULL_DISK) + (
        "kernels.compile_group(0, notify=lines.append)\n"
        "print(len(lines), kernels.cached(notify=lines.append))\n"
    )
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    lines, stderr = _run(code, env, tmp_path)
    # compiled, nothing loaded (each kernel that failed to save is found in memory next try)
    assert lines[0] == "[5.0, [1.0, 0.0]]" and lines[1].startswith("(0, ")
    notices = eval(lines[2])
    assert len(notices) == 1
    assert notices[0].startswith("warning: the compiled kernels cannot be saved")
    assert "No space left on device" in notices[0]
    assert lines[3] == "1 False"  # said once; and not taken for a warm cache
    assert not list((tmp_path / "numba").rglob("*.nbc"))


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_the_compile_helper_ends_with_its_parent_and_leaves_no_marks(tmp_path):
    # the parent killed mid-compile: its helper must not go on compiling for no one, nor leave
    # its folder of marks in the temporary folder
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba"), TMPDIR=str(temporary))
    code = "from closure_nlp import kernels\nkernels.compile_in_parallel(rho_only=True)\n"
    parent = subprocess.Popen(
        [sys.executable, "-c", code], env=env, cwd=tmp_path,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip

    def children(pid):
        found = []
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(stat.parent.name))
        return found

    def running(pid):
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return False
        return state not in ("Z", "X")

    try:
        deadline = time.monotonic() + 60
        helpers = []
        while not helpers and time.monotonic() < deadline and parent.poll() is None:
            helpers = children(parent.pid)
            time.sleep(0.05)
        assert helpers, "no helper started"
        while not list(temporary.glob("closure_nlp_compile_*")) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(1.0)  # the helper compiling
        assert running(helpers[0])
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and (
        running(helpers[0]) or list(temporary.glob("closure_nlp_compile_*"))
    ):
        time.sleep(0.05)
    alive = running(helpers[0])
    if alive:
        os.kill(helpers[0], signal.SIGKILL)
    assert not alive
    assert not list(temporary.glob("closure_nlp_compile_*"))
