"""``closure-nlp select MODEL --contacts M``: eligible element selection."""

from __future__ import annotations

from closure_nlp.base.errors import MethodError
from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output, setup
from closure_nlp.selection.algorithms import run_selection


def add_select(sub, common) -> None:
    p = arguments.model_parser(sub, common, "select", "select eligible elements", "contacts")
    p.add_argument("--algorithm", choices=["heuristic", "iterative"], default="heuristic")
    p.add_argument("--start", help="start elements I,J,... (heuristic: its i0 < M start ids)")
    p.add_argument(
        "--seed", type=arguments.seed_value, default=0, help="random start of the heuristic"
    )
    arguments.add_fixed_option(p)
    arguments.add_region_options(p)
    arguments.add_contact_options(p)
    p.set_defaults(run=cmd_select)


def cmd_select(args) -> None:
    eligibility = setup.model_eligibility(args, args.contacts, closure=True)
    with output.reading(args.model):
        start = arguments.id_list(args.start, "--start") if args.start else None
        if start is not None:
            eligibility.check_elements(start, "--start", partial=True)
    progress, close = output.progress_bar(args)
    try:
        result = run_selection(
            eligibility, args.algorithm, start=start, seed=args.seed, progress=progress
        )
    finally:
        close()
    verdict = output.verdict_text(result, result.eligible, "eligible", "not eligible")
    output.emit(
        args,
        {"algorithm": args.algorithm, **result.to_dict(), **setup.intent_keys(args, eligibility)},
        f"{output.shown(args.model)}: {args.algorithm}: "
        f"elements {output.joined_ids(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        f"{output.bounds_text(result, 'rho_hat')}; "
        f"{result.evaluations} evaluations in {result.seconds:.2f} s",
    )
    if not result.eligible:
        raise MethodError(
            f"{args.model}: no eligible element set found (best rho_hat = {result.rho_hat:.6g})"
        )
