"""The ``closure-nlp`` command line: a thin layer over the API (docs/formats.md).

Each command is a ``_cmd_<name>(args)`` function that returns one JSON-able dict per input and a
human-readable line for it. Exit status (README, "Exit status"): 2 for bad input, which the
commands check before any work and raise as :class:`InputError` naming the file and the field;
1 when the method cannot answer (:class:`MethodError`, out of memory, a non-finite result) or the
system refuses (:class:`OutputFault`, any ``OSError``: a full disk, stdout full or closed);
3 for an internal error (a bug: any other exception once the work has started, printed as
``internal error:``, never as bad input); 130 for Ctrl-C. No traceback reaches the user
(``CLOSURE_NLP_TRACEBACK=1`` prints it, for bug reports).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import sys
import time

from closure_nlp.base import quiet_interrupt as _quiet_interrupt  # noqa: F401 - first: Ctrl-C while importing
from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    check_output_dir,
    check_output_file,
    escape,
    non_finite_key,
    staged_folder,
    write_json,
)
from closure_nlp.base.formatting import bracket, certain, lengths
from closure_nlp.base.interrupts import interruptible
from closure_nlp.base.progress import progress_line
from closure_nlp.base.validation import (
    MAX_ELEMENT_CONTACTS,
    MAX_SEED,
    as_count,
    as_torque_scale,
    ascii_number,
)
from closure_nlp.cli import startup as _cli_startup  # noqa: F401 - first: Ctrl-C while importing
from closure_nlp.contact.contact_set import SOFT_FINGERS, ContactType
from closure_nlp.contact.count import require_closure_count
from closure_nlp.model.elements import load_model
from closure_nlp.model.scale import contact_specs, is_auto, scale_warnings
from closure_nlp.model.scale import resolve as resolve_scale
from closure_nlp.placement.ceiling import gap_text
from closure_nlp.placement.place import Placer
from closure_nlp.placement.placer import PlacementOptions
from closure_nlp.planning.plan import plan
from closure_nlp.planning.seeds import DEFAULT_BUDGET, DEFAULT_SEEDS, MAX_PLAN_SEEDS
from closure_nlp.report.plan_report import load_contacts, write_report
from closure_nlp.rho.rho_hat import Eligibility
from closure_nlp.rho.support_minimum import rho
from closure_nlp.selection.algorithms import run_selection

_quiet_interrupt.restore()

MAX_STARTS = 100  # placement start weights per run: each is a full exchange method
MAX_WORKERS = 256  # local Dask worker processes


class InputError(ValueError):
    """Bad input tied to a file: the message names the file, then the field."""

    def __init__(self, source: str, message: str):
        super().__init__(f"{source}: {message}")


class OutputFault(RuntimeError):
    """The system refused the output (a full disk, a closed or full stdout, an encoding that
    cannot show a name): exit 1, like any fault of the environment, never a bug."""

    def __init__(self, source: str, message: str):
        super().__init__(f"{source}: {message}")


def _print(line: str) -> None:
    """``line`` on stdout; a failure of stdout is an :class:`OutputFault` (exit 1)."""
    try:
        sys.stdout.write(line + "\n")
    except UnicodeEncodeError as exc:
        shown = exc.object[max(exc.start - 20, 0) : exc.end + 20]
        raise OutputFault(
            "stdout",
            f"cannot print {shown!r} in the output's encoding {exc.encoding}: set "
            "PYTHONIOENCODING=utf-8 (or use --json)",
        ) from None
    except BrokenPipeError:
        raise
    except OSError as exc:  # a full device (/dev/full), an I/O error
        raise OutputFault("stdout", f"cannot write: {exc.strerror or exc}") from None


def _flush_stdout() -> None:
    """Push out what is buffered: a full device fails here, after the last line."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise OutputFault("stdout", f"cannot write: {exc.strerror or exc}") from None


def _shown(name) -> str:
    """A name (a path) as messages show it: control characters escaped, one line."""
    return escape(str(name))


@contextlib.contextmanager
def _reading(source: str):
    """Checks of a command's inputs, before any work: ``ValueError``/``TypeError`` raised in
    them is bad input of ``source`` (exit 2); the same raised later is an internal error."""
    try:
        yield
    except InputError:
        raise
    except (ValueError, TypeError) as exc:
        raise InputError(source, str(exc)) from None


def _check_finite(payload: dict, source: str) -> None:
    """Every number printed or written is finite: a NaN is the method's failure, not an answer."""
    key = non_finite_key(payload)
    if key is not None:
        raise MethodError(f"{source}: the method produced a non-finite {key}; nothing reported")


def _emit(args, payload: dict, text: str) -> None:
    scale = getattr(args, "scale", None)
    if scale is not None:  # a model command: the torque scale, mu_s and point it used
        payload = {**payload, **scale.to_dict()}
        text = f"{_shown(args.model)}: {scale.text(getattr(args, 'soft_fingers', True))}\n{text}"
    _check_finite(payload, str(payload.get("file", getattr(args, "model", ""))))
    _print(json.dumps(payload, allow_nan=False) if args.json else text)


# --- commands -------------------------------------------------------------------------------


def _load_each(paths, loader):
    """Load and validate every input before any work, so bad input prints no partial output."""
    loaded = []
    for path in paths:
        try:
            loaded.append((path, loader(path)))
        except (ValueError, TypeError) as exc:
            raise InputError(path, str(exc)) from None
    return loaded


def _add_rho(sub, common) -> None:
    p = sub.add_parser("rho", parents=[common], help="rho(0, W_c^M) of contact-set files")
    p.add_argument(
        "files", nargs="+", metavar="FILE", help="*.contacts.json (or a plan's report.json)"
    )
    p.add_argument(
        "--certify",
        action="store_true",
        help="accepted for compatibility: certified bounds lo <= rho <= hi are always given",
    )
    p.set_defaults(run=_cmd_rho)


def _tolerance(args, given):
    """The file's tolerance with the command line's values in place of its own."""
    return given.merged(args.position_tolerance, args.normal_tolerance)


def _cmd_rho(args) -> None:
    for path, contact_set in _load_each(args.files, load_contacts):
        t0 = time.perf_counter()
        result = rho(contact_set, tolerance=_tolerance(args, contact_set.tolerance))
        payload = {"file": path, **result.to_dict(), **_whole_cost(result, t0)}
        direction = " ".join(f"{x:+.4f}" for x in result.direction)
        _emit(
            args,
            payload,
            f"{_shown(path)}: rho = {certain(result.rho, result.bounds)} "
            f"({_verdict(result, result.force_closure)}); "
            f"weakest direction u* = [{direction}]" + _bounds_text(result, "rho"),
        )


def _whole_cost(result, t0: float) -> dict:
    """``seconds``: the whole cost of an answer since ``t0`` (search and certificate), with its
    parts under ``timing``: the search as the result timed it, the rest (certificate, robustness)
    under ``certificate``."""
    whole = time.perf_counter() - t0
    search = result.timing[0] if result.timing is not None else result.stats.seconds
    return {"seconds": whole, "timing": {"search": search, "certificate": max(whole - search, 0.0)}}


def _verdict(result, positive: bool, yes="force closure", no="not force closure") -> str:
    """The certified verdict in words; a bracket that reaches zero is marginal, never closure."""
    if getattr(result, "marginal", False):
        return "marginal: within numerical accuracy of no interior"
    robust = getattr(result, "robust", None)
    if positive and robust is not None:
        shift = f"the support function may move {result.shift:.3g}"
        if robust:
            return f"{yes}, robust within the model's tolerance ({shift})"
        return f"{yes} by the file, NOT robust within the model's tolerance ({shift})"
    return yes if positive else no


def _bounds_text(result, name: str) -> str:
    """``; certified lo <= name <= hi`` (one digit more than the value, numbers.bracket), and
    the width when the bracket did not converge."""
    if getattr(result, "bounds", None) is None:
        return ""
    lo, hi = result.bounds
    text = "; certified {} <= {name} <= {}".format(*bracket(result.bounds), name=name)
    if not result.converged:
        text += f" (not converged: width {hi - lo:.2g})"
    return text


def _values(text: str, flag: str, count: int, convert):
    """One value, or a comma list of ``count`` values (one per contact)."""
    # ASCII spaces only: "fpc\u00a0" (a no-break space) is no contact type.
    parts = [p.strip(" \t") for p in str(text).split(",")]
    if len(parts) not in (1, count):
        raise ValueError(f"{flag}: expected 1 or {count} values (one per contact), got {text!r}")
    try:
        values = [convert(p) for p in parts]
    except ValueError:
        raise ValueError(f"{flag}: not a number in {text!r}") from None
    return values[0] if len(values) == 1 else values


def _int(text: str) -> int:
    """``int(text)`` of ASCII digits only (Python also reads "４８" as 48)."""
    return ascii_number(text, "", int)


def _float(text: str) -> float:
    """``float(text)`` of ASCII text only."""
    return ascii_number(text, "", float)


_int.__name__ = "integer"  # argparse says "invalid integer value: ..."
_float.__name__ = "number"


def _bounded(parse, noun: str, inside, limits: str, what: str):
    """argparse type: ``parse(text)`` where ``inside(value)``; the message names ``noun`` (what
    the text must be) or ``what`` and its ``limits``."""

    def convert(text: str):
        try:
            value = parse(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if not inside(value):
            raise argparse.ArgumentTypeError(f"{what} must be in {limits}, got {text}")
        return value

    return convert


def _bounded_int(low: int, high: int, what: str):
    """argparse type: an integer in [low, high] (the limit named in the message)."""
    return _bounded(_int, "an integer", lambda v: low <= v <= high, f"[{low}, {high}]", what)


_seed = _bounded_int(0, MAX_SEED, "a seed")


_starts = _bounded_int(1, MAX_STARTS, "the number of start weights")


# (flag, default, help) of the contact options every command on a MODEL takes.
CONTACT_OPTIONS = (
    ("--type", "pcwf", "fpc, pcwf, sfcl or sfce (default pcwf)"),
    ("--mu", "0.2", "Coulomb friction coefficient (default 0.2)"),
    (
        "--mu-s",
        "auto",
        "spin coefficient of soft fingers, a length in the model's units "
        "(default auto: 0.01 x the part's radius about its reference point)",
    ),
    ("--f-max", "1", "normal-force bound f^U (default 1)"),
    (
        "--torque-scale",
        "auto",
        "factor on every torque row (default auto: 1 / the part's radius, so that rho "
        "does not depend on the model's unit)",
    ),
)


def _bounded_float(low: float, high: float, what: str):
    """argparse type: a finite number in [low, high) (the limit named in the message)."""
    return _bounded(_float, "a number", lambda v: low <= v < high, f"[{low:g}, {high:g})", what)


_gap = _bounded_float(0.0, 1.0, "the gap")
_budget = _bounded(_float, "a number", lambda v: 0 < v < math.inf, "(0, inf)", "the time budget")


def _add_bound_options(parser) -> None:
    g = parser.add_argument_group("certified ceiling on the placement")
    g.add_argument(
        "--gap",
        type=_gap,
        default=0.02,
        metavar="G",
        help="search for better contacts until the certified gap to the best placement on the "
        "elements is at most G (default 0.02)",
    )
    g.add_argument(
        "--bound-cells",
        type=_bounded_int(1, 10**6, "the number of cells"),
        default=PlacementOptions.bound_cells,
        metavar="N",
        help="cells of that search's branch and bound at most (default 1, the root ceiling; "
        "40 tightens it by a few points at several times the cost; the same answer on any "
        "machine)",
    )
    g.add_argument(
        "--time-budget",
        type=_budget,
        default=None,
        metavar="SECONDS",
        help="seconds that search may take at most (default: no limit in seconds); the gap "
        "reached is reported either way",
    )
    g.add_argument(
        "--no-bound", action="store_true", help="skip the ceiling (the exchange method alone)"
    )


def _add_contact_options(parser) -> None:
    g = parser.add_argument_group("contact options (one value, or a comma list of one per contact)")
    for flag, default, text in CONTACT_OPTIONS:
        g.add_argument(flag, default=default, help=text)
    _add_mesh_option(parser)


def _add_mesh_option(parser) -> None:
    parser.add_argument(
        "--allow-outside-mesh",
        action="store_true",
        help="read the model's mesh even when its path leaves the model's folder",
    )


def _eligibility(args, m: int, field: str = "--contacts", closure: bool = False):
    """The model of ``args.model`` with ``m`` contacts of the requested specs (with
    ``closure``: only when such contacts can ever hold a 3-D part, else exit 2)."""
    with _reading(args.model):
        as_count(m, field, MAX_ELEMENT_CONTACTS, "contacts")  # the limit, before any work
    model = _load_model(args)
    with _reading(args.model):
        specs, scale = _specs(args, m, model)
    for line in scale_warnings(scale, [s.type.value for s in specs]):
        sys.stderr.write(f"warning: {_shown(args.model)}: {line}\n")
    args.scale = scale
    args.soft_fingers = any(s.type in SOFT_FINGERS for s in specs)  # mu_s plays a part
    if closure:
        with _reading(args.model):
            require_closure_count(specs, field)
    return Eligibility(model, specs, scale.torque_scale)


def _load_model(args, marked: list | None = None):
    """``args.model`` with its mesh checked: inside the model's folder (unless
    ``--allow-outside-mesh``), facet and segment normals pointing into it; a missing or broken
    mesh is one warning (it only serves pictures). With ``marked`` (a picture), elements whose
    normal points out of the mesh are put there, with one warning, instead of refused."""
    from dataclasses import replace

    from closure_nlp.model.elements import ElementKind
    from closure_nlp.model.model_mesh import check_normals, outward_elements, read_model_mesh

    [(_, model)] = _load_each([args.model], load_model)
    model = replace(model, tolerance=_tolerance(args, model.tolerance))
    if getattr(args, "allow_outside_mesh", False):
        model = replace(model, allow_outside_mesh=True)
    with _reading(args.model):
        model.mesh_path  # noqa: B018 - refuses a path outside the model's folder, before work
        judged = any(e.kind is not ElementKind.POINT for e in model.elements)
        if judged and not getattr(args, "no_mesh", False):  # points have nothing to check
            if marked is None:
                check_normals(model, read_model_mesh(model))
            else:
                marked += outward_elements(model, read_model_mesh(model))
    if marked:
        ids = ", ".join(str(i) for i in marked[:10]) + (", ..." if len(marked) > 10 else "")
        sys.stderr.write(
            f"warning: {args.model}: {len(marked)} element(s) with an inward normal pointing out "
            f"of the model's mesh, drawn marked (plan and the other commands refuse the model): "
            f"{ids}\n"
        )
    return model


def _specs(args, m: int, model):
    """The ``m`` contact specs of the contact options, and the scale (torque scale, mu_s)."""
    torque_scale = args.torque_scale
    if not is_auto(torque_scale):
        torque_scale = as_torque_scale(
            _values(torque_scale, "--torque-scale", 1, _float), "--torque-scale"
        )
    mu_s = args.mu_s if is_auto(args.mu_s) else _values(args.mu_s, "--mu-s", m, _float)
    types = _values(args.type, "--type", m, str)
    scale = resolve_scale(model, torque_scale, mu_s)
    try:
        specs = contact_specs(
            m,
            type=types,
            mu=_values(args.mu, "--mu", m, _float),
            mu_s=list(scale.mu_s) if isinstance(scale.mu_s, tuple) else scale.mu_s,
            f_max=_values(args.f_max, "--f-max", m, _float),
        )
    except ValueError as exc:
        raise ValueError(f"contact options: {exc}") from None
    return specs, scale


def _ids(text: str, flag: str) -> list[int]:
    try:
        return [_int(p) for p in text.split(",")]
    except ValueError:
        raise InputError(flag, f"expected comma-separated element ids, got {text!r}") from None


def _progress(args, starts: int | None = None):
    """``(callback, close)``: a progress line on stderr, only on a terminal and without
    ``--quiet``; ``starts`` (placement starts) gives an ETA over the starts."""
    return progress_line(args.quiet, {"placement start": starts} if starts else None)


def _add_eligibility(sub, common) -> None:
    p = sub.add_parser("eligibility", parents=[common], help="rho(0, What_c^M) of element sets")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--elements", required=True, help="element ids, one per contact: I,J,...")
    _add_contact_options(p)
    p.set_defaults(run=_cmd_eligibility)


def _cmd_eligibility(args) -> None:
    ids = _ids(args.elements, "--elements")
    eligibility = _eligibility(args, len(ids), "--elements")
    with _reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
    t0 = time.perf_counter()
    result = eligibility(ids)
    verdict = _verdict(result, result.eligible, "eligible", "not eligible")
    _emit(
        args,
        {**result.to_dict(), **_whole_cost(result, t0)},
        f"{_shown(args.model)}: elements {_join(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        + _bounds_text(result, "rho_hat"),
    )


def _add_select(sub, common) -> None:
    p = sub.add_parser("select", parents=[common], help="select eligible elements")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--contacts", type=_int, required=True, metavar="M", help="number of contacts")
    p.add_argument("--algorithm", choices=["heuristic", "iterative"], default="heuristic")
    p.add_argument("--start", help="start elements I,J,... (heuristic: its i0 < M start ids)")
    p.add_argument("--seed", type=_seed, default=0, help="random start of the heuristic")
    _add_contact_options(p)
    p.set_defaults(run=_cmd_select)


def _cmd_select(args) -> None:
    eligibility = _eligibility(args, args.contacts, closure=True)
    with _reading(args.model):
        start = _ids(args.start, "--start") if args.start else None
        if start is not None:
            eligibility.check_elements(start, "--start", partial=True)
    progress, close = _progress(args)
    try:
        result = run_selection(
            eligibility, args.algorithm, start=start, seed=args.seed, progress=progress
        )
    finally:
        close()
    verdict = _verdict(result, result.eligible, "eligible", "not eligible")
    _emit(
        args,
        {"algorithm": args.algorithm, **result.to_dict()},
        f"{_shown(args.model)}: {args.algorithm}: elements {_join(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        f"{_bounds_text(result, 'rho_hat')}; "
        f"{result.evaluations} evaluations in {result.seconds:.2f} s",
    )
    if not result.eligible:
        raise MethodError(
            f"{args.model}: no eligible element set found (best rho_hat = {result.rho_hat:.6g})"
        )


def _add_placement_options(p) -> None:
    """The placement's options, as ``place`` and ``plan`` share them."""
    p.add_argument("--starts", type=_starts, default=4, help="placement start weights (default 4)")


def _add_place(sub, common) -> None:
    p = sub.add_parser("place", parents=[common], help="optimal contacts on given elements")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--elements", required=True, help="element ids, one per contact: I,J,...")
    _add_placement_options(p)
    p.add_argument("--seed", type=_seed, default=0, help="random start weights after the first")
    p.add_argument("--out", metavar="FILE", help="write the placed contacts as a contact-set file")
    _add_margin_option(p)
    _add_bound_options(p)
    _add_contact_options(p)
    p.set_defaults(run=_cmd_place)


def _add_margin_option(p) -> None:
    p.add_argument(
        "--margin",
        type=_bounded_float(0.0, float("inf"), "the margin"),
        default=0.0,
        metavar="D",
        help="keep every contact at least D (model units) from its element's boundary "
        "(default 0); the ceiling covers the same region",
    )


def _with_margin(args, eligibility: Eligibility, ids=()) -> Eligibility:
    """``eligibility`` on the model shrunk by ``--margin`` (itself when the margin is 0);
    ``ids``: elements the command names, refused when too small for the margin."""
    from closure_nlp.placement.margin import with_margin

    if not args.margin:
        return eligibility
    model, dropped = with_margin(eligibility.model, args.margin)
    small = sorted(set(ids) & set(dropped))
    if small:
        raise InputError(
            "--margin",
            f"element(s) {_join(small)} too small for a margin of {args.margin:g}: "
            "no point of them is that far from their boundary",
        )
    if len(model.unusable) == len(model):
        raise InputError("--margin", f"every element is too small for a margin of {args.margin:g}")
    specs, scale = eligibility.specs, eligibility.torque_scale
    return Eligibility(model, specs, scale, tolerance=eligibility.tolerance)


def _margin_text(args, model) -> str:
    """The margin's line of a command's text (empty without a margin)."""
    if not args.margin:
        return ""
    text = f"\n  every contact at least {args.margin:g} from its element's boundary"
    left = model.unusable
    if left:
        listed = _join(left) if len(left) <= 12 else f"{_join(left[:12])},..."
        text += f"; {len(left)} element(s) too small for it left out ({listed})"
    return text


def _placement_options(args, seeded: bool) -> PlacementOptions:
    """``--starts`` (and ``--seed`` when it seeds the placement, as in ``place``; in ``plan`` it
    seeds the heuristic only, like the API's ``plan(seed=...)``: one seed, one answer)."""
    bound = {
        "bound": not args.no_bound,
        "target_gap": args.gap,
        "bound_cells": args.bound_cells,
        "time_budget": args.time_budget,
    }
    try:
        return PlacementOptions(
            starts=args.starts, **bound, **({"seed": args.seed} if seeded else {})
        )
    except ValueError as exc:
        raise ValueError(f"--{exc}") from None


def _placement_setup(args, seeded: bool, check_out):
    """``(options, progress, close)`` of a command that places contacts, its ``--out`` checked
    by ``check_out`` before any work."""
    with _reading(args.model):
        options = _placement_options(args, seeded)
    if args.out:
        with _reading(args.out):
            check_out(args.out)
    progress, close = _progress(args, options.starts)
    return options, progress, close


def _placement_text(result, model) -> str:
    verdict = _verdict(result, result.force_closure)
    bounds = _bounds_text(result, "rho")
    lines = [
        f"rho = {certain(result.rho, result.bounds)} ({verdict}){bounds}; "
        f"centroids gave {certain(result.start_rho)}; {result.seconds:.2f} s"
    ]
    if result.capacity_bound is not None:
        lines.append(f"  {gap_text(result)}")
    for i, c in enumerate(result.contacts):
        pos = lengths(c.position, model)  # to the model's accuracy (numbers.model_accuracy)
        lines.append(f"  contact {i}: element {c.element} at [{pos}]")
    return "\n".join(lines)


def _cmd_place(args) -> None:
    from closure_nlp.placement.margin import on_original

    ids = _ids(args.elements, "--elements")
    eligibility = _eligibility(args, len(ids), "--elements")
    original = eligibility.model
    with _reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
        require_closure_count(eligibility.specs, "--elements")
        eligibility = _with_margin(args, eligibility, ids)
    options, progress, close = _placement_setup(args, True, check_output_file)
    try:
        result = Placer(eligibility, options)(ids, progress=progress)
    finally:
        close()
    if args.margin:
        result = on_original(result, original)
    placed = _placement_text(result, original)
    payload, text = result.to_dict(), f"{_shown(args.model)}: {placed}"
    payload["margin"] = args.margin
    text += _margin_text(args, eligibility.model)
    if args.out:
        _check_finite(payload, args.model)  # before anything is written
        model = eligibility.model
        try:
            write_json(
                args.out, {**result.contact_file(model.name, model.units), "margin": args.margin}
            )
        except OSError as exc:
            raise OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
        payload["out"] = {"contacts": str(args.out)}
        text += f"\ncontacts in {_shown(args.out)}"
    _emit(args, payload, text)
    if not result.force_closure:
        raise MethodError(
            f"{args.model}: the placed contacts are not force closure (rho = {result.rho:.6g})"
        )
    if result.robust is False:
        raise MethodError(
            f"{args.model}: the placed contacts are not robust within the model's tolerance "
            f"(support shift {result.shift:.3g} against -hi = {-result.bounds[1]:.3g})"
        )


def _add_plan(sub, common) -> None:
    p = sub.add_parser("plan", parents=[common], help="heuristic, iterative and placement")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--contacts", type=_int, required=True, metavar="M", help="number of contacts")
    p.add_argument(
        "--seed", type=_seed, default=0, help="random start of the heuristic (the first seed)"
    )
    p.add_argument(
        "--seeds",
        type=_bounded_int(1, MAX_PLAN_SEEDS, "the number of seeds"),
        default=DEFAULT_SEEDS,
        metavar="N",
        help=f"plans from seeds S..S+N-1, the best returned (default {DEFAULT_SEEDS})",
    )
    p.add_argument(
        "--budget",
        type=_budget,
        default=DEFAULT_BUDGET,
        metavar="SECONDS",
        help=f"no further seed starts after this (default {DEFAULT_BUDGET:g})",
    )
    p.add_argument(
        "--workers",
        type=_bounded_int(1, MAX_WORKERS, "the number of worker processes"),
        metavar="K",
        help="processes the seeds run on (default: one per core)",
    )
    _add_placement_options(p)
    p.add_argument(
        "--alternatives",
        type=_int,
        default=4,
        metavar="N",
        help="further element sets placed when placement fails (default 4)",
    )
    p.add_argument(
        "--out", metavar="DIR", help="write report.json, contacts.json, pictures and summary.md"
    )
    p.add_argument(
        "--up", choices=["x", "y", "z"], help="model axis drawn upwards (default: the model's)"
    )
    _add_margin_option(p)
    _add_bound_options(p)
    _add_contact_options(p)
    p.set_defaults(run=_cmd_plan)


def _cmd_plan(args) -> None:
    from closure_nlp.placement.margin import on_original

    eligibility = _eligibility(args, args.contacts, closure=True)
    original = eligibility.model
    with _reading(args.model):
        eligibility = _with_margin(args, eligibility)
    placement_options, progress, close = _placement_setup(args, False, check_output_dir)
    try:
        if args.seed + args.seeds - 1 > MAX_SEED:
            raise InputError(
                "--seeds", f"seeds {args.seed}..{args.seed + args.seeds - 1} pass {MAX_SEED}"
            )
        several = {} if args.seeds == 1 else {"seeds": args.seeds, "workers": args.workers}
        result = plan(
            eligibility,
            seed=args.seed,
            placement=placement_options,
            progress=progress,
            alternatives=_alternatives_flag(args.alternatives),
            **several,
            **({"budget": args.budget} if several else {}),
        )
    finally:
        close()
    if args.margin:  # contacts' weights on the file's elements: the same positions
        result = dataclasses.replace(result, placement=on_original(result.placement, original))
    payload = result.to_dict()
    payload["margin"] = args.margin
    _check_finite(payload, args.model)  # before anything is written
    if args.out:
        options = {
            "contacts": args.contacts,
            "seed": args.seed,
            "seeds": args.seeds,
            "budget": args.budget,
            "type": args.type,
            "mu": args.mu,
            "f_max": args.f_max,
            **args.scale.to_dict(),  # mu_s, torque scale, reference point: the values used
            "placement": vars(placement_options),
            "alternatives": args.alternatives,
            "up": args.up or eligibility.model.up,
            "margin": args.margin,
        }
        with staged_folder(args.out) as staged:  # all files of this run, or none
            written = write_report(original, result, staged, options)
        payload["out"] = {name: os.path.join(args.out, name) for name in written}
    h, it = result.heuristic, result.iterative
    text = (
        f"{_shown(args.model)}: heuristic {_join(h.elements)} "
        f"rho_hat = {certain(h.rho_hat, h.bounds)} "
        f"({h.seconds:.2f} s); iterative {_join(it.elements)} "
        f"rho_hat = {certain(it.rho_hat, it.bounds)} "
        f"({it.seconds:.2f} s)\n"
        + "".join(
            f"placement on {_join(a.elements)} ({a.source}): rho = {a.rho:.6g}"
            f"{' (force closure)' if a.force_closure else ''} ({a.seconds:.2f} s)\n"
            for a in result.attempts[1:]
        )
        + f"{_placement_text(result.placement, original)}"
        + f"{_margin_text(args, eligibility.model)}\n"
        + ("" if result.seeds is None else result.seeds.line() + "\n")
        + f"total {result.seconds:.2f} s"
        + (f"; report in {_shown(args.out)}" if args.out else "")
    )
    _emit(args, payload, text)
    if not result.force_closure:
        raise MethodError(f"{args.model}: {result.failure()}")
    if result.placement.robust is False:
        raise MethodError(
            f"{args.model}: no robust placement found: the placed contacts are force closure by "
            f"the file but not within the model's tolerance (support shift "
            f"{result.placement.shift:.3g} against -hi = {-result.placement.bounds[1]:.3g})"
        )


def _alternatives_flag(value: int) -> int:
    if value < 0:
        raise ValueError(f"--alternatives: expected an integer >= 0, got {value}")
    return value


def _join(ids) -> str:
    return ",".join(str(i) for i in ids)


# --- parser ---------------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad flags the docs/formats.md way: one ``error:`` line, exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="closure-nlp", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = _Parser(add_help=False)
    common.add_argument("--json", action="store_true", help="print only JSON on stdout")
    common.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    common.add_argument(
        "--position-tolerance",
        type=_bounded_float(0.0, float("inf"), "the position tolerance"),
        metavar="LENGTH",
        help="how far the real part's contact points may lie from the file's (model units; "
        "default: the file's tolerance, else 0)",
    )
    common.add_argument(
        "--normal-tolerance",
        type=_bounded_float(0.0, 90.0, "the normal tolerance"),
        metavar="DEGREES",
        help="how far the real part's normals may lie from the file's (default: the file's "
        "tolerance, else 0); results say whether they are robust within both",
    )
    for add in COMMANDS:
        add(sub, common)
    return parser


# Functions (subparsers, common_parent) -> None, each registering one command.
COMMANDS: list = [_add_rho, _add_eligibility, _add_select, _add_place, _add_plan]


# --- characterize and show (element models from meshes, pictures) ----------------------------


def _length(text: str) -> float:
    """argparse type: a finite number >= 0."""
    try:
        value = _float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def _spacing(text: str):
    """argparse type: ``auto`` or a finite number >= 0."""
    return "auto" if text.strip().lower() == "auto" else _length(text)


def _point3(text: str) -> list[float]:
    """argparse type: ``x,y,z``."""
    parts = text.split(",")
    try:
        values = [_float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(abs(v) < float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"expected three numbers x,y,z, got {text!r}")
    return values


def _add_characterize(sub, common) -> None:
    p = sub.add_parser(
        "characterize", parents=[common], help="element model (facets, segments, points) of a mesh"
    )
    p.add_argument("mesh", metavar="MESH", help="mesh file (STL, OBJ, PLY, GLB, OFF...)")
    p.add_argument("--out", required=True, metavar="MODEL", help="*.model.json to write")
    spacing = "(default auto: 0.2 x the part's radius; 0 keeps all)"
    p.add_argument(
        "--segment-spacing",
        type=_spacing,
        default="auto",
        metavar="X",
        help=f"ruling spacing {spacing}",
    )
    p.add_argument(
        "--point-spacing",
        type=_spacing,
        default="auto",
        metavar="Y",
        help=f"point spacing {spacing}",
    )
    p.add_argument(
        "--sharp-angle",
        type=_length,
        default=30.0,
        metavar="DEG",
        help="edges sharper than this separate surfaces (default 30)",
    )
    p.add_argument("--name", help="model name (default: the mesh file's stem)")
    p.add_argument(
        "--units",
        choices=["m", "cm", "mm", "in"],
        help="length unit of the mesh (default m; the unit used is printed)",
    )
    p.add_argument(
        "--merge-bodies",
        action="store_true",
        help="hold a mesh of several separate bodies as one rigid part (default: refuse it)",
    )
    p.add_argument(
        "--reference-point",
        type=_point3,
        metavar="X,Y,Z",
        help="point torques are taken about (default: the part's centre of mass)",
    )
    p.add_argument("--up", default="z", choices=["x", "y", "z"], help="up axis for pictures")
    p.set_defaults(run=_cmd_characterize)


# The flags of ``characterize`` passed to :func:`characterize_mesh` under their own names.
CHARACTERIZE_FLAGS = (
    "segment_spacing",
    "point_spacing",
    "sharp_angle",
    "name",
    "units",
    "reference_point",
    "up",
    "merge_bodies",
)


def _cmd_characterize(args) -> None:
    import os
    from pathlib import Path

    from closure_nlp.base.files import write_atomic
    from closure_nlp.model.characterize import characterize_mesh, drop_outward_as_read
    from closure_nlp.model.elements import save_model
    from closure_nlp.model.scale import units_warning

    with _reading(args.out):
        out = check_output_file(args.out)
    mesh_ref = Path(os.path.relpath(Path(args.mesh).resolve(), out.resolve().parent)).as_posix()
    copy = None
    if mesh_ref.startswith("../"):  # models read only meshes in their folder: write one there
        copy = out.parent / (out.name.removesuffix(".json").removesuffix(".model") + ".mesh.stl")
        mesh_ref = copy.name
    try:
        found = characterize_mesh(
            args.mesh, mesh_ref=mesh_ref, **{k: getattr(args, k) for k in CHARACTERIZE_FLAGS}
        )
    except ValueError as exc:
        text, prefix = str(exc), f"{args.mesh}: "
        raise InputError(args.mesh, text.removeprefix(prefix)) from None
    model, dropped = found.model, list(found.dropped)
    model = dataclasses.replace(model, tolerance=_tolerance(args, model.tolerance))
    try:
        if copy is not None:  # the repaired mesh, beside the model (pictures draw it)
            write_atomic(copy, found.mesh.export(file_type="stl"))
        # The model commands judge normals against the mesh file as they read it (an STL holds
        # 32-bit coordinates): judged here the same way, so they never refuse what is written.
        model, more = drop_outward_as_read(model, out.parent)
        dropped += more
        save_model(model, out)
    except OSError as exc:
        raise OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
    for line in dropped:
        sys.stderr.write(f"warning: {_shown(args.mesh)}: dropped {line}\n")
    warning = units_warning(model.radius, model.units)
    if warning:
        sys.stderr.write(f"warning: {_shown(args.mesh)}: {warning}\n")
    counts = model.counts()
    summary = ", ".join(f"{n} {kind}s" for kind, n in counts.items())
    payload = {
        "file": args.mesh,
        "elements": counts,
        "adjacency": len(model.adjacency),
        "out": str(out),
        "units": model.units,
        "reference_point": model.reference_point.tolist(),
        "radius": model.radius,
        "segment_spacing": found.segment_spacing,
        "point_spacing": found.point_spacing,
        "repairs": list(found.repairs),
        "dropped": dropped,
        "tolerance": model.tolerance.to_dict(),
    }
    tol = model.tolerance
    _emit(
        args,
        payload,
        f"{_shown(args.mesh)}: {found.text()}\n{_shown(args.mesh)}: {summary}, "
        f"{len(model.adjacency)} neighbour pairs -> {_shown(out)}"
        f"\n{_shown(args.mesh)}: model accuracy: positions within "
        f"{tol.position:.3g}{' ' + model.units if model.units else ''}, normals within "
        f"{tol.normal_deg:.3g} degrees of the mesh (verdicts are robust within it)",
    )


def _angle(text: str) -> float:
    """argparse type: a finite number of degrees (``nan`` would draw an empty picture)."""
    try:
        value = _float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not abs(value) <= 360.0:
        raise argparse.ArgumentTypeError(f"expected degrees in [-360, 360], got {text!r}")
    return value


def _add_show(sub, common) -> None:
    p = sub.add_parser("show", parents=[common], help="picture (or 3-D scene) of a model")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument(
        "--contacts", metavar="FILE", help="*.contacts.json (or a plan's report.json) to draw"
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="PNG",
        help="picture (.png .svg .pdf .jpg) or interactive scene (.glb .html)",
    )
    p.add_argument(
        "--highlight",
        metavar="I,J,...",
        help="element ids to highlight (default: the contacts' 'element' ids)",
    )
    p.add_argument("--elev", type=_angle, default=22.0, help="view elevation, degrees")
    p.add_argument("--azim", type=_angle, default=-58.0, help="view azimuth, degrees")
    p.add_argument("--no-mesh", action="store_true", help="do not draw the model's mesh")
    _add_mesh_option(p)
    p.add_argument("--ids", action="store_true", help="write each element's id beside it")
    p.add_argument(
        "--up", choices=["x", "y", "z"], help="model axis drawn upwards (default: the model's)"
    )
    p.set_defaults(run=_cmd_show)


def _contact_elements(path: str) -> list[int]:
    """The ``element`` ids named by the contacts of a contact-set file (for highlighting)."""
    from closure_nlp.base.files import load_json

    data = load_json(path)
    if isinstance(data, dict) and isinstance(data.get("contact_set"), dict):
        data = data["contact_set"]  # a plan's report.json
    entries = data.get("contacts", []) if isinstance(data, dict) else []
    ids = [e.get("element") for e in entries if isinstance(e, dict)]
    return [i for i in ids if isinstance(i, int) and not isinstance(i, bool)]


def _show_title(model, contacts) -> str | None:
    """``name: N contacts, rho = ... (verdict)`` when contacts are drawn (their certified rho,
    as ``closure-nlp rho`` gives it); None: the model's name and counts."""
    if contacts is None or not contacts.contacts:
        return None
    result = rho(contacts)
    return (
        f"{model.name}: {len(contacts.contacts)} contacts, rho = "
        f"{certain(result.rho, result.bounds)} ({_verdict(result, result.force_closure)})"
    )


def _cmd_show(args) -> None:
    from pathlib import Path

    from closure_nlp.report.drawing import PICTURE_SUFFIXES, SCENE_SUFFIXES, save_view

    with _reading(args.out):
        check_output_file(args.out)
    marked: list[int] = []
    model = _load_model(args, marked)
    contacts, highlight = None, []
    if args.contacts:
        [(_, contacts)] = _load_each([args.contacts], load_contacts)
        highlight = _contact_elements(args.contacts)
    if args.highlight:
        try:
            highlight = [_int(part) for part in args.highlight.split(",")]
        except ValueError:
            message = f"expected element ids I,J,..., got {args.highlight!r}"
            raise InputError("--highlight", message) from None
    try:
        for k, i in enumerate(highlight):
            model.check_id(i, f"contacts[{k}].element" if not args.highlight else "--highlight")
    except (ValueError, TypeError) as exc:
        raise InputError(args.contacts if not args.highlight else "--highlight", str(exc)) from None
    suffix = Path(args.out).suffix.lower()
    if suffix not in PICTURE_SUFFIXES | SCENE_SUFFIXES:
        raise InputError(
            "--out",
            f"unsupported file type {suffix or args.out!r} "
            "(use .png, .svg, .pdf, .jpg, .glb or .html)",
        )
    options = {"up": args.up, "title": _show_title(model, contacts)}
    if suffix not in SCENE_SUFFIXES:
        options.update(view=(args.elev, args.azim), show_mesh=not args.no_mesh, ids=args.ids)
    try:
        out = save_view(model, args.out, contacts, highlight=highlight, marked=marked, **options)
    except OSError as exc:
        raise OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
    point = ", ".join(f"{x:.6g}" for x in model.reference_point)
    _emit(
        args,
        {
            "file": args.model,
            "out": str(out),
            "units": model.units,
            "reference_point": model.reference_point.tolist(),
            "marked": marked,
        },
        f"{_shown(args.model)}: drawn to {_shown(out)} (torques about [{point}]"
        + (f" {model.units}" if model.units else "")
        + ", marked x)",
    )


COMMANDS.extend([_add_characterize, _add_show])


# --- study: grids of plans on Dask (closure_nlp.study) ----------------------------------------


def _study_count(least: int):
    """argparse type: an integer >= ``least``."""

    def convert(text: str) -> int:
        try:
            value = _int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"expected an integer >= {least}, got {text!r}")
        return value

    return convert


def _scheduler_address(text: str) -> str:
    """argparse type: a Dask scheduler address (exit 2 when malformed, before any work)."""
    from closure_nlp.study import check_scheduler_address

    try:
        return check_scheduler_address(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("scheduler: ")) from None


def _add_study(sub, common) -> None:
    p = sub.add_parser(
        "study", parents=[common], help="a grid of plans (models x contacts x seeds) on Dask"
    )
    p.add_argument("study", metavar="STUDY", help="study file (TOML)")
    p.add_argument(
        "--out", required=True, metavar="DIR", help="results/, summary.md/.csv, results.csv, plots"
    )
    p.add_argument(
        "--scheduler",
        type=_scheduler_address,
        metavar="ADDRESS",
        help="join this Dask scheduler (tcp://HOST:PORT)",
    )
    p.add_argument(
        "--workers",
        type=_bounded_int(1, MAX_WORKERS, "the number of local workers"),
        metavar="N",
        help="local workers (default: cores)",
    )
    p.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    p.add_argument(
        "--limit", type=_study_count(0), metavar="N", help="run at most N tasks now (then resume)"
    )
    p.add_argument("--retry-failed", action="store_true", help="run failed tasks again")
    p.set_defaults(run=_cmd_study)


def _cmd_study(args) -> None:
    from closure_nlp.study import load_study, run_study

    try:
        study = load_study(args.study)
    except (ValueError, TypeError) as exc:
        raise InputError(args.study, str(exc)) from None
    with _reading(args.out):
        check_output_dir(args.out, marker=None)  # results are added to it (resume)
    bar = None

    def progress(done: int, total: int, row) -> None:
        nonlocal bar
        if bar is None:
            from tqdm import tqdm

            bar = tqdm(total=total, unit="task", file=sys.stderr, leave=False, desc=study.name)
        if row is not None:
            bar.set_postfix_str(f"{row['model']} {row['type']}x{row['contacts']}", refresh=False)
            bar.update(1)

    quiet = args.quiet or not sys.stderr.isatty()
    try:
        result = run_study(
            study,
            args.out,
            scheduler=args.scheduler,
            workers=args.workers,
            serial=args.serial,
            limit=args.limit,
            retry_failed=args.retry_failed,
            progress=None if quiet else progress,
        )
    finally:
        if bar is not None:
            bar.close()
    payload = {"file": args.study, **result.to_dict()}
    text = (
        f"{_shown(args.study)}: {result.total} tasks: {result.run} run ({result.failed} failed), "
        f"{result.skipped} done before, {result.remaining} remaining; {result.seconds:.1f} s on "
        f"{result.workers} worker(s), {result.tasks_per_second:.3f} tasks/s\n"
        f"summary in {_shown(result.paths['summary.md'])}"
    )
    _emit(args, payload, text)
    if result.failed:
        raise MethodError(
            f"{args.study}: {result.failed} of {result.run} tasks failed "
            f"(errors in {result.paths['summary.md']})"
        )


COMMANDS.append(_add_study)


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit status (module docstring) and never raises."""
    try:
        if sys.stdout is None:  # started with stdout closed: an answer would be lost
            raise OutputFault("stdout", "closed: nothing could be printed")
        args = build_parser().parse_args(argv)
        with _one_line_warnings(), interruptible():
            _compile_kernels(args)
            args.run(args)
        _flush_stdout()  # a full device fails here: the answer is not out, exit 1
    except SystemExit as exc:  # argparse: --help (0) or a bad flag (2, its line already printed)
        return exc.code if isinstance(exc.code, int) else 2
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: stopped by Ctrl-C; finished output is kept\n")
        return 130
    except InputError as exc:
        _error(exc)
        return 2
    except (MethodError, OutputFault) as exc:
        _error(exc)
        if isinstance(exc, OutputFault) and str(exc).startswith("stdout"):
            _drop_stdout()
        return 1
    except MemoryError:
        sys.stderr.write("error: out of memory: the input is too large for this machine\n")
        return 1
    except BrokenPipeError:  # stdout closed early (``| head``): nothing more to say
        _drop_stdout()
        return 1
    except OSError as exc:  # the system said no: a full disk, a lost scheduler
        text = exc.strerror or str(exc)
        _error(f"{exc.filename}: {text}" if exc.filename is not None else text)
        return 1
    except Exception as exc:  # a bug: said as one, never dressed as bad input
        if os.environ.get("CLOSURE_NLP_TRACEBACK"):
            import traceback

            traceback.print_exc()
        text = escape(" ".join(str(exc).split())[:300])
        sys.stderr.write(
            f"internal error: {type(exc).__name__}: {text} (a bug in closure_nlp, not in the "
            "input; CLOSURE_NLP_TRACEBACK=1 shows where)\n"
        )
        return 3
    return 0


def _error(exc) -> None:
    """The one ``error:`` line, control characters of names escaped."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"error: {escape(str(exc))}\n")


def _drop_stdout() -> None:
    """Point stdout at the null device: the interpreter's last flush must not fail again
    (it would print "Exception ignored" and change the exit status)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        fd = sys.stdout.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, fd)
        os.close(null)


def _compile_kernels(args) -> None:
    """Before a command that computes rho: the compiled kernels, loaded from the disk cache, or
    compiled once, said on stderr (how long) like the progress lines: on a terminal, unless
    ``--quiet``."""
    if args.run not in (_cmd_rho, _cmd_eligibility, _cmd_select, _cmd_place, _cmd_plan, _cmd_study):
        return
    from closure_nlp.rho.warm_up import warm_up

    shown = not args.quiet and sys.stderr.isatty()
    notify = (lambda text: sys.stderr.write(f"{text}\n")) if shown else None
    warm_up(notify, rho_only=args.run is _cmd_rho, capacity=_frictionless_placements(args))


def _frictionless_placements(args) -> bool:
    """Whether the command may place contacts that are all frictionless (the zonotope's
    capacity then runs): a study's tasks may; plan and place unless their options give a
    contact friction (FPC, or a zero or unreadable ``--mu``, counts as maybe); the others
    place nothing."""
    if args.run is _cmd_study:
        return True
    if args.run not in (_cmd_plan, _cmd_place):
        return False
    try:
        types = [ContactType.parse(p.strip(" \t")) for p in str(args.type).split(",")]
        mus = [_float(p.strip(" \t")) for p in str(args.mu).split(",")]
    except ValueError:
        return True  # the command refuses the option later: nothing to save here
    return ContactType.FPC in types or not all(mu > 0 for mu in mus)


@contextlib.contextmanager
def _one_line_warnings():
    """Each warning is one ``warning:`` line on stderr (Python's format adds a source line)."""
    import warnings

    saved = warnings.showwarning
    seen = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        if text not in seen:  # the same warning from two places is still one line
            seen.add(text)
            sys.stderr.write(f"warning: {escape(text)}\n")

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = saved


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
