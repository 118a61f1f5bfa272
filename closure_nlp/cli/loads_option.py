"""``--loads LOADS.json`` and ``--objective``: the load cases a part must hold, their certified
factors in a command's answer, and what placement maximises."""

from __future__ import annotations

from closure_nlp.cli import output


def add_loads_option(parser, objective: bool = False, help: str | None = None) -> None:
    parser.add_argument(
        "--loads",
        metavar="LOADS.json",
        help=help
        or "load cases the contacts must hold: their certified load factors are reported "
        "(f_max is then in the loads' force unit)",
    )
    if objective:
        parser.add_argument(
            "--objective",
            choices=["loads", "rho"],
            help="what placement maximises: the least load factor (default with --loads) or rho",
        )


def read_loads(args):
    """The validated :class:`~closure_nlp.contact.loads.Loads` of ``--loads`` (``None``
    without it), and ``args.objective`` resolved; bad input is an :class:`output.InputError`."""
    from closure_nlp.contact.loads import load_loads

    path = getattr(args, "loads", None)
    if getattr(args, "objective", None) is None and hasattr(args, "objective"):
        args.objective = "loads" if path else "rho"
    if getattr(args, "objective", None) == "loads" and not path:
        raise output.InputError("--objective", "loads needs --loads LOADS.json")
    if not path:
        return None
    return output.load_each([path], load_loads)[0][1]


def loads_answer(contact_set, loads, objective: str | None = None) -> tuple[dict, str]:
    """The JSON keys (``loads``, ``load_factor``, and ``objective`` when given) and the text line
    of the factors of ``loads`` on ``contact_set``; nothing without loads."""
    if loads is None:
        return {}, ""
    from closure_nlp.criterion.load_factor import load_factors

    return factors_answer(load_factors(contact_set, loads), objective)


def factors_answer(factors, objective: str | None = None) -> tuple[dict, str]:
    """:func:`loads_answer` of factors already computed
    (:class:`~closure_nlp.criterion.load_factor.LoadFactors`; nothing for ``None``)."""
    if factors is None:
        return {}, ""
    keys = factors.to_dict() | ({"objective": objective} if objective else {})
    return keys, "\n" + factors.text() + (f" (objective: {objective})" if objective else "")


def element_factors(eligibility, elements, loads):
    """The certified factors of ``loads`` on the wrench set of the element set ``elements``:
    an upper bound on any placement's factors on those elements (``None`` without loads)."""
    if loads is None:
        return None
    from closure_nlp.placement.load_objective import LoadObjective

    return LoadObjective.of(eligibility, loads)(eligibility.slots(elements)).factors
