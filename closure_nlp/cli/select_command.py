"""``closure-nlp select MODEL --contacts M``: eligible element selection."""

from __future__ import annotations

from closure_nlp.base.errors import MethodError
from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output, setup
from closure_nlp.cli.loads_option import (
    add_loads_option,
    element_factors,
    factors_answer,
    read_loads,
)
from closure_nlp.criterion.rho_hat import element_set_keys
from closure_nlp.selection.algorithms import run_selection


def load_history(result, value) -> list[dict]:
    """A selection's history by loads: the least load factor after every step."""
    return [{"iteration": k, "load_factor": value.factor(v)} for k, v in result.history]


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
    add_loads_option(
        p,
        objective=True,
        help="load cases: the certified load factors of the selected element set's wrench set "
        "(no placement on these elements holds more)",
    )
    p.set_defaults(run=cmd_select)


def cmd_select(args) -> None:
    loads = read_loads(args)
    eligibility = setup.model_eligibility(args, args.contacts, closure=True)
    with output.reading(args.model):
        start = arguments.id_list(args.start, "--start") if args.start else None
        if start is not None:
            eligibility.check_elements(start, "--start", partial=True)
    value = None
    if args.objective == "loads":
        from closure_nlp.placement.load_objective import LoadObjective
        from closure_nlp.selection.load_value import LoadValue

        value = LoadValue(eligibility, LoadObjective.of(eligibility, loads))
    progress, close = output.progress_bar(args)
    try:
        result = run_selection(
            eligibility, args.algorithm, start=start, seed=args.seed, progress=progress, value=value
        )
        payload = {"algorithm": args.algorithm, **result.to_dict()}
        shown = result
        if value is not None:  # the chosen set's own rho_hat; the history in load factors
            shown = eligibility(result.elements)
            payload.update(element_set_keys(shown), history=load_history(result, value))
    finally:
        close()
    factors, factors_text = factors_answer(
        element_factors(eligibility, result.elements, loads), args.objective if loads else None
    )
    verdict = output.verdict_text(shown, shown.eligible, "eligible", "not eligible")
    output.emit(
        args,
        {**payload, **factors, **setup.intent_keys(args, eligibility)},
        f"{output.shown(args.model)}: {args.algorithm}: "
        f"elements {output.joined_ids(result.elements)}: "
        f"rho_hat = {certain(shown.rho_hat, shown.bounds)} ({verdict})"
        f"{output.bounds_text(shown, 'rho_hat')}; "
        f"{result.evaluations} evaluations in {result.seconds:.2f} s{factors_text}",
    )
    if value is not None and not result.eligible:
        raise MethodError(
            f"{args.model}: no element set found that holds every load case "
            f"(best least load factor {value.factor(result.rho_hat):.6g})"
        )
    if value is None and not result.eligible:
        raise MethodError(
            f"{args.model}: no eligible element set found (best rho_hat = {result.rho_hat:.6g})"
        )
