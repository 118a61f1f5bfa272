"""Parsing of flag values, and the options several commands share."""

from __future__ import annotations

import argparse
import math

from closure_nlp.base.cores import MAX_WORKERS  # noqa: F401  (the commands' bound)
from closure_nlp.base.validation import (
    MAX_SEED,
    ascii_number,
)
from closure_nlp.cli.output import InputError
from closure_nlp.placement.options import PlacementOptions

MAX_ALTERNATIVES = 1000  # further element sets a plan places: each is a full placement
MAX_STARTS = 100  # placement start weights per run: each is a full exchange method


def model_tolerance(args, given):
    """The file's tolerance (one, or one per contact) with the command line's values in place
    of its own."""
    flags = args.position_tolerance, args.normal_tolerance
    if isinstance(given, tuple):
        return given if flags == (None, None) else tuple(t.merged(*flags) for t in given)
    return given.merged(*flags)


def value_list(text: str, flag: str, count: int, convert):
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


def int_value(text: str) -> int:
    """``int(text)`` of ASCII digits only (Python also reads "４８" as 48)."""
    return ascii_number(text, "", int)


def float_value(text: str) -> float:
    """``float(text)`` of ASCII text only."""
    return ascii_number(text, "", float)


def bounded(parse, noun: str, inside, limits: str, what: str):
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


def bounded_int(low: int, high: int, what: str):
    """argparse type: an integer in [low, high] (the limit named in the message)."""
    return bounded(int_value, "an integer", lambda v: low <= v <= high, f"[{low}, {high}]", what)


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


def bounded_float(low: float, high: float, what: str):
    """argparse type: a finite number in [low, high) (the limit named in the message)."""
    return bounded(float_value, "a number", lambda v: low <= v < high, f"[{low:g}, {high:g})", what)


def add_bound_options(parser) -> None:
    g = parser.add_argument_group("certified ceiling on the placement")
    g.add_argument(
        "--gap",
        type=gap_value,
        default=0.02,
        metavar="G",
        help="search for better contacts until the certified gap to the best placement on the "
        "elements is at most G (default 0.02)",
    )
    g.add_argument(
        "--bound-cells",
        type=bounded_int(1, 10**6, "the number of cells"),
        default=PlacementOptions.bound_cells,
        metavar="N",
        help=f"cells of that search's branch and bound at most (default "
        f"{PlacementOptions.bound_cells}; 1: the root ceiling alone; the same answer on any "
        "machine)",
    )
    g.add_argument(
        "--bound-neighbours",
        action="store_true",
        help="the ceiling covers each contact's neighbouring elements too (the elements the "
        "exchange method may move it to; far looser), not only the element it sits on",
    )
    g.add_argument(
        "--time-budget",
        type=budget_value,
        default=None,
        metavar="SECONDS",
        help="seconds that search may take at most (default: no limit in seconds); the gap "
        "reached is reported either way",
    )
    g.add_argument(
        "--no-bound", action="store_true", help="skip the ceiling (the exchange method alone)"
    )


def add_contact_options(parser) -> None:
    g = parser.add_argument_group("contact options (one value, or a comma list of one per contact)")
    for flag, default, text in CONTACT_OPTIONS:
        g.add_argument(flag, default=default, help=text)
    add_mesh_option(parser)


def add_placing_options(parser) -> None:
    """The options of the commands that place contacts (place, plan): margin, ceiling, where
    contacts may go, contact options."""
    add_margin_option(parser)
    add_bound_options(parser)
    add_region_options(parser)
    add_fixed_option(parser)
    parser.add_argument(
        "--min-spacing",
        type=bounded_float(0.0, float("inf"), "--min-spacing"),
        default=0.0,
        metavar="D",
        help="no two contacts (new or fixed) closer than D (model units; default 0: no limit)",
    )
    add_contact_options(parser)


def add_fixed_option(parser) -> None:
    parser.add_argument(
        "--fixed",
        metavar="CONTACTS.json",
        help="contacts already in place (a contact-set file, the model's frame and units): "
        "counted in every rho, never moved; --contacts counts the new ones",
    )


def add_region_options(parser) -> None:
    g = parser.add_argument_group(
        "where contacts may go (repeatable: --only regions united, then --exclude regions removed)"
    )
    forms = "ids:I,J,A-B | facing:AXIS[:DEG] | box:X0,Y0,Z0,X1,Y1,Z1"
    g.add_argument("--only", action="append", metavar="SPEC", help=f"contacts only here: {forms}")
    g.add_argument("--exclude", action="append", metavar="SPEC", help=f"never here: {forms}")


def add_mesh_option(parser) -> None:
    parser.add_argument(
        "--allow-outside-mesh",
        action="store_true",
        help="read the model's mesh even when its path leaves the model's folder",
    )


def id_list(text: str, flag: str) -> list[int]:
    try:
        return [int_value(p) for p in text.split(",")]
    except ValueError:
        raise InputError(flag, f"expected comma-separated element ids, got {text!r}") from None


def add_placement_options(p) -> None:
    """The placement's options, as ``place`` and ``plan`` share them."""
    p.add_argument(
        "--starts", type=starts_value, default=4, help="placement start weights (default 4)"
    )


def add_margin_option(p) -> None:
    p.add_argument(
        "--margin",
        type=bounded_float(0.0, float("inf"), "the margin"),
        default=0.0,
        metavar="D",
        help="keep every contact at least D (model units) from its element's boundary "
        "(default 0); the ceiling covers the same region",
    )


def number_value(text: str) -> float:
    """``text`` as a number, or argparse's error naming it."""
    try:
        return float_value(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def length_value(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = number_value(text)
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def spacing_value(text: str):
    """argparse type: ``auto`` or a finite number >= 0."""
    return "auto" if text.strip().lower() == "auto" else length_value(text)


def point3_value(text: str) -> list[float]:
    """argparse type: ``x,y,z``."""
    parts = text.split(",")
    try:
        values = [float_value(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(abs(v) < float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"expected three numbers x,y,z, got {text!r}")
    return values


def angle_value(text: str) -> float:
    """argparse type: a finite number of degrees (``nan`` would draw an empty picture)."""
    value = number_value(text)
    if not abs(value) <= 360.0:
        raise argparse.ArgumentTypeError(f"expected degrees in [-360, 360], got {text!r}")
    return value


def study_count(least: int):
    """argparse type: an integer >= ``least``."""

    def convert(text: str) -> int:
        try:
            value = int_value(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"expected an integer >= {least}, got {text!r}")
        return value

    return convert


def scheduler_address(text: str) -> str:
    """argparse type: a Dask scheduler address (exit 2 when malformed, before any work)."""
    from closure_nlp.study import check_scheduler_address

    try:
        return check_scheduler_address(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("scheduler: ")) from None


seed_value = bounded_int(0, MAX_SEED, "a seed")
starts_value = bounded_int(1, MAX_STARTS, "the number of start weights")
gap_value = bounded_float(0.0, 1.0, "the gap")
budget_value = bounded(
    float_value, "a number", lambda v: 0 < v < math.inf, "(0, inf)", "the time budget"
)


def model_parser(sub, common, name: str, help_text: str, count: str | None = None):
    """The parser of a command on one MODEL; ``count`` adds how it says how many contacts:
    ``"elements"`` (``--elements I,J,...``, one per contact) or ``"contacts"`` (``--contacts
    M``)."""
    p = sub.add_parser(name, parents=[common], help=help_text)
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    if count == "elements":
        p.add_argument("--elements", required=True, help="element ids, one per contact: I,J,...")
    elif count == "contacts":
        p.add_argument(
            "--contacts", type=int_value, required=True, metavar="M", help="number of contacts"
        )
    return p
