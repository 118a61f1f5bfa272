"""``closure-nlp rho FILE...``: certified rho of contact-set files."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

from closure_nlp.base.formatting import certain
from closure_nlp.cli import arguments, output
from closure_nlp.cli.loads_option import add_loads_option, loads_answer, read_loads
from closure_nlp.criterion.support_minimum import TOL_RANGE, rho
from closure_nlp.report.plan_report import load_contacts

# --tol: a certified bracket's relative width (rho's ``tol``)
_TOL = arguments.bounded(
    arguments.float_value, "a number", lambda v: TOL_RANGE[0] <= v <= TOL_RANGE[1],
    "[{:g}, {:g}]".format(*TOL_RANGE), "the bracket's relative width",
)  # fmt: skip


def add_rho(sub, common) -> None:
    p = sub.add_parser("rho", parents=[common], help="rho(0, W_c^M) of contact-set files")
    p.add_argument(
        "files", nargs="+", metavar="FILE", help="*.contacts.json (or a plan's report.json)"
    )
    p.add_argument(
        "--certify",
        action="store_true",
        help="accepted for compatibility: certified bounds lo <= rho <= hi are always given",
    )
    p.add_argument(
        "--workers",
        type=arguments.bounded_int(1, arguments.MAX_WORKERS, "the number of workers"),
        default=1,
        metavar="K",
        help="files certified at once, in threads (default 1; one file's long certificate "
        "runs in two of them); the answers and their order do not depend on it",
    )
    p.add_argument(
        "--tol",
        type=_TOL,
        metavar="T",
        help="certify every bracket to T of max(|rho|, the set's scale) (default 1e-6); a wider "
        "one costs less on sets in force closure, and the verdicts take the same accuracy",
    )
    add_loads_option(p)
    p.set_defaults(run=cmd_rho)


def cmd_rho(args) -> None:
    loaded = output.load_each(args.files, load_contacts)
    args.loads = read_loads(args)  # before any work
    if args.workers == 1 or len(loaded) == 1:
        answers = (_answer(args, path, contact_set, args.workers) for path, contact_set in loaded)
        for payload, text in answers:
            output.emit(args, payload, text)
        return
    with ThreadPoolExecutor(min(args.workers, len(loaded))) as pool:
        for payload, text in pool.map(lambda item: _answer(args, *item), loaded):
            output.emit(args, payload, text)


def _answer(args, path, contact_set, workers: int = 1) -> tuple[dict, str]:
    """One file's JSON answer and its line of text."""
    t0 = time.perf_counter()
    tolerance = arguments.model_tolerance(args, contact_set.tolerance)
    result = rho(contact_set, tolerance=tolerance, tol=args.tol, workers=workers)
    payload = {"file": path, **result.to_dict()}
    loads, loads_text = loads_answer(contact_set, args.loads)
    payload.update(loads, **output.whole_cost(result, t0))
    direction = " ".join(f"{x:+.4f}" for x in result.direction)
    text = (
        f"{output.shown(path)}: rho = {certain(result.rho, result.bounds)} "
        f"({output.verdict_text(result, result.force_closure)}); "
        f"weakest direction u* = [{direction}]" + output.bounds_text(result, "rho") + loads_text
    )
    return payload, text
