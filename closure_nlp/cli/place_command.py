"""``closure-nlp place MODEL --elements ...``: contact placement with its certified ceiling."""

from __future__ import annotations

from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    check_output_file,
    write_json,
)
from closure_nlp.cli.arguments import (
    add_bound_options,
    add_contact_options,
    add_margin_option,
    add_placement_options,
    id_list,
    seed_value,
)
from closure_nlp.cli.output import OutputFault, check_finite, emit, reading, shown
from closure_nlp.cli.setup import (
    margin_text,
    model_eligibility,
    placement_setup,
    placement_text,
    with_margin,
)
from closure_nlp.contact.count import require_closure_count
from closure_nlp.placement.place import Placer


def add_place(sub, common) -> None:
    p = sub.add_parser("place", parents=[common], help="optimal contacts on given elements")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--elements", required=True, help="element ids, one per contact: I,J,...")
    add_placement_options(p)
    p.add_argument(
        "--seed", type=seed_value, default=0, help="random start weights after the first"
    )
    p.add_argument("--out", metavar="FILE", help="write the placed contacts as a contact-set file")
    add_margin_option(p)
    add_bound_options(p)
    add_contact_options(p)
    p.set_defaults(run=cmd_place)


def cmd_place(args) -> None:
    from closure_nlp.placement.margin import on_original

    ids = id_list(args.elements, "--elements")
    eligibility = model_eligibility(args, len(ids), "--elements")
    original = eligibility.model
    with reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
        require_closure_count(eligibility.specs, "--elements")
        eligibility = with_margin(args, eligibility, ids)
    options, progress, close = placement_setup(args, True, check_output_file)
    try:
        result = Placer(eligibility, options)(ids, progress=progress)
    finally:
        close()
    if args.margin:
        result = on_original(result, original)
    placed = placement_text(result, original)
    payload, text = result.to_dict(), f"{shown(args.model)}: {placed}"
    payload["margin"] = args.margin
    text += margin_text(args, eligibility.model)
    if args.out:
        check_finite(payload, args.model)  # before anything is written
        model = eligibility.model
        try:
            write_json(
                args.out, {**result.contact_file(model.name, model.units), "margin": args.margin}
            )
        except OSError as exc:
            raise OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
        payload["out"] = {"contacts": str(args.out)}
        text += f"\ncontacts in {shown(args.out)}"
    emit(args, payload, text)
    if not result.force_closure:
        raise MethodError(
            f"{args.model}: the placed contacts are not force closure (rho = {result.rho:.6g})"
        )
    if result.robust is False:
        raise MethodError(
            f"{args.model}: the placed contacts are not robust within the model's tolerance "
            f"(support shift {result.shift:.3g} against -hi = {-result.bounds[1]:.3g})"
        )
