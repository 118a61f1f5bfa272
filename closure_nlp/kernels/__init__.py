"""The compiled kernels (numba): one module per concept, named after what it computes.

* :mod:`.support`: support values and support points of wrench slots (eqs 26-32, 35-36);
* :mod:`.branch_bound`: cells, bounds and matrix games of the branch and bound over the sphere;
* :mod:`.slot_game`: the matrix game of a cell with one budget of weights per slot;
* :mod:`.nearest_point`: Wolfe's nearest point of a hull and Gilbert's iteration;
* :mod:`.descent`: the batched descent and the local minimiser on the sphere.

Every kernel is compiled on first use and cached on disk (``cache=True``), releases the GIL
(``nogil=True``) and takes plain arrays and integers, never a function.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np


def _cache_dir_fallback() -> None:
    """Point numba's disk cache at a user cache folder when this package's folder is read-only
    (a system-wide install): set before numba is imported, only when needed, never over a
    ``NUMBA_CACHE_DIR`` the user chose."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    here = Path(__file__).resolve().parent
    pycache = here / "__pycache__"
    if os.access(pycache if pycache.is_dir() else here, os.W_OK):
        return
    base = os.environ.get("XDG_CACHE_HOME") or (
        os.environ.get("LOCALAPPDATA") if sys.platform == "win32" else None
    )
    root = Path(base) if base else Path.home() / ".cache"
    for folder in (root / "closure_nlp" / "numba", Path(tempfile.gettempdir()) / "closure_nlp"):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            os.environ["NUMBA_CACHE_DIR"] = str(folder)
            return


_cache_dir_fallback()


def sources_digest(folder: Path) -> str:
    """A digest of every kernel module's source in ``folder``."""
    digest = hashlib.sha256()
    for source in sorted(folder.glob("*.py")):
        digest.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    return digest.hexdigest()


def drop_stale_cache(cache: Path, digest: str, modules) -> None:
    """Remove ``modules``' compiled kernels from ``cache`` unless they were compiled from the
    sources of ``digest``: numba checks a cached kernel against its own file only, and a kernel
    compiled with an older version of a callee in another module would load unchanged."""
    stamp = cache / "closure_nlp_kernels.sha256"
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        # made first: a folder numba has yet to create (a fresh NUMBA_CACHE_DIR) gets its stamp
        # now, else the next process would drop every kernel this one compiles
        cache.mkdir(parents=True, exist_ok=True)
        for entry in cache.iterdir():
            if entry.suffix in (".nbi", ".nbc") and entry.name.split(".")[0] in modules:
                entry.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:  # none writable: numba caches nothing there either
        pass


def _cache_folder(here: Path) -> Path | None:
    """Where numba caches the kernels of ``here``: the user's ``NUMBA_CACHE_DIR`` (numba's own
    sub-folder for this folder) or the package's ``__pycache__``."""
    if "NUMBA_CACHE_DIR" not in os.environ:
        return here / "__pycache__"
    try:
        from numba.core.caching import _CacheLocator  # private: its folder naming

        sub = _CacheLocator.get_suitable_cache_subpath(str(here / "__init__.py"))
    except Exception:
        return None
    return Path(os.environ["NUMBA_CACHE_DIR"]) / sub


def _drop_stale_kernels() -> None:
    here = Path(__file__).resolve().parent
    cache = _cache_folder(here)
    if cache is not None:
        modules = {source.stem for source in here.glob("*.py")}
        drop_stale_cache(cache, sources_digest(here), modules)


_drop_stale_kernels()


def kernel_array(a) -> np.ndarray:
    """``a`` as the kernels are compiled for it: float64, C order, aligned, writeable, a
    plain ndarray; a copy only when ``a`` is not already so. numba compiles another version of
    a kernel for a read-only, strided or Fortran-ordered array (seconds, inside the caller's
    timing); no kernel writes into its inputs, so sharing the caller's array is safe."""
    return np.require(a, dtype=float, requirements=["C", "A", "W", "E"])


# The steps of the smoothed descent of a placement's sphere search (:mod:`.descent`, called
# from :func:`closure_nlp.sphere_search.descend`): not a certified rho's.
SMOOTHED_STEPS = ("smoothed_terms", "smoothed_values", "smoothed_trials", "smoothed_accept")
# The kernels called from Python (the others are compiled into them): warm_up calls each.
ENTRY_POINTS = {
    "support": ("support_many", "evaluate_many", "rows_many", "row_wrenches_many", "slots_many"),
    "branch_bound": ("consider", "advance"),
    "nearest_point": ("min_norm_point", "nearest_point_bounds"),
    "descent": ("descend_many", "local_minimum", *SMOOTHED_STEPS),
    "zonotope": ("capacity_many",),
}
# Kernels of the branch and bound that ``advance`` calls, compiled ahead for the types it passes
# (:func:`signatures`, :data:`COMPILE_GROUPS`): the slot game's bound, the cell games, the
# split of the live cells, Frank-Wolfe's bound, the cloud round the incumbent and the screen.
ADVANCE_PARTS = tuple(
    ("branch_bound", name)
    for name in ("slot_bound", "exact_bound", "split", "frank_wolfe", "cloud", "screen")
)
# The kernels a certified rho runs (the ``rho`` command's, :func:`warm_up`'s ``rho_only``),
# ``advance``'s parts included, and Wolfe's nearest point of given points, which the local
# minimiser runs: a cold ``rho`` compiles these alone; the others (slot values, row terms, the
# zonotope's capacity) compile when a command that runs them first warms up, or at their first
# call.
RHO_KERNELS = (
    ("nearest_point", "min_norm_point"),
    ("branch_bound", "consider"),
    ("branch_bound", "advance"),
    *ADVANCE_PARTS,
    ("descent", "descend_many"),
    ("descent", "local_minimum"),
    ("nearest_point", "nearest_point_bounds"),
    ("support", "support_many"),
    ("support", "evaluate_many"),
)
# The zonotope's capacity: only a placement whose every contact is frictionless runs it (its
# search, :func:`~closure_nlp.zonotope.climb`); a warm-up told that none will compiles it not.
CAPACITY_KERNELS = (("zonotope", "capacity_many"),)
# The helper's kernels that the command's process waits for before ``advance``: the slot game's
# bound and the cell games (the longest chain), then the cloud round the incumbent and
# Frank-Wolfe's bound.
AWAITED = tuple(
    ("branch_bound", name) for name in ("slot_bound", "exact_bound", "cloud", "frank_wolfe")
)
# A cold compile splits the kernels in two lists, one per process (numba compiles under a lock:
# one process compiles on one core); both write the disk cache. ``advance`` is compiled last,
# once every part it calls is in the cache, so that it compiles only itself: the command's
# process compiles the other parts, the helper :data:`AWAITED` first (a kernel in both lists:
# the helper compiles it, the other waits until the helper has cached it, then loads it; should
# the helper fail, it compiles it itself). Wolfe's nearest point of given points comes first:
# the helper's local minimiser calls it.
COMPILE_GROUPS = (
    (
        ("nearest_point", "min_norm_point"),
        ("branch_bound", "consider"),
        *(part for part in ADVANCE_PARTS if part not in AWAITED),
        ("support", "support_many"),
        *AWAITED,
        ("branch_bound", "advance"),
    ),
    (
        *AWAITED,
        *(("support", name) for name in ENTRY_POINTS["support"] if name != "support_many"),
        ("nearest_point", "nearest_point_bounds"),
        ("descent", "local_minimum"),
        ("descent", "descend_many"),
        *(("descent", name) for name in SMOOTHED_STEPS),
        ("zonotope", "capacity_many"),
    ),
)


def _wanted(kernel: tuple, rho_only: bool, capacity: bool) -> bool:
    """Whether a warm-up compiles ``kernel`` ``(module, name)``: with ``rho_only``, those of
    :data:`RHO_KERNELS` alone; without ``capacity``, not those of :data:`CAPACITY_KERNELS`."""
    if rho_only:
        return kernel in RHO_KERNELS
    return capacity or kernel not in CAPACITY_KERNELS


def signatures() -> dict:
    """The one signature of each kernel of :data:`COMPILE_GROUPS`: an entry point's, the
    argument types the Python wrappers pass (see :func:`kernel_array`); another's, the types
    its caller passes. A compile needs no inputs: ``{(module, name): types}``."""
    from numba import types

    f1, f2, f3 = (types.Array(types.float64, d, "C") for d in (1, 2, 3))
    i1 = types.Array(types.int64, 1, "C")
    slots = (f3, f1, f3, i1, i1)  # G, f, W, npc, ends (:mod:`.support`)
    cells = (i1, f1, f2, f2)  # axis, sign, lo, hi (:mod:`.branch_bound`)
    samples = (f3, f3, f2)  # U, points, values
    f8, i8 = types.float64, types.int64
    out = {("support", name): (*slots, f2) for name in ENTRY_POINTS["support"]}
    out["branch_bound", "consider"] = (*slots, f2, f2, f1, f1)
    out["branch_bound", "advance"] = (
        *slots, *cells, *samples, types.boolean, f2, f1, f1, f2, f1, f1, f1,
    )  # fmt: skip
    out["nearest_point", "min_norm_point"] = (f2, f8)
    out["nearest_point", "nearest_point_bounds"] = (*slots, f2, f8, i8)
    out["descent", "descend_many"] = (*slots, f2, i8, f8)
    out["descent", "local_minimum"] = (*slots, f1, i8, f8)
    b1 = types.Array(types.boolean, 1, "C")
    terms = (f2, f3, f2, f1)  # P, wrench, weights, top (:func:`.descent.smoothed_terms`)
    out["descent", "smoothed_terms"] = (*slots, f2, f8, b1, *terms, f2)
    out["descent", "smoothed_values"] = (*terms, f2, f8, b1, f1, f2)
    out["descent", "smoothed_trials"] = (f2, f2, f1, f2, b1)
    out["descent", "smoothed_accept"] = (f2, f1, f2, f1, f2, b1, f1, f2)
    i2 = types.Array(types.int64, 2, "C")
    out["zonotope", "capacity_many"] = (f3, i2, i2, f1)
    work = types.Tuple((f2, i1, f2, f1, f2, f2, f1, i1, f1))  # :func:`.branch_bound.slot_work`
    out["branch_bound", "slot_bound"] = (*slots, f2, f2, f2, f8, f8, f8, f1, work)
    out["branch_bound", "exact_bound"] = (f2, i8, f2, f2, f8, f8, f8, f1)
    out["branch_bound", "split"] = (*cells, i8, f2, f1, f8, f8)
    out["branch_bound", "frank_wolfe"] = (f2, i8, f1, f8, i8, f1, f1)
    out["branch_bound", "cloud"] = (f1, f1, f2)
    geo = types.Tuple((f1, f1, f2, f3, f3))  # :func:`.branch_bound.geometry`
    out["branch_bound", "screen"] = (*cells, f2, f8, f2, f8, f8, f1, geo)
    return out


def compile_group(
    group: int, rho_only: bool = False, capacity: bool = True, marks=None, helper=None
) -> None:
    """Compile (or load from the disk cache) the kernels of ``COMPILE_GROUPS[group]``, in
    order, those a warm-up of ``rho_only`` and ``capacity`` wants (:func:`_wanted`).

    ``marks``, a folder shared by the two processes of a cold compile: the helper (group 1)
    marks there each kernel it is done with; the first group, for a kernel of :data:`AWAITED`, waits
    until the helper has marked it (or ``helper``, its process, has ended), then loads it."""
    import importlib

    from numba.core.errors import TypingError

    declared = signatures()
    for module, name in COMPILE_GROUPS[group]:
        if not _wanted((module, name), rho_only, capacity):
            continue
        mark = None if marks is None else Path(marks) / f"{module}.{name}"
        if mark is not None and group == 0 and (module, name) in AWAITED:
            _wait_for(mark, helper)
        try:
            kernel = getattr(importlib.import_module(f"{__name__}.{module}"), name)
            kernel.compile(declared[module, name])
        except TypingError:  # a stale declaration: the kernel compiles at its first call
            pass  # (tests/test_kernel_cache checks the declarations against the calls)
        finally:
            if mark is not None and group == 1:
                mark.touch()


def _wait_for(mark: Path, helper) -> None:
    """Until ``mark`` exists or the process ``helper`` (None: none) has ended."""
    import time

    while helper is not None and helper.poll() is None and not mark.exists():
        time.sleep(0.02)


def helper_code(statements: str) -> str:
    """``statements`` for ``python -c``, with this package first on the path: ``-c`` puts the
    working folder first, where another checkout of the package would otherwise be imported
    (and its kernels compiled into another cache)."""
    root = str(Path(__file__).resolve().parents[2])
    return f"import sys; sys.path.insert(0, {root!r}); {statements}"


def compile_in_parallel(rho_only: bool = False, capacity: bool = True) -> None:
    """The first list of kernels compiled here while another process compiles the second
    (on a machine of one core, or should the other process fail, this one compiles it after:
    the same kernels, the same cache)."""
    import shutil
    import subprocess

    helper = None
    marks = tempfile.mkdtemp(prefix="closure_nlp_compile_")
    if (os.cpu_count() or 1) > 1:
        code = helper_code(
            f"from {__name__} import compile_group; "
            f"compile_group(1, {rho_only}, {capacity}, {marks!r})"
        )
        try:
            helper = subprocess.Popen(
                [sys.executable, "-c", code],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        except (OSError, ValueError):  # no interpreter to start: compile it all here
            helper = None
    try:
        compile_group(0, rho_only, capacity, marks, helper)
        if helper is not None:
            helper.wait()  # its kernels then load from the disk cache (or compile here, failed)
    except BaseException:  # an interrupt: no process left compiling behind
        if helper is not None and helper.poll() is None:
            helper.kill()
            helper.wait()
        raise
    finally:
        shutil.rmtree(marks, ignore_errors=True)


def cached(rho_only: bool = False, capacity: bool = True) -> bool:
    """Whether every kernel called from Python that a warm-up of ``rho_only`` and ``capacity``
    wants (:func:`_wanted`) has a current copy in numba's disk cache (the index numba reads:
    empty when missing or when the source changed since)."""
    import importlib

    try:
        for module, names in ENTRY_POINTS.items():
            loaded = importlib.import_module(f"{__name__}.{module}")
            for name in names:
                if not _wanted((module, name), rho_only, capacity):
                    continue
                if not getattr(loaded, name)._cache._cache_file._load_index():
                    return False
        return True
    except Exception:  # numba's cache layout is private: assume a compile is due
        return False
