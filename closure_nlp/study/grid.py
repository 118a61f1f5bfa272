"""The study file: a TOML grid of planning runs, validated and expanded into tasks."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, fields, replace
from itertools import product
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from closure_nlp.base.files import read_input
from closure_nlp.base.validation import (
    MAX_SEED,
    MAX_STUDY_TASKS,
    as_f_max,
    as_mu,
    as_mu_s,
    as_torque_scale,
    check_keys,
    is_whole,
)
from closure_nlp.contact.contact_set import (
    DEFAULT_F_MAX,
    DEFAULT_MU,
    DEFAULT_MU_S,
    ContactType,
    contact_set_from_dict,
)
from closure_nlp.contact.count import closure_count_problem
from closure_nlp.contact.loads import as_loads, load_loads
from closure_nlp.model.elements import load_model
from closure_nlp.model.fixed_contacts import fixed_contacts
from closure_nlp.model.regions import excluded_elements
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.selection.algorithms import SelectionOptions
from closure_nlp.study.tasks import GRID_AXES, Task

INTENT_KEYS = ("only", "exclude", "fixed", "min_spacing")
STUDY_KEYS = {
    "name",
    "description",
    "models",
    "seeds",
    "selection",
    "placement",
    *GRID_AXES,
    *INTENT_KEYS,
}
STUDY_KEYS |= {"loads", "objective"}
REQUIRED_KEYS = {"models", "contacts"}
MODEL_SUFFIX = ".model.json"


@dataclass(frozen=True)
class ModelRef:
    """A model of a study: its label, file, content digest and text (shipped to workers)."""

    label: str
    path: Path
    digest: str
    text: str = field(repr=False, compare=False)


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
    loads : str or None
        The load cases every task reports the factors of (canonical JSON of a LOADS.json).
    objective : str or None
        ``"loads"`` (the default with loads: plans steered by the least load factor) or
        ``"rho"``; ``None`` without loads.
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
    intent: dict = field(default_factory=dict)
    loads: str | None = None
    objective: str | None = None

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
            **{k: (list(v) if isinstance(v, tuple) else v) for k, v in self.intent.items()},
            **({} if self.loads is None else {"loads": json.loads(self.loads)}),
            **({} if self.objective is None else {"objective": self.objective}),
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
        data = tomllib.loads(read_input(path).decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"cannot read file: not UTF-8 text ({exc.reason})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"malformed TOML: {exc}") from None
    except RecursionError:
        raise ValueError("TOML nested too deeply to read") from None
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
        "mu": _axis(data, "mu", DEFAULT_MU, as_mu),
        "mu_s": _axis(data, "mu_s", DEFAULT_MU_S, as_mu_s),
        "f_max": _axis(data, "f_max", DEFAULT_F_MAX, as_f_max),
        "torque_scale": _axis(data, "torque_scale", 1.0, as_torque_scale),
    }
    _check_size(data, grid)  # before the seeds or the tasks are built
    seeds = _seeds(data.get("seeds", 1))
    selection = _options(data, "selection", SelectionOptions)
    placement = _options(data, "placement", PlacementOptions)
    if "min_spacing" in data:  # the same as [placement] min_spacing
        try:
            placement = replace(placement, min_spacing=data["min_spacing"])
        except ValueError as exc:
            raise ValueError(str(exc)) from None
    intent, fixed = _intent(data, Path(base_dir))
    if not selection.initial < min(grid["contacts"]):
        raise ValueError(
            f"selection.initial: must be < every contact count {list(grid['contacts'])}, "
            f"got {selection.initial}"
        )
    _check_counts(grid, [c.spec for c in fixed.contacts] if fixed is not None else ())
    models = _models(data["models"], Path(base_dir))
    for ref in models:  # the regions and the fixed contacts hold on every model
        model = load_model(ref.path)
        try:
            excluded_elements(model, intent.get("only", ()), intent.get("exclude", ()))
            fixed_contacts(model, fixed)
        except ValueError as exc:
            raise ValueError(f"{ref.label}: {exc}") from None
    loads, objective = _loads(data, Path(base_dir))
    tasks, duplicates = _expand(
        models, grid, seeds, selection, placement, intent, (loads, objective)
    )
    return Study(
        name,
        description,
        source,
        models,
        grid,
        seeds,
        selection,
        placement,
        tasks,
        duplicates,
        dict(intent, **({"fixed": str(data["fixed"])} if fixed is not None else {})),
        loads,
        objective,
    )


def _intent(data: dict, base_dir: Path):
    """The study's ``only`` and ``exclude`` (tuples of regions: SPEC strings or id lists) and
    ``fixed`` (a contact-set file, relative to the study file) as task keys, and the fixed
    contacts read."""
    intent: dict = {}
    for key in ("only", "exclude"):
        if key not in data:
            continue
        value = data[key]
        values = value if isinstance(value, list) else [value]
        if values and all(is_whole(v) and not isinstance(v, bool) for v in values):
            values = [values]  # one list of ids
        for i, v in enumerate(values):
            if not (isinstance(v, str) or isinstance(v, list)):
                raise TypeError(f"{key}[{i}]: expected a SPEC string or a list of ids, got {v!r}")
        intent[key] = tuple(tuple(v) if isinstance(v, list) else v for v in values)
    fixed = None
    if "fixed" in data:
        if not isinstance(data["fixed"], str) or not data["fixed"]:
            raise TypeError(f"fixed: expected a contact-set file's path, got {data['fixed']!r}")
        path = (base_dir / data["fixed"]).resolve()
        try:
            raw = json.loads(read_input(path).decode("utf-8"))
            fixed = contact_set_from_dict(raw)
        except OSError as exc:
            reason = exc.strerror or exc
            raise ValueError(f"fixed: cannot read {data['fixed']!r}: {reason}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"fixed: {data['fixed']!r}: {exc}") from None
        intent["fixed"] = json.dumps(raw, sort_keys=True, separators=(",", ":"))
    return intent, fixed


def _loads(data: dict, base_dir: Path) -> tuple[str | None, str | None]:
    """``loads`` (a LOADS.json path relative to the study file, or its content inline) as
    canonical JSON, and ``objective`` (default ``"loads"`` with loads, ``"rho"`` the other)."""
    objective = data.get("objective")
    if objective is not None and objective not in ("loads", "rho"):
        raise ValueError(f"objective: expected 'loads' or 'rho', got {objective!r}")
    if "loads" not in data:
        if objective is not None:
            raise ValueError(f"objective: {objective!r} needs a loads key (the load cases)")
        return None, None
    value = data["loads"]
    try:
        if isinstance(value, str):
            loads = load_loads(base_dir / value)
        elif isinstance(value, (dict, list)):
            loads = as_loads(value)
        else:
            raise TypeError(f"expected a LOADS.json path or the cases inline, got {value!r}")
    except OSError as exc:
        raise ValueError(f"loads: cannot read {value!r}: {exc.strerror or exc}") from None
    except (TypeError, ValueError) as exc:
        where = f"loads: {value!r}" if isinstance(value, str) else "loads"
        raise type(exc)(f"{where}: {exc}") from None
    text = json.dumps(loads.to_dict(), sort_keys=True, separators=(",", ":"))
    return text, objective or "loads"


def _check_size(data: dict, grid: dict) -> None:
    """The number of grid points (models counted as given: a folder as one), against the limit;
    a study of 10**12 seeds is refused here, not by a MemoryError while listing them."""
    seeds = data.get("seeds", 1)
    n_seeds = len(seeds) if isinstance(seeds, list) else seeds
    models = data.get("models")
    n_models = len(models) if isinstance(models, list) else 1
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, int) or n_seeds < 1:
        return  # _seeds names the problem
    size = n_seeds * n_models
    for axis in grid.values():
        size *= len(axis)
    if size > MAX_STUDY_TASKS:
        raise ValueError(
            f"seeds: the grid has {size:,} points ({n_seeds:,} seeds x {size // n_seeds:,} "
            f"parameter sets and models), over the limit of {MAX_STUDY_TASKS:,} per study"
        )


def _check_counts(grid: dict, fixed=()) -> None:
    """Refuse a grid point whose contacts (with the ``fixed`` ones' specs) can never give force
    closure (before any model)."""
    for kind, m, mu, mu_s in product(grid["type"], grid["contacts"], grid["mu"], grid["mu_s"]):
        specs = tuple(fixed) + tuple(contact_specs(m, type=kind, mu=mu, mu_s=mu_s))
        problem = closure_count_problem(specs)
        if problem is not None:
            point = "" if kind == "fpc" else f" (grid point mu = {mu:g}, mu_s = {mu_s:g})"
            raise ValueError(f"contacts: {problem}{point}")


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
    if not is_whole(value) or value < least:
        raise ValueError(f"{where}: expected {what} >= {least}, got {value!r}")
    return int(value)


def _count(value, where: str) -> int:
    return _integer(value, where, 1, "a number of contacts")


def _seeds(value) -> tuple[int, ...]:
    """``seeds``: a count N (seeds 0..N-1) or a non-empty list of distinct integers >= 0."""
    if not isinstance(value, list):
        return tuple(range(_integer(value, "seeds", 1, "a count (or a list of seeds)")))
    return _axis({"seeds": value}, "seeds", None, _seed)


def _seed(value, where: str) -> int:
    seed = _integer(value, where, 0, "a seed")
    if seed > MAX_SEED:
        raise ValueError(f"{where}: a seed must be <= 2**63 - 1 (stored as int64), got {seed}")
    return seed


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
        elif path.exists():  # a file: read_input refuses a FIFO or a device, naming it
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
        raw = read_input(path)
        load_model(path)  # validates every element now, not in a worker later
    except OSError as exc:
        raise ValueError(f"{where}: cannot read {str(path)!r}: {exc.strerror or exc}") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {str(path)!r}: {exc}") from None
    label = path.name.removesuffix(MODEL_SUFFIX).removesuffix(".json")
    digest = hashlib.sha256(raw).hexdigest()[:16]
    return ModelRef(label, path, digest, raw.decode("utf-8"))


def _expand(models, grid, seeds, selection, placement, intent, loads=(None, None)):
    """Tasks in grid order, seeds innermost (so a worker meets the same solvers in a row), and
    the number of grid points dropped as repeats; ``loads``: (cases, objective) of every task."""
    sel = tuple(sorted(asdict(selection).items()))
    # without a spacing, the tasks' ids stay those of studies that had none
    plc = tuple(
        (k, v) for k, v in sorted(asdict(placement).items()) if (k, v) != ("min_spacing", 0.0)
    )
    kept = tuple(sorted(intent.items()))
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
            kept,
            *loads,
        )
        tasks.setdefault(task.task_id, task)
    return tuple(tasks.values()), points - len(tasks)


# --- summary, plots -----------------------------------------------------------------------------

GROUP_KEYS = ("model", "type", "contacts")
VARYING_KEYS = ("mu", "mu_s", "f_max", "torque_scale")


def group_keys(study: Study) -> list[str]:
    """Model, type, count, and each parameter that takes several values in the study's tasks
    (``None``, a parameter without effect on a contact type, does not count)."""
    values = {k: {getattr(t, k) for t in study.tasks} - {None} for k in VARYING_KEYS}
    varying = [k for k in VARYING_KEYS if len(values[k]) > 1]
    return list(GROUP_KEYS) + varying


def task_groups(study: Study, frame) -> list[tuple[dict, int, object]]:
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
