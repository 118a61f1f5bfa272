"""Studies: grids of planning runs on many models, contact types and seeds, run on Dask.

A study file (TOML) names a grid: models (files, or folders of ``*.model.json``, relative to the
study file), contact types and counts, ``mu``, ``mu_s``, ``f_max``, ``torque_scale`` (each one
value or a list), seeds (a count or a list) and the options of the selection and placement
algorithms::

    name = "grasps"
    models = ["../../models/lamp.model.json", "../../models/cup.model.json"]
    type = ["pcwf", "sfce"]
    contacts = [3, 4]
    mu = [0.2, 0.4]
    seeds = 20

    [placement]
    starts = 2

Keys: ``models`` (required; a path or a list), ``contacts`` (required; number of contacts m),
``type`` (default ``"pcwf"``), ``mu`` (0.2), ``mu_s`` (0.2), ``f_max`` (1), ``torque_scale`` (1),
``seeds`` (1: seed 0), ``name`` (default: the file name), ``description``, and the tables
``[selection]`` (fields of :class:`~closure_nlp.selection.SelectionOptions`) and ``[placement]``
(fields of :class:`~closure_nlp.placement.PlacementOptions`). Every value-or-list key is one
axis of the grid; an unknown key or option, a missing model or a bad value is a ``ValueError``
(or ``TypeError``) that names the key and the value.

:func:`load_study` validates everything before anything runs and expands the grid into
:class:`Task` objects, each with a stable ``task_id`` (a hash of its inputs). :func:`run_study`
runs the tasks not done yet on a ``dask.distributed`` cluster (a local one by default) or
serially, and writes one Parquet part-file per task in ``OUT/results/`` as each task finishes, so
a crash loses nothing already done and running the study again resumes it. At the end it writes
a summary table (``summary.md``, ``summary.csv``), all rows (``results.csv``) and plots
(``rho.png``, ``seconds.png``).

Each worker builds the solvers of a (model, contact specs, torque scale) once and reuses them for
every seed (:func:`run_task` keeps a small per-thread cache); the rho and rho_hat NLPs, cached
by shape, serve every task of the worker.

A result row (:data:`ROW_COLUMNS`) holds the task's inputs, ``status`` (``ok`` or ``error``) and
``error``; per selection step its ``elements``, ``rho_hat``, ``eligible``, ``evaluations`` and
``seconds``; the placement's ``elements``, ``rho``, ``force_closure``, ``start_rho``, rounds,
moves, seconds and the placed contacts (JSON); the task's ``seconds`` (the three steps),
``setup_seconds`` (model and problem objects; CasADi builds its solvers lazily, inside the first
step), ``wall_seconds``, ``solvers_built`` (this task met an empty cache), ``worker``
(``host:pid``) and ``finished`` (UTC).
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import socket
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields
from datetime import datetime, timezone
from itertools import product
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from . import __version__
from .contacts import DEFAULT_F_MAX, DEFAULT_MU, DEFAULT_MU_S, ContactType, contact_specs
from .elements import load_model, model_from_dict
from .eligibility import Eligibility
from .files import write_atomic, write_json
from .placement import PlacementOptions, Placer
from .planning import plan
from .quality import SupportMinimizer
from .selection import SelectionOptions
from .validation import as_number, check_keys

log = logging.getLogger(__name__)

STUDY_KEYS = {
    "name",
    "description",
    "models",
    "type",
    "contacts",
    "mu",
    "mu_s",
    "f_max",
    "torque_scale",
    "seeds",
    "selection",
    "placement",
}
REQUIRED_KEYS = {"models", "contacts"}
TASK_VERSION = 1  # part of every task_id: bump when a task's meaning changes
MODEL_SUFFIX = ".model.json"

# progress(done, total, row): called in the driver before the first task (row None) and after
# every finished task (its row already written); an exception raised there stops the study.
StudyProgress = Callable[[int, int, dict], None]
# runner(task, model_text) -> row: what a worker runs for one task (tests swap it).
Runner = Callable[["Task", "str | None"], dict]


# --- the study file -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ModelRef:
    """A model of a study: its label, file, content digest and text (shipped to workers)."""

    label: str
    path: Path
    digest: str
    text: str = field(repr=False, compare=False)


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

    def inputs(self) -> dict:
        """Everything the result depends on, as plain JSON values (the model by its digest)."""
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "model_file"}
        data["selection"] = dict(self.selection)
        data["placement"] = dict(self.placement)
        return {"version": TASK_VERSION, **data}

    @property
    def task_id(self) -> str:
        """16 hex digits of the SHA-256 of the canonical JSON of :meth:`inputs`."""
        text = json.dumps(self.inputs(), sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

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

    def placement_options(self) -> PlacementOptions:
        """The options of the contact placement."""
        return PlacementOptions(**dict(self.placement))


@dataclass(frozen=True)
class Study:
    """A validated study: its grid and the tasks it expands into.

    Attributes
    ----------
    name, description : str
    source : Path or None
        The study file.
    models : tuple of ModelRef
    grid : dict
        ``type``, ``contacts``, ``mu``, ``mu_s``, ``f_max``, ``torque_scale``: tuples of values.
    seeds : tuple of int
    selection : SelectionOptions
    placement : PlacementOptions
    tasks : tuple of Task
        Grid order (models, types, counts, parameters, then seeds innermost), without repeats.
    duplicates : int
        Grid points dropped because they repeat a task (e.g. several ``mu`` for FPC).
    """

    name: str
    description: str
    source: Path | None
    models: tuple[ModelRef, ...]
    grid: dict
    seeds: tuple[int, ...]
    selection: SelectionOptions
    placement: PlacementOptions
    tasks: tuple[Task, ...]
    duplicates: int

    def to_dict(self) -> dict:
        """The resolved study as JSON values (written as ``OUT/study.json``)."""
        return {
            "name": self.name,
            "description": self.description,
            "source": str(self.source) if self.source else None,
            "models": [
                {"label": m.label, "path": str(m.path), "digest": m.digest} for m in self.models
            ],
            "grid": {k: list(v) for k, v in self.grid.items()},
            "seeds": list(self.seeds),
            "selection": asdict(self.selection),
            "placement": asdict(self.placement),
            "tasks": len(self.tasks),
            "duplicates": self.duplicates,
        }


def load_study(path) -> Study:
    """Read and validate a study file (TOML) and expand its grid.

    Raises
    ------
    ValueError, TypeError
        For an unreadable or malformed file, an unknown or missing key, a missing or invalid
        model, or a bad value; the message names the key and the value.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError("file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read file: {exc.__class__.__name__}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"malformed TOML: {exc}") from None
    name = path.name.removesuffix(".toml").removesuffix(".study")
    return study_from_dict(data, path.resolve().parent, default_name=name, source=path)


def study_from_dict(
    data: dict, base_dir, *, default_name: str = "study", source: Path | None = None
) -> Study:
    """Validate a study given as a dict (the TOML layout); model paths are relative to
    ``base_dir``. See :func:`load_study`."""
    check_keys(data, "study", STUDY_KEYS, REQUIRED_KEYS)
    name = _text(data, "name", default_name)
    description = _text(data, "description", "")
    grid = {
        "type": _axis(data, "type", "pcwf", lambda v, f: ContactType.parse(v, f).value),
        "contacts": _axis(data, "contacts", None, _count),
        "mu": _axis(data, "mu", DEFAULT_MU, _number(strict=False)),
        "mu_s": _axis(data, "mu_s", DEFAULT_MU_S, _number(strict=False)),
        "f_max": _axis(data, "f_max", DEFAULT_F_MAX, _number(strict=True)),
        "torque_scale": _axis(data, "torque_scale", 1.0, _number(strict=True)),
    }
    seeds = _seeds(data.get("seeds", 1))
    selection = _options(data, "selection", SelectionOptions)
    placement = _options(data, "placement", PlacementOptions)
    if not selection.initial < min(grid["contacts"]):
        raise ValueError(
            f"selection.initial: must be < every contact count {list(grid['contacts'])}, "
            f"got {selection.initial}"
        )
    models = _models(data["models"], Path(base_dir))
    tasks, duplicates = _expand(models, grid, seeds, selection, placement)
    return Study(
        name, description, source, models, grid, seeds, selection, placement, tasks, duplicates
    )


def _text(data: dict, key: str, default: str) -> str:
    value = data.get(key, default)
    if not isinstance(value, str):
        raise TypeError(f"{key}: expected text, got {value!r}")
    return value


def _axis(data: dict, key: str, default, convert) -> tuple:
    """A grid axis: one value or a non-empty list of distinct values."""
    value = data.get(key, default)
    values = value if isinstance(value, list) else [value]
    if not values:
        raise ValueError(f"{key}: expected a value or a non-empty list, got []")
    out = []
    for i, item in enumerate(values):
        where = f"{key}[{i}]" if isinstance(value, list) else key
        converted = convert(item, where)
        if converted in out:
            raise ValueError(f"{where}: repeated value {item!r}")
        out.append(converted)
    return tuple(out)


def _integer(value, where: str, least: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise ValueError(f"{where}: expected {what} >= {least}, got {value!r}")
    return value


def _count(value, where: str) -> int:
    return _integer(value, where, 1, "a number of contacts")


def _number(strict: bool):
    """A finite number ``>= 0`` (``> 0`` when ``strict``)."""
    return lambda value, where: as_number(value, where, minimum=0.0, strict=strict)


def _seeds(value) -> tuple[int, ...]:
    """``seeds``: a count N (seeds 0..N-1) or a non-empty list of distinct integers >= 0."""
    if not isinstance(value, list):
        return tuple(range(_integer(value, "seeds", 1, "a count (or a list of seeds)")))
    return _axis({"seeds": value}, "seeds", None, lambda v, f: _integer(v, f, 0, "a seed"))


def _options(data: dict, key: str, cls):
    """A ``[selection]`` or ``[placement]`` table as its options dataclass."""
    table = data.get(key, {})
    check_keys(table, key, {f.name for f in fields(cls)})
    try:
        return cls(**table)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{key}.{exc}") from None


def _models(value, base_dir: Path) -> tuple[ModelRef, ...]:
    """Resolve ``models`` (a path or a list of paths: files, or folders of ``*.model.json``)."""
    entries = value if isinstance(value, list) else [value]
    if not entries:
        raise ValueError("models: expected a model file, a folder or a list of them, got []")
    refs: list[ModelRef] = []
    for i, entry in enumerate(entries):
        where = f"models[{i}]" if isinstance(value, list) else "models"
        if not isinstance(entry, str) or not entry:
            raise ValueError(f"{where}: expected a path, got {entry!r}")
        path = (base_dir / entry).resolve()
        if path.is_dir():
            files = sorted(path.glob(f"*{MODEL_SUFFIX}"))
            if not files:
                raise ValueError(f"{where}: no *{MODEL_SUFFIX} file in folder {entry!r}")
        elif path.is_file():
            files = [path]
        else:
            raise ValueError(f"{where}: model {entry!r} not found (no such file or folder)")
        for file in files:
            refs.append(_model_ref(file, where))
    labels: dict[str, Path] = {}
    for ref in refs:
        if ref.label in labels and labels[ref.label] != ref.path:
            raise ValueError(
                f"models: two models labelled {ref.label!r}: {labels[ref.label]} and {ref.path}"
            )
        labels[ref.label] = ref.path
    unique = list({ref.path: ref for ref in refs}.values())
    return tuple(unique)


def _model_ref(path: Path, where: str) -> ModelRef:
    try:
        raw = path.read_bytes()
        load_model(path)  # validates every element now, not in a worker later
    except OSError as exc:
        raise ValueError(f"{where}: cannot read {str(path)!r}: {exc.strerror or exc}") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {str(path)!r}: {exc}") from None
    label = path.name.removesuffix(MODEL_SUFFIX).removesuffix(".json")
    digest = hashlib.sha256(raw).hexdigest()[:16]
    return ModelRef(label, path, digest, raw.decode("utf-8"))


def _expand(models, grid, seeds, selection, placement) -> tuple[tuple[Task, ...], int]:
    """Tasks in grid order, seeds innermost (so a worker meets the same solvers in a row)."""
    sel = tuple(sorted(asdict(selection).items()))
    plc = tuple(sorted(asdict(placement).items()))
    tasks: dict[str, Task] = {}
    points = 0
    axes = [grid[k] for k in ("type", "contacts", "mu", "mu_s", "f_max", "torque_scale")]
    for ref, (kind, m, mu, mu_s, f_max, scale), seed in product(models, product(*axes), seeds):
        points += 1
        task = Task(
            ref.label,
            str(ref.path),
            ref.digest,
            kind,
            m,
            None if kind == "fpc" else mu,  # FPC has no friction, PCwF no spin
            mu_s if kind in ("sfcl", "sfce") else None,
            f_max,
            scale,
            seed,
            sel,
            plc,
        )
        tasks.setdefault(task.task_id, task)
    return tuple(tasks.values()), points - len(tasks)


# --- one task, on a worker ----------------------------------------------------------------------

_CACHE_SIZE = 8
# Per thread: CasADi solvers must not be called from two threads at once, and a joined cluster's
# workers may run several tasks at a time (the local cluster's have one thread each).
_local = threading.local()


def _solvers(task: Task, model_text: str | None) -> tuple[Eligibility, Placer, bool]:
    """The :class:`Eligibility` and :class:`Placer` of ``task``, from this thread's cache.

    Returns them and whether a solver object was made now. One :class:`SupportMinimizer` serves
    every task (its CasADi NLPs are cached by shape, the numbers are parameters); the last few
    (model, specs, torque scale) combinations keep their eligibility and placers, so the
    placement NLPs are built once per worker too.
    """
    if not hasattr(_local, "cache"):
        _local.cache, _local.minimizer = OrderedDict(), SupportMinimizer()
    cache = _local.cache
    key = (task.model_digest, task.type, task.contacts, task.mu, task.mu_s, task.f_max)
    key += (task.torque_scale,)
    built = key not in cache
    if built:
        if model_text is None:
            raw = Path(task.model_file).read_bytes()
            if hashlib.sha256(raw).hexdigest()[:16] != task.model_digest:
                raise ValueError(f"{task.model_file}: model file changed since the study was read")
            model_text = raw.decode("utf-8")
        model = model_from_dict(json.loads(model_text), Path(task.model_file).parent)
        cache[key] = (Eligibility(model, task.specs(), task.torque_scale, _local.minimizer), {})
        while len(cache) > _CACHE_SIZE:
            cache.popitem(last=False)
    cache.move_to_end(key)
    eligibility, placers = cache[key]
    if task.placement not in placers:
        placers[task.placement] = Placer(eligibility, task.placement_options())
        built = True
    return eligibility, placers[task.placement], built


def clear_cache() -> None:
    """Forget this thread's solvers (tests; memory)."""
    _local.__dict__.clear()


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
        eligibility, placer, built = _solvers(task, model_text)
        setup = time.perf_counter() - t0
        result = plan(
            eligibility, seed=task.seed, selection=task.selection_options(), placer=placer
        )
        first, second, placed, seconds = (
            result.heuristic, result.iterative, result.placement, result.seconds
        )
    except Exception as exc:  # noqa: BLE001 - a failing task is recorded, the study goes on
        row.update(status="error", error=f"{type(exc).__name__}: {exc}")
        row["wall_seconds"] = time.perf_counter() - t0
        return row
    for prefix, result in (("heuristic", first), ("iterative", second)):
        row[f"{prefix}_elements"] = [int(e) for e in result.elements]
        row[f"{prefix}_rho_hat"] = float(result.rho_hat)
        row[f"{prefix}_eligible"] = bool(result.eligible)
        row[f"{prefix}_evaluations"] = int(result.evaluations)
        row[f"{prefix}_seconds"] = float(result.seconds)
    row.update(
        status="ok",
        heuristic_rounds=int(first.rounds),
        elements=[int(e) for e in placed.elements],
        rho=float(placed.rho),
        force_closure=bool(placed.force_closure),
        start_rho=float(placed.start_rho),
        placement_rounds=int(placed.rounds),
        placement_moves=len(placed.moves),
        placement_seconds=float(placed.seconds),
        placed_contacts=json.dumps([c.to_dict() for c in placed.contacts]),
        seconds=seconds,
        setup_seconds=setup,
        solvers_built=built,
        wall_seconds=time.perf_counter() - t0,
    )
    return row


def task_row(task: Task) -> dict:
    """A result row with the task's inputs filled in and every result column empty."""
    row = dict.fromkeys(ROW_COLUMNS)
    row.update(
        task_id=task.task_id,
        model=task.model,
        model_digest=task.model_digest,
        type=task.type,
        contacts=task.contacts,
        mu=task.mu,
        mu_s=task.mu_s,
        f_max=task.f_max,
        torque_scale=task.torque_scale,
        seed=task.seed,
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


# --- result files -------------------------------------------------------------------------------


def _columns() -> list[tuple[str, str]]:
    """(name, kind) of every result column; kinds: text, real, int, flag, ids."""
    steps = [
        (f"{prefix}_{name}", kind)
        for prefix in ("heuristic", "iterative")
        for name, kind in (
            ("elements", "ids"),
            ("rho_hat", "real"),
            ("eligible", "flag"),
            ("evaluations", "int"),
            ("seconds", "real"),
        )
    ]
    return [
        *[(k, "text") for k in ("task_id", "model", "model_digest", "type")],
        ("contacts", "int"),
        *[(k, "real") for k in ("mu", "mu_s", "f_max", "torque_scale")],
        ("seed", "int"),
        *[(k, "text") for k in ("selection", "placement", "status", "error")],
        *steps,
        ("heuristic_rounds", "int"),
        ("elements", "ids"),
        ("rho", "real"),
        ("force_closure", "flag"),
        ("start_rho", "real"),
        ("placement_rounds", "int"),
        ("placement_moves", "int"),
        ("placement_seconds", "real"),
        ("placed_contacts", "text"),
        ("seconds", "real"),
        ("setup_seconds", "real"),
        ("solvers_built", "flag"),
        ("wall_seconds", "real"),
        *[(k, "text") for k in ("worker", "finished", "closure_nlp")],
    ]


ROW_COLUMNS: tuple[str, ...] = tuple(name for name, _ in _columns())


def _schema():
    """The Arrow schema of a result row (:data:`ROW_COLUMNS`)."""
    import pyarrow as pa

    types = {
        "text": pa.string(),
        "real": pa.float64(),
        "int": pa.int64(),
        "flag": pa.bool_(),
        "ids": pa.list_(pa.int64()),
    }
    return pa.schema([(name, types[kind]) for name, kind in _columns()])


def write_row(results_dir, row: dict) -> Path:
    """Write one row as ``results_dir/<task_id>.parquet``, atomically (replacing an old one)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([row], schema=_schema())
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    return write_atomic(Path(results_dir) / f"{row['task_id']}.parquet", buffer.getvalue())


def read_results(results_dir):
    """Every row in ``results_dir`` as a pandas DataFrame (one row per part-file).

    An unreadable part-file is skipped with a warning (its task then counts as not done).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = _schema()
    tables = []
    for path in sorted(Path(results_dir).glob("*.parquet")):
        try:
            table = pq.read_table(path)
        except (OSError, pa.ArrowException) as exc:
            log.warning("skipping unreadable result file %s: %s", path, exc)
            continue
        for name in schema.names:  # files from older versions may lack newer columns
            if name not in table.column_names:
                table = table.append_column(name, pa.nulls(len(table), schema.field(name).type))
        tables.append(table.select(schema.names).cast(schema))
    if not tables:
        return schema.empty_table().to_pandas()
    frame = pa.concat_tables(tables).to_pandas()
    return frame.drop_duplicates("task_id", keep="last").reset_index(drop=True)


# --- running a study ----------------------------------------------------------------------------


@dataclass(frozen=True)
class StudyRun:
    """What :func:`run_study` did.

    Attributes
    ----------
    name : str
    total : int
        Tasks in the study.
    run : int
        Tasks run now (including the failed ones).
    skipped : int
        Tasks already done by an earlier run.
    failed : int
        Tasks run now that recorded an error.
    remaining : int
        Tasks still not done (``limit``).
    seconds : float
        Wall time of running the tasks.
    workers : int
        Workers that ran them (1 for a serial run).
    paths : dict of str
        ``results`` (the part-file folder), ``results.csv``, ``summary.md``, ``summary.csv``,
        ``rho.png``, ``seconds.png``, ``study.json``.
    summary : list of dict
        The rows of the summary table.
    """

    name: str
    total: int
    run: int
    skipped: int
    failed: int
    remaining: int
    seconds: float
    workers: int
    paths: dict
    summary: list

    @property
    def tasks_per_second(self) -> float:
        """Tasks run now per second of :attr:`seconds`."""
        return self.run / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict:
        """The CLI's ``--json`` payload: counts, seconds, workers, output paths, summary."""
        return {
            "study": self.name,
            "tasks": {
                "total": self.total,
                "run": self.run,
                "skipped": self.skipped,
                "failed": self.failed,
                "remaining": self.remaining,
            },
            "seconds": self.seconds,
            "workers": self.workers,
            "tasks_per_second": self.tasks_per_second,
            "out": self.paths,
            "summary": self.summary,
        }


def run_study(
    study: Study,
    out,
    *,
    client=None,
    scheduler: str | None = None,
    workers: int | None = None,
    serial: bool = False,
    limit: int | None = None,
    retry_failed: bool = False,
    progress: StudyProgress | None = None,
    runner: Runner = run_task,
) -> StudyRun:
    """Run the tasks of ``study`` not done yet in ``out``, then write the summary and plots.

    Parameters
    ----------
    study : Study
    out : str or Path
        Output folder; ``out/results/`` holds one Parquet part-file per finished task.
    client : distributed.Client, optional
        Run on this client's cluster (left open).
    scheduler : str, optional
        Address of a running Dask scheduler to join (its cluster is left as it is).
    workers : int, optional
        Worker processes of the local cluster started otherwise (default: the machine's cores),
        one thread each.
    serial : bool
        Run the tasks one after another in this process, without Dask.
    limit : int, optional
        Run at most this many of the pending tasks (run again to resume).
    retry_failed : bool
        Run again the tasks whose earlier run recorded an error.
    progress : callable, optional
        ``progress(0, total, None)`` before the first task, then ``progress(done, total, row)``
        after every finished task.
    runner : callable
        ``runner(task, model_text) -> row``; :func:`run_task` (tests swap it).

    Returns
    -------
    StudyRun
    """
    if limit is not None:
        _integer(limit, "limit", 0, "an integer")
    if workers is not None:
        _integer(workers, "workers", 1, "an integer")
    if sum(x is not None for x in (client, scheduler)) + bool(serial) > 1:
        raise ValueError("scheduler: give at most one of client, scheduler and serial")
    if workers is not None and (client is not None or scheduler):
        raise ValueError("workers: only for the local cluster (not with a scheduler or client)")
    out = Path(out)
    results_dir = out / "results"
    results_dir.mkdir(parents=True, exist_ok=True)
    write_json(out / "study.json", study.to_dict())
    done = read_results(results_dir)
    finished = set(done.task_id) if not retry_failed else set(done.task_id[done.status == "ok"])
    pending = [t for t in study.tasks if t.task_id not in finished]
    skipped = len(study.tasks) - len(pending)
    if limit is not None:
        pending = pending[:limit]
    texts = {ref.digest: ref.text for ref in study.models}
    count = {"done": 0, "failed": 0}

    def record(row: dict) -> None:
        write_row(results_dir, row)
        count["done"] += 1
        count["failed"] += row["status"] != "ok"
        if progress:
            progress(count["done"], len(pending), row)

    if progress:
        progress(0, len(pending), None)
    t0 = time.perf_counter()
    if serial or not pending:
        used = 1
        for task in pending:
            try:
                row = runner(task, texts[task.model_digest])
            except Exception as exc:  # noqa: BLE001 - the study goes on
                row = error_row(task, f"{type(exc).__name__}: {exc}")
            record(row)
    else:
        used = _run_dask(pending, texts, record, runner, client, scheduler, workers)
    seconds = time.perf_counter() - t0
    paths = {"results": str(results_dir), "study.json": str(out / "study.json")}
    frame = read_results(results_dir)
    summary = summarize(study, frame)
    paths.update(write_outputs(study, frame, summary, out))
    ids = set(frame.task_id)
    return StudyRun(
        study.name,
        len(study.tasks),
        count["done"],
        skipped,
        count["failed"],
        sum(t.task_id not in ids for t in study.tasks),
        seconds,
        used,
        paths,
        [{k: _plain(v) for k, v in r.items()} for r in summary.to_dict("records")],
    )


def _plain(value):
    """A JSON value: numpy scalars as Python ones, NaN as None."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _run_dask(tasks: Sequence[Task], texts, record, runner, client, scheduler, workers) -> int:
    """Submit every task, record rows as they complete; returns the number of workers.

    Waits as long as it takes: a joined cluster without workers runs nothing until some join.
    """
    import asyncio
    import uuid

    from distributed import Client, as_completed

    cluster = own_client = None
    if client is None:
        if scheduler:
            try:
                client = own_client = Client(scheduler)
            except OSError as exc:
                raise ValueError(f"scheduler: cannot connect to {scheduler!r}: {exc}") from None
        else:
            cluster = local_cluster(workers)
            client = own_client = Client(cluster)
    futures = {}
    try:
        used = len(client.scheduler_info().get("workers", {}))
        models = {d: client.scatter(text, hash=False) for d, text in texts.items()}
        tag = uuid.uuid4().hex[:8]
        for task in tasks:
            future = client.submit(
                runner,
                task,
                models[task.model_digest],
                key=f"study-{task.task_id}-{tag}",
            )
            futures[future] = task
        for future in as_completed(futures):
            task = futures.pop(future)
            try:
                row = future.result()
            except (Exception, asyncio.CancelledError) as exc:  # noqa: BLE001 - a dead worker
                row = error_row(task, f"{type(exc).__name__}: {exc}")
            future.release()
            record(row)
        return used
    except BaseException:
        if futures:  # stopped (Ctrl-C, a failing callback): leave no work behind on the cluster
            client.cancel(list(futures))
        raise
    finally:
        if own_client is not None:
            own_client.close()
        if cluster is not None:
            cluster.close()


def local_cluster(workers: int | None = None, **kwargs):
    """A ``distributed.LocalCluster`` for studies: ``workers`` processes (default: the cores), one
    thread each, the scheduler's HTTP server on a free port, quiet logs.

    Dask starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which makes the many small
    allocations of CasADi and IPOPT about a third slower; these workers keep glibc's default.
    ``kwargs`` go to ``LocalCluster``.
    """
    import dask
    from distributed import LocalCluster

    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    options = {
        "n_workers": workers or os.cpu_count() or 1,
        "threads_per_worker": 1,
        "processes": True,
        "dashboard_address": ":0",  # any free port: several clusters may run at once
        "silence_logs": logging.ERROR,
        **kwargs,
    }
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
        return LocalCluster(**options)


# --- summary, plots -----------------------------------------------------------------------------

GROUP_KEYS = ("model", "type", "contacts")
VARYING_KEYS = ("mu", "mu_s", "f_max", "torque_scale")


def group_keys(study: Study) -> list[str]:
    """Model, type, count, and each parameter that takes several values in the study's tasks
    (``None``, a parameter without effect on a contact type, does not count)."""
    values = {k: {getattr(t, k) for t in study.tasks} - {None} for k in VARYING_KEYS}
    varying = [k for k in VARYING_KEYS if len(values[k]) > 1]
    return list(GROUP_KEYS) + varying


def _groups(study: Study, frame) -> list[tuple[dict, int, object]]:
    """Per group of :func:`group_keys`, in task order: its key values, its number of tasks and
    the rows of ``frame`` of its tasks."""
    keys = group_keys(study)
    ids: dict[tuple, list[str]] = {}
    for task in study.tasks:
        ids.setdefault(tuple(getattr(task, k) for k in keys), []).append(task.task_id)
    return [
        (dict(zip(keys, values)), len(group), frame[frame.task_id.isin(group)])
        for values, group in ids.items()
    ]


def summarize(study: Study, frame):
    """The summary table: one row per group of :func:`group_keys`.

    Columns: the group keys, ``tasks`` (of the study), ``done``, ``errors``, ``force_closure``
    (count), ``success_rate`` (force closure among the tasks done), ``rho_median``, ``rho_best``
    (most negative rho), ``rho_hat_median`` (iterative selection), ``seconds_median`` (the three
    steps of one task).
    """
    import pandas as pd

    out = []
    for values, tasks, mine in _groups(study, frame):
        ok = mine[mine.status == "ok"]
        fc = int(ok.force_closure.fillna(False).astype(bool).sum())
        out.append(
            values
            | {
                "tasks": tasks,
                "done": len(mine),
                "errors": int((mine.status != "ok").sum()),
                "force_closure": fc,
                "success_rate": fc / len(mine) if len(mine) else float("nan"),
                "rho_median": _stat(ok.rho, "median"),
                "rho_best": _stat(ok.rho, "min"),
                "rho_hat_median": _stat(ok.iterative_rho_hat, "median"),
                "seconds_median": _stat(ok.seconds, "median"),
            }
        )
    return pd.DataFrame(out, columns=group_keys(study) + SUMMARY_COLUMNS)


SUMMARY_COLUMNS = [
    "tasks",
    "done",
    "errors",
    "force_closure",
    "success_rate",
    "rho_median",
    "rho_best",
    "rho_hat_median",
    "seconds_median",
]


def _stat(series, how: str) -> float:
    series = series.dropna()
    return float(getattr(series, how)()) if len(series) else float("nan")


def summary_markdown(study: Study, summary, frame) -> str:
    """``summary.md``: the table, the counts and the first errors."""
    rows = frame[frame.task_id.isin({t.task_id for t in study.tasks})]
    errors = rows[rows.status != "ok"]
    lines = [f"# Study {study.name}", ""]
    if study.description:
        lines += [study.description, ""]
    lines += [
        f"{len(study.tasks)} tasks ({len(study.models)} models, seeds "
        f"{_range_text(study.seeds)}); {len(rows)} done, {len(errors)} with errors. "
        "rho < 0 is force closure (best = most negative); success = force closure; seconds = "
        "heuristic + iterative + placement of one task (median).",
        "",
        "| " + " | ".join(summary.columns) + " |",
        "|" + "---|" * len(summary.columns),
    ]
    for record in summary.to_dict("records"):
        lines.append("| " + " | ".join(_cell(k, v) for k, v in record.items()) + " |")
    if len(errors):
        lines += ["", "## Errors", ""]
        for record in errors.head(20).to_dict("records"):
            lines.append(
                f"- {record['task_id']} ({record['model']}, {record['type']} x "
                f"{record['contacts']}, seed {record['seed']}): {record['error']}"
            )
        if len(errors) > 20:
            lines.append(f"- ... and {len(errors) - 20} more (see results.csv)")
    lines += ["", "Plots: rho.png (rho over seeds), seconds.png (time per task).", ""]
    return "\n".join(lines)


def _range_text(seeds: Sequence[int]) -> str:
    if list(seeds) == list(range(seeds[0], seeds[0] + len(seeds))) and len(seeds) > 2:
        return f"{seeds[0]}..{seeds[-1]}"
    return ",".join(str(s) for s in seeds)


def _cell(key: str, value) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "-"
    if key == "success_rate":
        return f"{100 * value:.0f}%"
    if key in ("rho_median", "rho_best", "rho_hat_median"):
        return f"{value:.4f}"
    if key == "seconds_median":
        return f"{value:.2f}"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def write_outputs(study: Study, frame, summary, out) -> dict:
    """Write ``results.csv``, ``summary.md``, ``summary.csv``, ``rho.png`` and ``seconds.png``."""
    out = Path(out)
    order = {t.task_id: i for i, t in enumerate(study.tasks)}
    rows = frame[frame.task_id.isin(order)].copy()
    rows["_order"] = rows.task_id.map(order)
    rows = rows.sort_values("_order").drop(columns="_order")
    for column in ("heuristic_elements", "iterative_elements", "elements"):
        rows[column] = rows[column].map(
            lambda ids: " ".join(str(int(i)) for i in ids) if ids is not None else None
        )
    paths = {
        "results.csv": write_atomic(out / "results.csv", rows.to_csv(index=False)),
        "summary.csv": write_atomic(out / "summary.csv", summary.to_csv(index=False)),
        "summary.md": write_atomic(out / "summary.md", summary_markdown(study, summary, frame)),
    }
    paths.update(plot_study(study, frame, out))
    return {k: str(v) for k, v in paths.items()}


def plot_study(study: Study, frame, out) -> dict:
    """``rho.png``: rho over seeds per group; ``seconds.png``: seconds per task per group."""
    from .drawing import pyplot, save_figure

    plt = pyplot()
    groups = [
        (" ".join(_label(k, v) for k, v in values.items()), rows[rows.status == "ok"])
        for values, _, rows in _groups(study, frame)
    ]
    paths = {}
    for name, column, xlabel in (
        ("rho.png", "rho", "rho (negative = force closure; lower is better)"),
        ("seconds.png", "seconds", "seconds per task (heuristic + iterative + placement)"),
    ):
        fig, ax = plt.subplots(figsize=(8.0, 1.2 + 0.38 * max(1, len(groups))))
        data = [g[column].dropna().to_numpy() for _, g in groups]
        positions = np.arange(len(groups))[::-1]
        filled = [i for i, d in enumerate(data) if len(d)]
        if filled:
            ax.boxplot(
                [data[i] for i in filled],
                positions=positions[filled],
                **_horizontal(),
                widths=0.6,
                showfliers=False,
            )
        rng = np.random.default_rng(0)
        for i, d in enumerate(data):
            y = positions[i] + rng.uniform(-0.18, 0.18, len(d))
            ax.plot(d, y, "o", ms=3, alpha=0.6, color="tab:blue")
        ax.set_yticks(positions)
        ax.set_yticklabels([label for label, _ in groups], fontsize=8)
        ax.set_ylim(-0.7, len(groups) - 0.3)
        if column == "rho":
            ax.axvline(0.0, color="grey", lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_title(f"{study.name}: {column} per task (over seeds)")
        fig.tight_layout()
        paths[name] = save_figure(fig, Path(out) / name)
        plt.close(fig)
    return paths


def _horizontal() -> dict:
    """``boxplot`` keywords for horizontal boxes (``vert`` is deprecated from matplotlib 3.10)."""
    import matplotlib

    major, minor = (int(p) for p in matplotlib.__version__.split(".")[:2])
    return {"orientation": "horizontal"} if (major, minor) >= (3, 10) else {"vert": False}


def _label(key: str, value) -> str:
    if key in ("model", "type"):
        return str(value)
    if key == "contacts":
        return f"x{value}"
    return f"{key}={'-' if value is None else f'{value:g}'}"


__all__ = [
    "ModelRef",
    "ROW_COLUMNS",
    "Study",
    "StudyRun",
    "Task",
    "clear_cache",
    "error_row",
    "load_study",
    "local_cluster",
    "read_results",
    "run_study",
    "run_task",
    "study_from_dict",
    "summarize",
    "write_row",
]
