"""``closure-nlp eligibility MODEL --elements ...``: rho_hat of an element set."""

from __future__ import annotations

import time

from closure_nlp.base.formatting import certain
from closure_nlp.cli.arguments import add_contact_options, id_list
from closure_nlp.cli.output import (
    bounds_text,
    emit,
    joined_ids,
    reading,
    shown,
    verdict_text,
    whole_cost,
)
from closure_nlp.cli.setup import model_eligibility


def add_eligibility(sub, common) -> None:
    p = sub.add_parser("eligibility", parents=[common], help="rho(0, What_c^M) of element sets")
    p.add_argument("model", metavar="MODEL", help="*.model.json")
    p.add_argument("--elements", required=True, help="element ids, one per contact: I,J,...")
    add_contact_options(p)
    p.set_defaults(run=cmd_eligibility)


def cmd_eligibility(args) -> None:
    ids = id_list(args.elements, "--elements")
    eligibility = model_eligibility(args, len(ids), "--elements")
    with reading(args.model):
        ids = eligibility.check_elements(ids, "--elements")
    t0 = time.perf_counter()
    result = eligibility(ids)
    verdict = verdict_text(result, result.eligible, "eligible", "not eligible")
    emit(
        args,
        {**result.to_dict(), **whole_cost(result, t0)},
        f"{shown(args.model)}: elements {joined_ids(result.elements)}: "
        f"rho_hat = {certain(result.rho_hat, result.bounds)} ({verdict})"
        + bounds_text(result, "rho_hat"),
    )
