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
    # set, then removed, through monkeypatch: restored after the test whatever
    # _cache_dir_fallback writes (the later tests' subprocesses would compile in tmp_path)
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
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


def test_without_a_writable_user_cache_the_kernels_cache_in_the_temporary_folder(
    tmp_path, monkeypatch
):
    from closure_nlp import kernels

    package = Path(kernels.__file__).resolve().parent
    user = tmp_path / "cache" / "closure_nlp" / "numba"
    real_access = os.access

    def access(path, mode):  # the package's folder and the user's cache folder read-only
        if mode == os.W_OK and Path(path).resolve() in (package, package / "__pycache__", user):
            return False
        return real_access(path, mode)

    monkeypatch.setattr(kernels.os, "access", access)
    monkeypatch.setattr(kernels.tempfile, "gettempdir", lambda: str(tmp_path / "tmp"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")  # restored after the test (see above)
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    kernels._cache_dir_fallback()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "tmp" / "closure_nlp")
    # no XDG_CACHE_HOME: the home folder's .cache
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    kernels._cache_dir_fallback()
    assert os.environ["NUMBA_CACHE_DIR"] == str(
        tmp_path / "home" / ".cache" / "closure_nlp" / "numba"
    )


def test_a_read_only_package_compiles_into_the_user_cache_and_loads_from_it(tmp_path):
    # end to end, in fresh processes: the folder is chosen before numba reads its settings, a
    # kernel compiled there is written there, and the next process loads it (no compile)
    from closure_nlp import kernels

    package = Path(kernels.__file__).resolve().parent
    code = (
        "import os\n"
        "from pathlib import Path\n"
        f"package = Path({str(package)!r})\n"
        "real = os.access\n"
        "def access(path, mode):\n"
        "    if mode == os.W_OK and Path(path).resolve() in (package, package / '__pycache__'):\n"
        "        return False\n"
        "    return real(path, mode)\n"
        "os.access = access\n"
        "import numpy as np\n"
        "from closure_nlp.kernels import arrays\n"
        "print(arrays.dot(np.arange(3.0), np.arange(3.0)))\n"
        "stats = arrays.dot.stats\n"
        "print(sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))\n"
        "print(Path(stats.cache_path).is_relative_to(os.environ['NUMBA_CACHE_DIR']))\n"
    )
    env = _env(PYTHONPATH=str(ROOT), XDG_CACHE_HOME=str(tmp_path / "cache"))
    folder = tmp_path / "cache" / "closure_nlp" / "numba"
    assert _run(code, env, tmp_path) == ["5.0", "0 1", "True"]  # compiled, cached
    assert list(folder.rglob("arrays.dot-*.nbi"))
    assert _run(code, env, tmp_path) == ["5.0", "1 0", "True"]  # loaded from that cache


@pytest.mark.slow  # a cold compile of every kernel
def test_a_cold_cache_compiles_once_and_says_so(tmp_path):
    code = (
        "from closure_nlp.criterion.warm_up import warm_up\n"
        "lines = []\n"
        "first = warm_up(lines.append)\n"
        "print(first is not None and first > 0, len(lines))\n"
        "print(lines[0].startswith('compiling'), lines[-1].startswith('compiled'))\n"
        "print(warm_up(lines.append) is None, len(lines))\n"
    )
    env = _env(PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    assert _run(code, env, tmp_path) == ["True 2", "True True", "True 2"]
    # a new process finds everything in the disk cache: nothing to say
    again = "from closure_nlp.criterion.warm_up import warm_up\nlines = []\n"
    again += "print(warm_up(lines.append) is None, len(lines))\n"
    assert _run(again, env, tmp_path) == ["True 0"]


def test_the_rho_command_loads_only_the_kernels_of_rho(tmp_path):
    from closure_nlp import kernels

    code = (
        "from closure_nlp.kernels import nearest_point, support\n"
        "from closure_nlp.criterion.warm_up import warm_up\n"
        "print(warm_up(rho_only=True) is None, bool(support.rows_many.overloads),\n"
        "      bool(support.slots_many.overloads), bool(nearest_point.min_norm_point.overloads),\n"
        "      bool(support.evaluate_many.overloads))\n"
    )
    env = _env(PYTHONPATH=str(ROOT))
    if "NUMBA_CACHE_DIR" in os.environ:
        env["NUMBA_CACHE_DIR"] = os.environ["NUMBA_CACHE_DIR"]
    if not kernels.cached(rho_only=True):  # a cold cache: this first process compiles them
        # Wolfe's nearest point of given points first (the local minimiser's, in the helper)
        assert _run(code, env, tmp_path) == ["False False False True True"]
    # warm: the kernels of rho loaded, not those of rows, slots and Wolfe's nearest point
    assert _run(code, env, tmp_path) == ["True False False False True"]


@pytest.mark.slow  # a cold compile of the kernels of rho, then of the others
def test_a_cold_rho_compiles_the_kernels_of_rho_and_a_later_command_the_others(tmp_path):
    # the rho command compiles only what a certified rho runs; a command that runs the others
    # (slot values, rows, Wolfe's nearest point, the zonotope) compiles those at its warm-up,
    # and says so, and then nothing is left to compile; the zonotope's capacity only for a
    # command that may place frictionless contacts
    code = (
        "import sys\n"
        "from closure_nlp import kernels\n"
        "from closure_nlp.criterion import warm_up\n"
        "lines = []\n"
        "rho_only, capacity = sys.argv[1] == 'rho', sys.argv[1] == 'all'\n"
        "first = warm_up.warm_up(lines.append, rho_only=rho_only, capacity=capacity)\n"
        "print(first is not None, len(lines))\n"
        "cached = kernels.cached\n"
        "print(cached(rho_only=True), cached(capacity=False), cached())\n"
    )
    env = _env(PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))

    def run(which):
        out = subprocess.run(
            [sys.executable, "-c", code, which], capture_output=True, text=True, env=env,
            cwd=tmp_path, timeout=600,
        )  # fmt: skip
        assert out.returncode == 0, out.stderr
        return out.stdout.strip().splitlines()

    assert run("rho") == ["True 2", "True False False"]
    assert run("rho") == ["False 0", "True False False"]
    # placements of contacts with friction: all but the zonotope's capacity
    assert run("friction") == ["True 2", "True True False"]
    assert run("friction") == ["False 0", "True True False"]
    assert run("all") == ["True 2", "True True True"]
    assert run("all") == ["False 0", "True True True"]


@pytest.mark.parametrize(
    "command, kind, mu, compiled",
    [
        ("plan", "pcwf", "0.2", False),
        ("place", "sfce,pcwf", "0.2,0.5", False),
        ("plan", "fpc", "0.2", True),
        ("plan", "pcwf,FPC", "0.2", True),
        ("place", "pcwf", "0.2,0", True),  # a frictionless PCwF
        ("plan", "pcwf", "x", True),  # refused later: nothing spared
        ("study", "pcwf", "0.2", True),  # the tasks' own contacts
        ("select", "fpc", "0.2", False),  # places nothing
        ("rho", "fpc", "0.2", False),
    ],
)
def test_the_capacity_compiles_for_commands_that_may_place_frictionless_contacts(
    command, kind, mu, compiled
):
    # the zonotope's capacity runs only in placements whose contacts are all frictionless
    import importlib
    from argparse import Namespace

    from closure_nlp.cli import main as cli

    module = importlib.import_module(f"closure_nlp.cli.{command}_command")
    args = Namespace(run=getattr(module, f"cmd_{command}"), type=kind, mu=mu)
    assert cli._frictionless_placements(args) is compiled


def test_the_declared_signatures_are_those_the_library_calls():
    # a cold compile compiles each entry point for its declared signature, in two processes:
    # a call of other types would compile the kernel again inside an answer's timing
    import importlib

    from closure_nlp import kernels
    from closure_nlp.criterion import warm_up

    warm_up.warm_up()  # rho, slot values, row terms, Wolfe's nearest point: every entry point
    declared = kernels.signatures()
    entries = {(m, n) for m, names in kernels.ENTRY_POINTS.items() for n in names}
    first, second = kernels.COMPILE_GROUPS
    assert sorted({*first, *second}) == sorted(declared)  # each declared kernel compiled
    assert len(set(first)) == len(first) and len(set(second)) == len(second)
    assert entries <= set(declared)
    for module, name in entries:
        dispatcher = getattr(importlib.import_module(f"closure_nlp.kernels.{module}"), name)
        assert dispatcher.signatures == [declared[module, name]], (module, name)


@pytest.mark.slow  # a cold compile of the branch and bound
def test_the_declared_inner_kernels_are_those_their_callers_pass(tmp_path):
    # a kernel compiled ahead for its caller (the other process's) must be declared with the
    # types the caller passes: else the caller compiles it again, and the other process's
    # compile was wasted
    from closure_nlp import kernels

    inner = [
        key for key in kernels.signatures()
        if key[1] not in kernels.ENTRY_POINTS.get(key[0], ())
    ]  # fmt: skip
    assert inner
    code = (
        "import importlib\n"
        "from closure_nlp import kernels\n"
        "def kernel(module, name):\n"
        "    return getattr(importlib.import_module(f'closure_nlp.kernels.{module}'), name)\n"
        "declared = kernels.signatures()\n"
        f"inner = {inner!r}\n"
        "for module, names in kernels.ENTRY_POINTS.items():  # their callers, without them\n"
        "    if any(module == m for m, _ in inner):\n"
        "        for name in names:\n"
        "            kernel(module, name).compile(declared[module, name])\n"
        "for key in inner:\n"
        "    print(kernel(*key).signatures == [declared[key]])\n"
    )
    env = _env(PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    assert _run(code, env, tmp_path) == ["True"] * len(inner)


def test_a_stale_declaration_compiles_at_the_first_call(tmp_path):
    # a declared signature the kernel cannot take: the cold compile skips it and the first
    # call compiles the kernel for the types it is given, the answer unchanged
    code = (
        "from numba import types\n"
        "from closure_nlp import kernels\n"
        "declared = kernels.signatures()\n"
        "key = ('nearest_point', 'min_norm_point')\n"
        "declared[key] = (types.Array(types.float64, 3, 'C'), types.float64)\n"
        "kernels.signatures = lambda: declared\n"
        "kernels.compile_group(next(i for i, g in enumerate(kernels.COMPILE_GROUPS) if key in g))\n"
        "import numpy as np\n"
        "from closure_nlp.kernels.nearest_point import min_norm_point\n"
        "x = min_norm_point(np.array([[1.0, 1.0], [1.0, -1.0]]), 1e-12)\n"
        "print(np.round(x[0], 9).tolist())\n"
    )
    lines = _run(code, _env(NUMBA_CACHE_DIR=str(tmp_path)), tmp_path)
    assert lines == ["[1.0, 0.0]"]


def test_read_only_and_strided_inputs_reuse_the_compiled_kernels():
    # a read-only or strided array is another numba type: the API's wrappers pass C-ordered
    # writeable copies, so no call compiles a kernel again inside an answer's timing
    import numpy as np

    from closure_nlp.contact.contact_set import Contact, ContactSet
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.hull_distance import _start_directions, min_norm_point
    from closure_nlp.criterion.support_minimum import _local_minimum
    from closure_nlp.kernels import descent
    from closure_nlp.kernels import nearest_point as kernel

    normals = np.vstack([np.eye(3), -np.eye(3)])
    slots = WrenchSlots.from_contacts(ContactSet(tuple(Contact(-n, n) for n in normals[:4])))
    points = np.vstack([np.eye(6), -np.eye(6)])
    _local_minimum(slots, np.full(6, 0.5))
    min_norm_point(points.copy())
    counts = [len(descent.local_minimum.signatures), len(kernel.min_norm_point.signatures)]
    frozen = np.full(6, 0.5)
    frozen.flags.writeable = False
    _local_minimum(slots, frozen)
    _local_minimum(slots, np.full((6, 2), 0.5)[:, 0])  # strided
    frozen_points = points.copy()
    frozen_points.flags.writeable = False
    min_norm_point(frozen_points)
    min_norm_point(np.asfortranarray(points))
    after = [len(descent.local_minimum.signatures), len(kernel.min_norm_point.signatures)]
    assert after == counts
    assert _start_directions(np.full(6, 0.5)).flags.c_contiguous  # Gilbert's starts


def test_a_change_to_any_kernel_module_drops_every_cached_kernel(tmp_path):
    """numba checks a cached kernel against its own file only: one compiled with an older
    callee from another module must not load. Any kernel source changed -> all dropped."""
    import shutil

    from closure_nlp import kernels

    package = Path(kernels.__file__).resolve().parent
    sources = tmp_path / "kernels"
    shutil.copytree(package, sources, ignore=shutil.ignore_patterns("__pycache__"))
    before = kernels.sources_digest(sources)
    assert before == kernels.sources_digest(package)
    callee = sources / "arrays.py"
    callee.write_text(callee.read_text() + "\n# edited\n")
    after = kernels.sources_digest(sources)
    assert after != before

    cache = tmp_path / "cache"
    cache.mkdir()
    ours = ["support.support_many-127.py311.nbi", "branch_bound.advance-519.py311.1.nbc"]
    theirs = ["other.f-1.py311.nbi", "support.cpython-311.pyc"]
    for name in ours + theirs:
        (cache / name).write_text("x")
    modules = {"support", "branch_bound", "arrays"}
    kernels.drop_stale_cache(cache, before, modules)  # no stamp yet: dropped, stamp written
    assert sorted(p.name for p in cache.iterdir() if p.suffix != ".sha256") == sorted(theirs)
    for name in ours:
        (cache / name).write_text("x")
    kernels.drop_stale_cache(cache, before, modules)  # same sources: kept
    assert all((cache / name).exists() for name in ours)
    kernels.drop_stale_cache(cache, after, modules)  # a callee changed: dropped
    assert not any((cache / name).exists() for name in ours)
    assert all((cache / name).exists() for name in theirs)


def test_the_package_cache_is_stamped_with_its_sources():
    from closure_nlp import kernels

    package = Path(kernels.__file__).resolve().parent
    cache = kernels.CACHE_FOLDER
    stamp = cache / "closure_nlp_kernels.sha256"
    assert stamp.read_text() == kernels.sources_digest(package)


class _Helper:
    """A stand-in for the helper process: running until ``ended`` is set."""

    def __init__(self):
        self.ended = False

    def poll(self):
        return 0 if self.ended else None


def test_the_command_waits_for_a_kernel_of_both_lists_until_the_helper_marks_it(tmp_path):
    # a kernel in both lists is the helper's: the command's process waits for its mark (then
    # loads it from the cache), or compiles it itself once the helper has ended without it
    import threading
    import time

    from closure_nlp import kernels

    shared = set(kernels.COMPILE_GROUPS[0]) & set(kernels.COMPILE_GROUPS[1])
    assert shared == set(kernels.AWAITED) and ("branch_bound", "slot_bound") in shared
    assert kernels.COMPILE_GROUPS[0].index(("branch_bound", "advance")) > max(
        kernels.COMPILE_GROUPS[0].index(kernel) for kernel in shared
    )  # advance compiled once its parts are cached
    mark, helper = tmp_path / "branch_bound.slot_bound", _Helper()
    threading.Timer(0.3, mark.touch).start()
    start = time.perf_counter()
    kernels._wait_for(mark, helper)
    assert mark.exists() and time.perf_counter() - start >= 0.25
    # a helper that ended (failed): no wait, nor without one
    helper.ended = True
    start = time.perf_counter()
    kernels._wait_for(tmp_path / "never", helper)
    kernels._wait_for(tmp_path / "never", None)
    assert time.perf_counter() - start < 0.2


def test_the_helper_marks_each_kernel_it_is_done_with(tmp_path, monkeypatch):
    # a stale declaration (a TypingError) is marked too: the other process must not wait on it
    from numba import types

    from closure_nlp import kernels

    vector = types.Array(types.float64, 1, "C")
    fill, dot = ("arrays", "fill"), ("arrays", "dot")
    monkeypatch.setattr(kernels, "COMPILE_GROUPS", ((), (fill, dot)))
    monkeypatch.setattr(
        kernels,
        "signatures",
        lambda: {fill: (vector, types.int64, types.float64), dot: (vector, types.int64)},
    )
    kernels.compile_group(1, marks=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arrays.dot", "arrays.fill"]


def test_the_compile_helper_imports_this_package_whatever_the_working_folder(tmp_path):
    # ``python -c`` puts the working folder first on the path: another checkout there must not
    # be the package the helper process compiles
    decoy = tmp_path / "closure_nlp"
    decoy.mkdir()
    (decoy / "__init__.py").write_text("raise ImportError('the checkout in the working folder')\n")
    from closure_nlp import kernels

    code = kernels.helper_code("import closure_nlp; print(closure_nlp.__file__)")
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert Path(result.stdout.strip()).resolve() == (ROOT / "closure_nlp" / "__init__.py").resolve()
