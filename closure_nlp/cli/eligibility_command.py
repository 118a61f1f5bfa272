"""``closure-nlp eligibility MODEL --elements ...``: rho_hat of an element set."""

from __future__ import annotations

import time

from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output
from closure_nlp.cli.loads_option import (
    add_loads_option,
    element_factors,
    factors_answer,
    read_loads,
)
from closure_nlp.cli.setup import intent_keys, model_eligibility


def add_eligibility(sub, common) -> None:
    p = arguments.model_parser(
        sub, common, "eligibility", "rho(0, What_c^M) of element sets", "elements"
    )
    arguments.add_fixed_option(p)
    arguments.add_contact_options(p)
    add_loads_option(
        p,
        help="load cases: the certified load factors of the element set's wrench set (no "
        "placement on these elements holds more)",
    )
    p.set_defaults(run=cmd_eligibility)


def cmd_eligibility(args) -> None:
    ids = arguments.id_list(args.elements, "--elements")
    loads = read_loads(args)
    eligibility = model_eligibility(args, len(ids), "--elements")
    with output.reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
    t0 = time.perf_counter()
    result = eligibility(ids)
    factors, factors_text = factors_answer(element_factors(eligibility, ids, loads))
    verdict = output.verdict_text(result, result.eligible, "eligible", "not eligible")
    output.emit(
        args,
        {
            **result.to_dict(),
            **output.whole_cost(result, t0),
            **intent_keys(args, eligibility),
            **factors,
        },
        f"{output.shown(args.model)}: elements {output.joined_ids(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        + output.bounds_text(result, "rho_hat")
        + factors_text,
    )
