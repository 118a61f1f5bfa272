"""``closure-nlp eligibility MODEL --elements ...``: rho_hat of an element set."""

from __future__ import annotations

import time

from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output
from closure_nlp.cli.setup import intent_keys, model_eligibility


def add_eligibility(sub, common) -> None:
    p = arguments.model_parser(
        sub, common, "eligibility", "rho(0, What_c^M) of element sets", "elements"
    )
    arguments.add_fixed_option(p)
    arguments.add_contact_options(p)
    p.set_defaults(run=cmd_eligibility)


def cmd_eligibility(args) -> None:
    ids = arguments.id_list(args.elements, "--elements")
    eligibility = model_eligibility(args, len(ids), "--elements")
    with output.reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
    t0 = time.perf_counter()
    result = eligibility(ids)
    verdict = output.verdict_text(result, result.eligible, "eligible", "not eligible")
    output.emit(
        args,
        {**result.to_dict(), **output.whole_cost(result, t0), **intent_keys(args, eligibility)},
        f"{output.shown(args.model)}: elements {output.joined_ids(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        + output.bounds_text(result, "rho_hat"),
    )
