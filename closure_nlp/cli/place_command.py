"""``closure-nlp place MODEL --elements ...``: contact placement with its certified ceiling."""

from __future__ import annotations

from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    check_output_file,
    write_json,
)
from closure_nlp.cli import arguments, output, setup
from closure_nlp.cli.loads_option import add_loads_option, loads_answer, read_loads
from closure_nlp.contact.count import require_closure_count
from closure_nlp.placement.place import Placer


def add_place(sub, common) -> None:
    p = arguments.model_parser(
        sub, common, "place", "optimal contacts on given elements", "elements"
    )
    arguments.add_placement_options(p)
    p.add_argument(
        "--seed", type=arguments.seed_value, default=0, help="random start weights after the first"
    )
    p.add_argument("--out", metavar="FILE", help="write the placed contacts as a contact-set file")
    arguments.add_placing_options(p)
    add_loads_option(p, objective=True)
    p.set_defaults(run=cmd_place)


def cmd_place(args) -> None:
    from closure_nlp.placement.margin import on_original

    ids = arguments.id_list(args.elements, "--elements")
    eligibility = setup.model_eligibility(args, len(ids), "--elements")
    original = eligibility.model
    intent = setup.intent_keys(args, eligibility)
    loads = read_loads(args)
    with output.reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
        require_closure_count(eligibility.all_specs, "--elements")
        eligibility = setup.with_margin(args, eligibility, ids)
    options, progress, close = setup.placement_setup(args, True, check_output_file)
    try:
        steer = loads if args.objective == "loads" else None
        result = Placer(eligibility, options, loads=steer)(ids, progress=progress)
    finally:
        close()
    if args.margin:
        result = on_original(result, original)
    placed = setup.placement_text(result, original)
    payload, text = result.to_dict(), f"{output.shown(args.model)}: {placed}"
    payload["margin"] = args.margin
    payload.update(intent)
    text += setup.margin_text(args, eligibility.model)
    factors, factors_text = loads_answer(result.contact_set, loads, args.objective)
    payload.update(factors)
    text += factors_text
    if args.out:
        output.check_finite(payload, args.model)  # before anything is written
        model = eligibility.model
        try:
            write_json(
                args.out, {**result.contact_file(model.name, model.units), "margin": args.margin}
            )
        except OSError as exc:
            raise output.OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
        payload["out"] = {"contacts": str(args.out)}
        text += f"\ncontacts in {output.shown(args.out)}"
    output.emit(args, payload, text)
    if not result.force_closure:
        raise MethodError(
            f"{args.model}: the placed contacts are not force closure (rho = {result.rho:.6g})"
        )
    if result.robust is False:
        raise MethodError(
            f"{args.model}: the placed contacts are not robust within the model's tolerance "
            f"(support shift {result.shift:.3g} against -hi = {-result.bounds[1]:.3g}); "
            + result.to_be_robust_text(eligibility.model.units)
        )
