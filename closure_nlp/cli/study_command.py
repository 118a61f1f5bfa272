"""``closure-nlp study FILE --out DIR``: a study of many plans, on Dask."""

from __future__ import annotations

import sys

from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    check_output_dir,
)
from closure_nlp.cli import arguments, output


def add_study(sub, common) -> None:
    p = sub.add_parser(
        "study", parents=[common], help="a grid of plans (models x contacts x seeds) on Dask"
    )
    p.add_argument("study", metavar="STUDY", help="study file (TOML)")
    p.add_argument(
        "--out", required=True, metavar="DIR", help="results/, summary.md/.csv, results.csv, plots"
    )
    p.add_argument(
        "--scheduler",
        type=arguments.scheduler_address,
        metavar="ADDRESS",
        help="join this Dask scheduler (tcp://HOST:PORT)",
    )
    p.add_argument(
        "--workers",
        type=arguments.bounded_int(1, arguments.MAX_WORKERS, "the number of local workers"),
        metavar="N",
        help="local workers (default: cores)",
    )
    p.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    p.add_argument(
        "--limit",
        type=arguments.study_count(0),
        metavar="N",
        help="run at most N tasks now (then resume)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run failed tasks again")
    p.set_defaults(run=cmd_study)


def cmd_study(args) -> None:
    from closure_nlp.study import load_study, run_study

    try:
        study = load_study(args.study)
    except (ValueError, TypeError) as exc:
        raise output.InputError(args.study, str(exc)) from None
    with output.reading(args.out):
        check_output_dir(args.out, marker=None)  # results are added to it (resume)
    bar = None

    def progress(done: int, total: int, row) -> None:
        nonlocal bar
        if bar is None:
            from tqdm import tqdm

            bar = tqdm(total=total, unit="task", file=sys.stderr, leave=False, desc=study.name)
        if row is not None:
            bar.set_postfix_str(f"{row['model']} {row['type']}x{row['contacts']}", refresh=False)
            bar.update(1)

    quiet = args.quiet or not sys.stderr.isatty()
    try:
        result = run_study(
            study,
            args.out,
            scheduler=args.scheduler,
            workers=args.workers,
            serial=args.serial,
            limit=args.limit,
            retry_failed=args.retry_failed,
            progress=None if quiet else progress,
        )
    finally:
        if bar is not None:
            bar.close()
    payload = {"file": args.study, **result.to_dict()}
    text = (
        f"{output.shown(args.study)}: {result.total} tasks: {result.run} run "
        f"({result.failed} failed), "
        f"{result.skipped} done before, {result.remaining} remaining; {result.seconds:.1f} s on "
        f"{result.workers} worker(s), {result.tasks_per_second:.3f} tasks/s\n"
        f"summary in {output.shown(result.paths['summary.md'])}"
    )
    output.emit(args, payload, text)
    if result.failed:
        raise MethodError(
            f"{args.study}: {result.failed} of {result.run} tasks failed "
            f"(errors in {result.paths['summary.md']})"
        )
