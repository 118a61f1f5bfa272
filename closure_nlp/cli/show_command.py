"""``closure-nlp show MODEL --out PNG``: a picture of a model and contacts."""

from __future__ import annotations

from closure_nlp.base.files import (
    check_output_file,
)
from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output
from closure_nlp.cli.loads_option import add_loads_option, read_loads
from closure_nlp.cli.setup import read_model
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.regions import with_exclusions
from closure_nlp.report.plan_report import load_contacts


def add_show(sub, common) -> None:
    p = arguments.model_parser(sub, common, "show", "picture (or 3-D scene) of a model")
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
    p.add_argument(
        "--elev", type=arguments.angle_value, default=22.0, help="view elevation, degrees"
    )
    p.add_argument(
        "--azim", type=arguments.angle_value, default=-58.0, help="view azimuth, degrees"
    )
    p.add_argument("--no-mesh", action="store_true", help="do not draw the model's mesh")
    arguments.add_mesh_option(p)
    arguments.add_region_options(p)
    p.add_argument("--ids", action="store_true", help="write each element's id beside it")
    p.add_argument(
        "--up", choices=["x", "y", "z"], help="model axis drawn upwards (default: the model's)"
    )
    add_loads_option(
        p,
        help="load cases drawn as arrows at their points (pictures only; with "
        "--contacts, each case's certified load factor in the legend)",
    )
    p.set_defaults(run=cmd_show)


def _entries(path: str) -> list:
    """The contact entries of a contact-set file (or of a plan's report.json), as written."""
    from closure_nlp.base.files import load_json

    data = load_json(path)
    if isinstance(data, dict) and isinstance(data.get("contact_set"), dict):
        data = data["contact_set"]  # a plan's report.json
    entries = data.get("contacts", []) if isinstance(data, dict) else []
    return [e for e in entries if isinstance(e, dict)]


def contact_elements(path: str) -> list[int]:
    """The ``element`` ids named by the contacts of a contact-set file (for highlighting)."""
    ids = [e.get("element") for e in _entries(path)]
    return [i for i in ids if isinstance(i, int) and not isinstance(i, bool)]


def fixed_count(path: str) -> int:
    """How many contacts at the start of a contact-set file were already in place."""
    count = 0
    for entry in _entries(path):
        if entry.get("fixed") is not True:
            break
        count += 1
    return count


def show_title(model, contacts) -> str | None:
    """``name: N contacts, rho = ... (verdict)`` when contacts are drawn (their certified rho,
    as ``closure-nlp rho`` gives it); None: the model's name and counts."""
    if contacts is None or not contacts.contacts:
        return None
    result = rho(contacts)
    return (
        f"{model.name}: {len(contacts.contacts)} contacts, rho = "
        f"{certain(result.rho, result.bounds)} "
        f"({output.verdict_text(result, result.force_closure)})"
    )


def cmd_show(args) -> None:
    from pathlib import Path

    from closure_nlp.report.drawing import PICTURE_SUFFIXES, SCENE_SUFFIXES, save_view

    with output.reading(args.out):
        check_output_file(args.out)
    marked: list[int] = []
    model = read_model(args, marked)
    with output.reading(args.model):  # excluded elements drawn grey
        model = with_exclusions(model, args.only, args.exclude)
    contacts, highlight, fixed = None, [], 0
    if args.contacts:
        [(_, contacts)] = output.load_each([args.contacts], load_contacts)
        highlight = contact_elements(args.contacts)
        fixed = fixed_count(args.contacts)
    if args.highlight:
        try:
            highlight = [arguments.int_value(part) for part in args.highlight.split(",")]
        except ValueError:
            message = f"expected element ids I,J,..., got {args.highlight!r}"
            raise output.InputError("--highlight", message) from None
    try:
        for k, i in enumerate(highlight):
            model.check_id(i, f"contacts[{k}].element" if not args.highlight else "--highlight")
    except (ValueError, TypeError) as exc:
        raise output.InputError(
            args.contacts if not args.highlight else "--highlight", str(exc)
        ) from None
    suffix = Path(args.out).suffix.lower()
    loads = read_loads(args)
    if loads is not None and suffix in SCENE_SUFFIXES:
        raise output.InputError(
            "--loads", f"load arrows are drawn in pictures, not {suffix} scenes"
        )
    if suffix not in PICTURE_SUFFIXES | SCENE_SUFFIXES:
        raise output.InputError(
            "--out",
            f"unsupported file type {suffix or args.out!r} "
            "(use .png, .svg, .pdf, .jpg, .glb or .html)",
        )
    options = {"up": args.up, "title": show_title(model, contacts)}
    if suffix not in SCENE_SUFFIXES:
        options.update(
            view=(args.elev, args.azim), show_mesh=not args.no_mesh, ids=args.ids, fixed=fixed
        )
    if loads is not None:
        from closure_nlp.criterion.load_factor import load_factors

        options["loads"] = loads
        if contacts is not None and contacts.contacts:
            options["load_factors"] = load_factors(contacts, loads)
    try:
        out = save_view(model, args.out, contacts, highlight=highlight, marked=marked, **options)
    except OSError as exc:
        raise output.OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
    point = ", ".join(f"{x:.6g}" for x in model.reference_point)
    output.emit(
        args,
        {
            "file": args.model,
            "out": str(out),
            "units": model.units,
            "reference_point": model.reference_point.tolist(),
            "marked": marked,
        },
        f"{output.shown(args.model)}: drawn to {output.shown(out)} (torques about [{point}]"
        + (f" {model.units}" if model.units else "")
        + ", marked x)",
    )
