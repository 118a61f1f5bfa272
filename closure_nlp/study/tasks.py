"""One task of a study, and running it on a worker (solvers cached per thread)."""

from __future__ import annotations

import ctypes
import gc
import hashlib
import json
import os
import socket
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from functools import cached_property
from pathlib import Path

from closure_nlp._version import __version__
from closure_nlp.base.files import parse_json, read_input
from closure_nlp.base.solver_cache import PerThread
from closure_nlp.contact.contact_set import contact_set_from_dict
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import SupportMinimizer
from closure_nlp.model.elements import model_from_dict
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
from closure_nlp.planning.seeds import wrench_unit
from closure_nlp.selection.algorithms import SelectionOptions
from closure_nlp.study.store import ROW_COLUMNS

TASK_VERSION = 2  # part of every task_id: bump when a task's meaning changes (2: alternatives)

_NOT_SHARED = ("model", "model_file", "seed")

# runner(task, model_text) -> row: what a worker runs for one task (tests swap it).
Runner = Callable[["Task", "str | None"], dict]


@dataclass(frozen=True)
class Task:
    """One planning run: a model, ``contacts`` contacts of one type and parameters, one seed.

    Parameters that do not act on the contact type are ``None`` (``mu`` and ``mu_s`` of FPC,
    ``mu_s`` of PCwF), so grid points that differ only in them are one task.

    Attributes
    ----------
    model : str
        Label of the model (its file name without ``.model.json``).
    model_file : str
        Absolute path of the model file (not part of :attr:`task_id`: moving a study keeps it).
    model_digest : str
        Hash of the model file's content (part of :attr:`task_id`: an edited model is new work).
    type : str
        ``fpc``, ``pcwf``, ``sfcl`` or ``sfce``.
    contacts : int
        Number of contacts m.
    mu, mu_s : float or None
    f_max, torque_scale : float
    seed : int
        Seed of the heuristic's random start element.
    selection, placement : tuple of (str, object)
        Every field of :class:`SelectionOptions` and :class:`PlacementOptions`, sorted by name.
    intent : tuple of (str, object)
        Where contacts may go and the contacts already in place, for every task of the study:
        ``only`` and ``exclude`` (tuples of regions) and ``fixed`` (the contact-set file's
        content as canonical JSON text, or None); empty when the study gives none.
    loads : str or None
        The load cases (canonical JSON of a LOADS.json) whose certified factors the row
        reports; part of :attr:`task_id` only when given.
    objective : str or None
        ``"loads"``: the plan steered by the least load factor
        (:func:`~closure_nlp.planning.load_steering.steer_by_loads`); ``"rho"``; ``None``
        without loads.
    """

    model: str
    model_file: str = field(compare=False)
    model_digest: str
    type: str
    contacts: int
    mu: float | None
    mu_s: float | None
    f_max: float
    torque_scale: float
    seed: int
    selection: tuple[tuple[str, object], ...]
    placement: tuple[tuple[str, object], ...]
    intent: tuple[tuple[str, object], ...] = ()
    loads: str | None = None
    objective: str | None = None

    def inputs(self) -> dict:
        """Everything the result depends on, as plain JSON values (the model by its digest;
        no ``loads`` or ``objective`` without loads, so such a task's id is as before)."""
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "model_file"}
        data["selection"] = dict(self.selection)
        data["placement"] = dict(self.placement)
        data["intent"] = dict(self.intent)
        if not self.intent:  # the ids of studies without it stay as they were
            del data["intent"]
        if self.loads is None:
            del data["loads"], data["objective"]
        else:
            data["loads"] = json.loads(self.loads)
        return {"version": TASK_VERSION, **data}

    @cached_property  # a run asks for it several times per task; hashing is most of its cost
    def task_id(self) -> str:
        """16 hex digits of the SHA-256 of the canonical JSON of :meth:`inputs`."""
        text = json.dumps(self.inputs(), sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def memo_group(self) -> tuple:
        """Everything but the seed: the tasks of one group share a worker's solvers and its plan
        memo (:func:`run_task`), so seeds meeting the same element sets reuse each other's work
        only when one worker runs them (:func:`~closure_nlp.study.running.run_study`)."""
        return tuple(getattr(self, f.name) for f in fields(self) if f.name not in _NOT_SHARED)

    def specs(self):
        """The contact specs of this task (defaults for the parameters that are ``None``)."""
        given = {"mu": self.mu, "mu_s": self.mu_s}
        return contact_specs(
            self.contacts,
            type=self.type,
            f_max=self.f_max,
            **{k: v for k, v in given.items() if v is not None},
        )

    def selection_options(self) -> SelectionOptions:
        """The options of the heuristic and iterative algorithms."""
        return SelectionOptions(**dict(self.selection))

    def intent_keywords(self) -> dict:
        """``only``, ``exclude`` and ``fixed`` as :class:`Eligibility` takes them."""
        out = dict(self.intent)
        if out.get("fixed") is not None:
            out["fixed"] = contact_set_from_dict(json.loads(out["fixed"]))
        return out

    def placement_options(self) -> PlacementOptions:
        """The options of the contact placement."""
        return PlacementOptions(**dict(self.placement))


# The grid's axes: the fields of a task that a study file gives as one value or a list (the
# study's keys and the result rows' columns are derived from the Task fields).
GRID_AXES = tuple(
    f.name
    for f in fields(Task)
    if f.name
    not in {"model", "model_file", "model_digest", "seed", "selection", "placement", "intent"}
    and f.name not in {"loads", "objective"}  # one value for the whole study
)

_CACHE_SIZE = 8
# A worker drops its solver caches when its resident set after a task has grown by more than
# this since the first task after its last drop (their NLPs, 2-5 MB per element-set shape and
# 15-30 MB per exchange shape, are most of the growth on the fixture study's pistol). Relative,
# because most of the floor is not the caches': the numba kernels hold about 150 MiB, and about
# 250 MiB more in a worker that compiled them. A fixed 450 MiB, which every fixture task passes,
# would rebuild every solver per task and lose the plan memo (seeds meeting the same elements),
# which is what makes a model's later seeds cheaper.
MEMORY_GROWTH_MIB = 256.0
# Per thread: CasADi solvers must not be called from two threads at once, and a joined cluster's
# workers may run several tasks at a time (the local cluster's have one thread each).
_local = threading.local()


def _solvers(task: Task, model_text: str | None) -> tuple[Eligibility, Placer, dict, bool]:
    """The :class:`Eligibility` and :class:`Placer` of ``task``, from this thread's cache, and
    the memo of the plans on that eligibility (:func:`~closure_nlp.planning.plan.plan`: seeds whose
    heuristic meets the same set reuse the iterative run and the placement).

    Returns them and whether a solver object was made now. One :class:`SupportMinimizer` serves
    every task of a model (its CasADi NLPs are cached by shape, the numbers are parameters); the
    last few (specs, torque scale) combinations keep their eligibility and placers, so the
    placement NLPs are built once per worker too. A task on another model than the previous one
    drops them all (:func:`release_memory`): the NLP shapes differ between models anyway, and a
    worker that kept them would grow by every model's solvers for no gain in time. Tasks come in
    grid order, models outermost, so a worker meets each model about once.
    """
    if getattr(_local, "model", None) not in (None, task.model_digest):
        release_memory()
    _local.model = task.model_digest
    if not hasattr(_local, "cache"):
        _local.cache, _local.minimizer = OrderedDict(), SupportMinimizer()
        _local.problems = PerThread(dict)  # exchange NLPs, shared by the thread's placers
    cache = _local.cache
    key = (task.model_digest, task.type, task.contacts, task.mu, task.mu_s, task.f_max)
    key += (task.torque_scale, task.intent)
    built = key not in cache
    if built:
        if model_text is None:
            raw = read_input(task.model_file)
            if hashlib.sha256(raw).hexdigest()[:16] != task.model_digest:
                raise ValueError(f"{task.model_file}: model file changed since the study was read")
            model_text = raw.decode("utf-8")
        model = model_from_dict(parse_json(model_text), Path(task.model_file).parent)
        eligibility = Eligibility(
            model, task.specs(), task.torque_scale, _local.minimizer, **task.intent_keywords()
        )
        cache[key] = (eligibility, {}, {})
        while len(cache) > _CACHE_SIZE:
            cache.popitem(last=False)
    cache.move_to_end(key)
    eligibility, placers, memo = cache[key]
    if task.placement not in placers:
        placers[task.placement] = Placer(eligibility, task.placement_options(), _local.problems)
        built = True
    return eligibility, placers[task.placement], memo, built


def clear_cache() -> None:
    """Forget this thread's solvers (tests; memory)."""
    _local.__dict__.clear()


def release_memory() -> None:
    """Forget this thread's solvers and hand the freed heap back to the system (glibc keeps it
    otherwise, the more so as :func:`~closure_nlp.study.local_cluster` raises its trim
    threshold back to the default for speed)."""
    clear_cache()
    gc.collect()
    trim_heap()


def _limit_memory() -> None:
    """Drop this thread's solvers when the resident set has grown by more than
    :data:`MEMORY_GROWTH_MIB` since the first task after the last drop (the floor: the kernels,
    the libraries and one task's solvers); rebuild what is needed then."""
    rss = worker_memory().get("rss_mib", 0.0)
    floor = getattr(_local, "floor", None)
    if floor is None:
        _local.floor = rss
    elif rss > floor + MEMORY_GROWTH_MIB:
        release_memory()  # clears the floor too: the next task sets it again


def trim_heap() -> None:
    """Hand the heap's free pages back to the system (glibc keeps them otherwise: a fixture
    study's worker held 2.4 GB between tasks whose live data was a fraction of it)."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: the memory is freed, just not returned
        pass


def run_task(task: Task, model_text: str | None = None) -> dict:
    """Run one task: heuristic, iterative selection and placement; never raises for a failure
    of the method or bad input, which is recorded in the row's ``error``.

    Parameters
    ----------
    task : Task
    model_text : str, optional
        The model file's content (sent by the driver, so workers need no shared file system);
        read from ``task.model_file`` when omitted.

    Returns
    -------
    dict
        One result row (the columns of :data:`ROW_COLUMNS`).
    """
    t0 = time.perf_counter()
    row = task_row(task)
    try:
        eligibility, placer, memo, built = _solvers(task, model_text)
        setup = time.perf_counter() - t0
        result = plan(
            eligibility,
            seed=task.seed,
            seeds=1,
            selection=task.selection_options(),
            placer=placer,
            memo=memo,
        )
        factors = None
        if task.loads is not None:
            result, factors = _with_loads(task, eligibility, placer, result)
        first, second, placed, seconds, attempts, reused = (
            result.heuristic,
            result.iterative,
            result.placement,
            result.seconds,
            len(result.attempts),
            ",".join(result.reused),
        )
    except Exception as exc:  # noqa: BLE001 - a failing task is recorded, the study goes on
        row.update(status="error", error=f"{type(exc).__name__}: {exc}")
        row["wall_seconds"] = time.perf_counter() - t0
        return row
    finally:
        trim_heap()  # the next task starts from the live data, not the last one's peak
        _limit_memory()
    for prefix, result in (("heuristic", first), ("iterative", second)):
        row[f"{prefix}_elements"] = [int(e) for e in result.elements]
        row[f"{prefix}_rho_hat"] = float(result.rho_hat)
        row[f"{prefix}_rho_hat_lo"], row[f"{prefix}_rho_hat_hi"] = _bounds(result.bounds)
        row[f"{prefix}_eligible"] = bool(result.eligible)
        row[f"{prefix}_evaluations"] = int(result.evaluations)
        row[f"{prefix}_seconds"] = float(result.seconds)
    rho_lo, rho_hi = _bounds(placed.bounds)
    row.update(
        status="ok",
        heuristic_rounds=int(first.rounds),
        elements=[int(e) for e in placed.elements],
        rho=float(placed.rho),
        rho_lo=rho_lo,
        rho_hi=rho_hi,
        rho_unit=wrench_unit(eligibility, placed.elements),
        force_closure=bool(placed.force_closure),
        robust=bool(placed.force_closure if placed.robust is None else placed.robust),
        marginal=bool(placed.marginal),
        converged=bool(placed.converged),
        start_rho=float(placed.start_rho),
        capacity_bound=placed.capacity_bound,
        gap=placed.gap,
        placement_rounds=int(placed.rounds),
        placement_moves=len(placed.moves),
        placement_attempts=attempts,
        placement_seconds=float(placed.seconds),
        placed_contacts=json.dumps([c.to_dict() for c in placed.contacts]),
        seconds=seconds,
        reused=reused,
        setup_seconds=setup,
        solvers_built=built,
        wall_seconds=time.perf_counter() - t0,
        **worker_memory(),
    )
    if factors is not None:
        lo, hi = factors.bounds
        row.update(
            load_factor=float(factors.load_factor),
            load_factor_lo=float(lo),
            load_factor_hi=float(hi),
            load_factors=json.dumps(factors.to_dict()["loads"]),
        )
    return row


def _with_loads(task: Task, eligibility, placer, result):
    """The plan steered by the task's loads when its objective says so, and the certified
    factors of the loads on its placed contacts."""
    from closure_nlp.contact.loads import as_loads
    from closure_nlp.criterion.load_factor import load_factors
    from closure_nlp.planning.load_steering import steer_by_loads

    loads = as_loads(json.loads(task.loads))
    if task.objective == "loads":
        result = steer_by_loads(eligibility, result, loads, placer.options, seed=task.seed)
    return result, load_factors(result.placement.contact_set, loads)


def _bounds(bounds) -> tuple[float | None, float | None]:
    """A result's certified ``(lo, hi)`` as row values (empty when it has none)."""
    return (None, None) if bounds is None else (float(bounds[0]), float(bounds[1]))


def worker_memory() -> dict:
    """This process's resident set now and its peak so far, in MiB (Linux ``/proc``; empty
    elsewhere): a study's ``results.csv`` shows what its workers held."""
    keys = {"VmRSS:": "rss_mib", "VmHWM:": "peak_rss_mib"}
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            lines = status.read().splitlines()
    except OSError:
        return {}
    found = {}
    for line in lines:
        parts = line.split()
        if parts and parts[0] in keys:
            found[keys[parts[0]]] = int(parts[1]) / 1024.0  # kB
    return found


# The task's fields that a row holds as they are (the options go in as JSON).
_TASK_COLUMNS = tuple(
    f.name
    for f in fields(Task)
    if f.name not in {"model_file", "selection", "placement", "intent", "loads"}
)


def task_row(task: Task) -> dict:
    """A result row with the task's inputs filled in and every result column empty."""
    row = dict.fromkeys(ROW_COLUMNS)
    row.update(
        {name: getattr(task, name) for name in _TASK_COLUMNS},
        task_id=task.task_id,
        selection=json.dumps(dict(task.selection), sort_keys=True),
        placement=json.dumps(dict(task.placement), sort_keys=True),
        worker=f"{socket.gethostname()}:{os.getpid()}",
        finished=datetime.now(timezone.utc).isoformat(timespec="seconds"),
        closure_nlp=__version__,
    )
    return row


def error_row(task: Task, message: str) -> dict:
    """The row of a task that failed outside :func:`run_task` (a dead worker, say)."""
    row = task_row(task)
    row.update(status="error", error=message, worker=None)
    return row
