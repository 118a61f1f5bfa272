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
import logging
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

log = logging.getLogger("closure_nlp")


def _user_cache_folders() -> list[Path]:
    """Where the kernels may cache when their own folder is read-only: the user's cache
    folder, then the temporary folder (either left out when there is none)."""
    folders = []
    base = os.environ.get("XDG_CACHE_HOME") or (
        os.environ.get("LOCALAPPDATA") if sys.platform == "win32" else None
    )
    try:
        folders.append((Path(base) if base else Path.home() / ".cache") / "closure_nlp" / "numba")
    except (RuntimeError, KeyError):  # no home folder to be found
        pass
    try:
        folders.append(Path(tempfile.gettempdir()) / "closure_nlp")
    except OSError:  # gettempdir raises when no candidate folder is writable
        pass
    return folders


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
    for folder in _user_cache_folders():
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            os.environ["NUMBA_CACHE_DIR"] = str(folder)
            return


_cache_dir_fallback()


def _probe() -> int:
    return 0


def _find_cache_folder() -> Path | None:
    """The folder numba caches this folder's kernels in (its own choice among the user's
    ``NUMBA_CACHE_DIR``, ``__pycache__`` and a user-wide folder, each tried for writing),
    None when it can write none: the kernels then compile in memory at every start."""
    from numba import njit

    try:
        return Path(njit(cache=True)(_probe).stats.cache_path)
    except Exception:  # numba refuses cache=True when it finds no writable folder
        return None


CACHE_FOLDER = _find_cache_folder()
CACHE = CACHE_FOLDER is not None  # the kernels' ``cache`` option
_STAMP = "closure_nlp_kernels.sha256"  # the sources the cached kernels were compiled from
# The kernels a completed compile left in the cache: written only after each was compiled and
# saved without error, so that a start finding it loads them without a compile notice.
_WARM = "closure_nlp_kernels.warm"


def sources_digest(folder: Path) -> str:
    """A digest of every kernel module's source in ``folder``."""
    digest = hashlib.sha256()
    for source in sorted(folder.glob("*.py")):
        digest.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    return digest.hexdigest()


def _is_kernel_file(entry: Path, modules) -> bool:
    """Whether ``entry`` is a cached kernel of ``modules``: numba names its files
    ``module.function-line.pyXY[.n].nbi|nbc``, and ``.tmp.<id>`` after them while writing."""
    name = entry.name
    return name.split(".")[0] in modules and (
        entry.suffix in (".nbi", ".nbc") or ".nbi.tmp." in name or ".nbc.tmp." in name
    )


def drop_stale_cache(cache: Path, digest: str, modules) -> None:
    """Remove ``modules``' compiled kernels from ``cache`` unless they were compiled from the
    sources of ``digest``: numba checks a cached kernel against its own file only, and a kernel
    compiled with an older version of a callee in another module would load unchanged."""
    stamp = cache / _STAMP
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        # made first: a folder numba has yet to create (a fresh NUMBA_CACHE_DIR) gets its stamp
        # now, else the next process would drop every kernel this one compiles
        cache.mkdir(parents=True, exist_ok=True)
        _wipe(cache, modules)
        stamp.write_text(digest)
    except OSError:  # none writable: numba caches nothing there either
        pass


def _wipe(cache: Path, modules, keep=frozenset()) -> None:
    """Remove ``modules``' cached kernels, but those named in ``keep`` (``module.function``),
    and the stamp of a completed compile, from ``cache`` (those that can be removed)."""
    try:
        entries = list(cache.iterdir())
    except OSError:
        return
    for entry in entries:
        kernel = _is_kernel_file(entry, modules) and entry.name.split("-", 1)[0] not in keep
        if kernel or entry.name == _WARM:
            try:
                entry.unlink(missing_ok=True)
            except OSError:
                pass


def _in_memory() -> frozenset:
    """``module.function`` of every kernel of this package compiled or loaded in this process."""
    names = set()
    for module_name, module in list(sys.modules.items()):
        if not module_name.startswith(f"{__name__}.") or module is None:
            continue
        for value in vars(module).values():
            if getattr(value, "overloads", None) and hasattr(value, "py_func"):
                names.add(f"{module_name.rsplit('.', 1)[1]}.{value.py_func.__qualname__}")
    return frozenset(names)


def _drop_damaged(error: Exception, notify=None) -> None:
    """After ``error`` loading a cached kernel: every cached kernel of this package that this
    process has not loaded or compiled is removed (the damaged file among them; those in
    memory loaded well, and stay for the next start), said once."""
    _trouble["healed"] = True
    _wipe(CACHE_FOLDER, _MODULES, keep=_in_memory())
    _notice(
        f"a damaged compiled kernel in {CACHE_FOLDER} ({type(error).__name__}: {error}): "
        "the cached kernels not yet loaded are dropped and compiled again",
        notify,
    )


_HERE = Path(__file__).resolve().parent
_MODULES = frozenset(source.stem for source in _HERE.glob("*.py"))
_DIGEST = sources_digest(_HERE)
if CACHE_FOLDER is not None:
    drop_stale_cache(CACHE_FOLDER, _DIGEST, _MODULES)


def _identity() -> str:
    """What a cached kernel was compiled by: these sources, this numba and this Python."""
    import numba

    return f"{_DIGEST} numba {numba.__version__} python {sys.implementation.cache_tag}"


# What went wrong with the disk cache in this process: ``unwritable`` once a kernel could not be
# saved (from then on the kernels compile in memory), ``healed`` once damaged cached kernels
# were dropped (once: a second failure is not the cache's).
_trouble = {"unwritable": False, "healed": False}
_said: set = set()


def _notice(text: str, notify=None) -> None:
    """``text`` once per process, as a ``warning:`` line: through ``notify`` when given, else
    as a Python warning (the CLI shows each as one ``warning:`` line); the library never
    prints."""
    if text in _said:
        return
    _said.add(text)
    log.info(text)
    if notify is not None:
        notify(f"warning: {text}")
    else:
        import warnings

        warnings.warn(text, RuntimeWarning, stacklevel=3)


def _no_cache_notice(notify=None) -> None:
    _notice(
        "no writable folder for the compiled kernels' disk cache: they compile in memory, "
        "at every start",
        notify,
    )


# Tries of one compile through a cache that cannot be written: each failed save leaves one more
# kernel compiled in memory (more than the package has kernels).
_TRIES = 200


def _compile(kernel, signature, notify=None) -> None:
    """``kernel.compile(signature)`` whatever the disk cache holds or accepts.

    A cached kernel numba fails to load (a truncated, empty or foreign file) drops the cached
    kernels not yet loaded (:func:`_drop_damaged`), and the compile starts again (once per
    process). A
    kernel numba cannot save (a full disk, a read-only folder): numba keeps a kernel it has
    compiled before saving it, so the compile started again finds that one in memory and goes
    on to the next; said once. A :class:`~numba.core.errors.TypingError` is the caller's."""
    from numba.core.errors import TypingError

    for _ in range(_TRIES):
        try:
            kernel.compile(signature)
            return
        except TypingError:
            raise
        except OSError as error:
            _trouble["unwritable"] = True
            reason = error.strerror or str(error)
            _notice(
                f"the compiled kernels cannot be saved in {CACHE_FOLDER} ({reason}): "
                "compiled in memory, again at the next start",
                notify,
            )
        except Exception as error:
            if _trouble["healed"] or CACHE_FOLDER is None:
                raise
            _drop_damaged(error, notify)
    kernel.compile(signature)


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
        *slots, *cells, f2, *samples, i8, f2, f1, f1, f2, f1, f1, f1,
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
    out["branch_bound", "split"] = (*cells, i8, f2, f1, f8, f8, f8)
    out["branch_bound", "frank_wolfe"] = (f2, i8, f1, f8, i8, f1, f1)
    out["branch_bound", "cloud"] = (f1, f1, f2)
    geo = types.Tuple((f1, f1, f2, f3, f3))  # :func:`.branch_bound.geometry`
    out["branch_bound", "screen"] = (*cells, f2, f8, f2, f8, f8, f1, geo)
    return out


def compile_group(
    group: int,
    rho_only: bool = False,
    capacity: bool = True,
    marks=None,
    helper=None,
    notify=None,
) -> None:
    """Compile (or load from the disk cache) the kernels of ``COMPILE_GROUPS[group]``, in
    order, those a warm-up of ``rho_only`` and ``capacity`` wants (:func:`_wanted`).

    ``marks``, a folder shared by the two processes of a cold compile: the helper (group 1)
    marks there each kernel it is done with; the first group, for a kernel of :data:`AWAITED`, waits
    until the helper has marked it (or ``helper``, its process, has ended), then loads it. A
    helper that cannot save a kernel stops: what it compiles in memory is of no use to the
    other process."""
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
            _compile(kernel, declared[module, name], notify)
        except TypingError:  # a stale declaration: the kernel compiles at its first call
            pass  # (tests/test_kernel_cache checks the declarations against the calls)
        finally:
            if mark is not None and group == 1:
                mark.touch()
        if mark is not None and group == 1 and _trouble["unwritable"]:
            return


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


_MARKS_PREFIX = "closure_nlp_compile_"


def _marks_folder() -> Path | None:
    """A new folder for the marks of a cold compile, named after this process (a folder whose
    process has ended is removed here: one killed mid-compile leaves its own), None when
    there is no temporary folder to write."""
    import shutil

    try:
        temporary = Path(tempfile.gettempdir())
        for folder in temporary.glob(f"{_MARKS_PREFIX}*_*"):
            pid = folder.name[len(_MARKS_PREFIX) :].split("_")[0]
            if pid.isdigit() and not _alive(int(pid)):
                shutil.rmtree(folder, ignore_errors=True)
        return Path(tempfile.mkdtemp(prefix=f"{_MARKS_PREFIX}{os.getpid()}_"))
    except OSError:
        return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def _helper(rho_only: bool, capacity: bool, marks: str, parent: int) -> None:
    """The compile helper's process: the second list of kernels, for as long as ``parent``
    (the process that started it) lives; orphaned, it removes the marks and ends at once (its
    compile is of use to no one)."""
    import shutil
    import threading
    import time

    def watch():
        while os.getppid() == parent:
            time.sleep(0.1)
        shutil.rmtree(marks, ignore_errors=True)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
    compile_group(1, rho_only, capacity, marks)


def compile_in_parallel(rho_only: bool = False, capacity: bool = True, notify=None) -> None:
    """The first list of kernels compiled here while another process compiles the second,
    then the second loaded here from the cache the other process wrote (on a machine of one
    core, without a temporary folder or disk cache, or should the other process fail, this
    one compiles it: the same kernels, the same cache). Once every kernel is compiled and
    saved, the cache is stamped as holding them (:func:`cached`)."""
    import shutil
    import subprocess

    if not CACHE:
        _no_cache_notice(notify)
    helper = marks = None
    if CACHE and (os.cpu_count() or 1) > 1:
        marks = _marks_folder()
    if marks is not None:
        code = helper_code(
            f"from {__name__} import _helper; "
            f"_helper({rho_only}, {capacity}, {str(marks)!r}, {os.getpid()})"
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
        compile_group(0, rho_only, capacity, marks, helper, notify)
        if helper is not None:
            helper.wait()
        compile_group(1, rho_only, capacity, notify=notify)
    except BaseException:  # an interrupt: no process left compiling behind
        if helper is not None and helper.poll() is None:
            helper.kill()
            helper.wait()
        raise
    finally:
        if marks is not None:
            shutil.rmtree(marks, ignore_errors=True)
    if CACHE and not _trouble["unwritable"]:
        _stamp_warm(_entry_points(rho_only, capacity))


# Entry points a certified rho runs only inside other kernels (the local minimiser calls
# Wolfe's nearest point): a warm ``rho`` command loads them not (milliseconds each).
INNER_IN_RHO = (("nearest_point", "min_norm_point"),)


def _entry_points(rho_only: bool, capacity: bool) -> list:
    """The kernels called from Python that a warm-up of ``rho_only`` and ``capacity`` wants."""
    return [
        (module, name)
        for module, names in ENTRY_POINTS.items()
        for name in names
        if _wanted((module, name), rho_only, capacity)
    ]


def _stamp_warm(kernels) -> None:
    """Add ``kernels`` to the stamp of the kernels a completed compile saved (written whole,
    then renamed: never read half-written)."""
    stamp = CACHE_FOLDER / _WARM
    names = {f"{module}.{name}" for module, name in kernels}
    try:
        lines = stamp.read_text().splitlines()
        if lines and lines[0] == _identity():
            names.update(lines[1:])
    except OSError:
        pass
    text = "\n".join([_identity(), *sorted(names)]) + "\n"
    part = stamp.with_name(f"{_WARM}.{os.getpid()}.part")
    try:
        part.write_text(text)
        os.replace(part, stamp)
    except OSError:  # not written: the next start compiles (loads) and says so
        try:
            part.unlink(missing_ok=True)
        except OSError:
            pass


def cached(rho_only: bool = False, capacity: bool = True, notify=None) -> bool:
    """Whether every kernel called from Python that a warm-up of ``rho_only`` and ``capacity``
    wants (:func:`_wanted`) is in the disk cache, compiled from these sources by this numba and
    Python (a completed compile's stamp says so), and loads: they are loaded here (the warm-up
    runs them next). A cached kernel that fails to load drops those not yet loaded
    (:func:`_drop_damaged`), said once through ``notify``: False, a compile is due."""
    import importlib

    from numba.core.errors import TypingError

    if not CACHE:
        _no_cache_notice(notify)
        return False
    wanted = _entry_points(rho_only, capacity)
    try:
        lines = (CACHE_FOLDER / _WARM).read_text().splitlines()
    except (OSError, UnicodeDecodeError):
        return False
    if not lines or lines[0] != _identity():
        return False
    if not {f"{module}.{name}" for module, name in wanted} <= set(lines[1:]):
        return False
    declared = signatures()
    for module, name in wanted:
        if rho_only and (module, name) in INNER_IN_RHO:
            continue
        kernel = getattr(importlib.import_module(f"{__name__}.{module}"), name)
        misses = sum(kernel.stats.cache_misses.values())
        try:
            kernel.compile(declared[module, name])
        except TypingError:
            return False
        except Exception as error:  # a damaged file: numba loads it with no check of its own
            _drop_damaged(error, notify)
            return False
        if sum(kernel.stats.cache_misses.values()) > misses:  # its file gone: compiled here
            return False
    return True
