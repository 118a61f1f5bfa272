"""``closure-nlp select MODEL --contacts M``: eligible element selection."""

from __future__ import annotations

from closure_nlp.base.errors import MethodError
from closure_nlp.base.formatting import certain
from closure_nlp.cli.arguments import add_contact_options, id_list, int_value, seed_value
from closure_nlp.cli.output import (
    bounds_text,
    emit,
    joined_ids,
    progress_bar,
    reading,
    shown,
    verdict_text,
)
from closure_nlp.cli.setup import model_eligibility
from closure_nlp.selection.algorithms import run_selection


def add_select(sub, common) -> None:
    p = sub.add_parser("select", parents=[common], help="select eligible elements")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument(
        "--contacts", type=int_value, required=True, metavar="M", help="number of contacts"
    )
    p.add_argument("--algorithm", choices=["heuristic", "iterative"], default="heuristic")
    p.add_argument("--start", help="start elements I,J,... (heuristic: its i0 < M start ids)")
    p.add_argument("--seed", type=seed_value, default=0, help="random start of the heuristic")
    add_contact_options(p)
    p.set_defaults(run=cmd_select)


def cmd_select(args) -> None:
    eligibility = model_eligibility(args, args.contacts, closure=True)
    with reading(args.model):
        start = id_list(args.start, "--start") if args.start else None
        if start is not None:
            eligibility.check_elements(start, "--start", partial=True)
    progress, close = progress_bar(args)
    try:
        result = run_selection(
            eligibility, args.algorithm, start=start, seed=args.seed, progress=progress
        )
    finally:
        close()
    verdict = verdict_text(result, result.eligible, "eligible", "not eligible")
    emit(
        args,
        {"algorithm": args.algorithm, **result.to_dict()},
        f"{shown(args.model)}: {args.algorithm}: elements {joined_ids(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        f"{bounds_text(result, 'rho_hat')}; "
        f"{result.evaluations} evaluations in {result.seconds:.2f} s",
    )
    if not result.eligible:
        raise MethodError(
            f"{args.model}: no eligible element set found (best rho_hat = {result.rho_hat:.6g})"
        )
