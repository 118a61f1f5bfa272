"""``closure-nlp plan MODEL --contacts M``: the whole method and its report."""

from __future__ import annotations

import dataclasses
import os

from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    check_output_dir,
    staged_folder,
)
from closure_nlp.base.formatting import certain
from closure_nlp.base.validation import (
    MAX_SEED,
)
from closure_nlp.cli import arguments, output, setup
from closure_nlp.cli.loads_option import add_loads_option, factors_answer, read_loads
from closure_nlp.placement.ceiling import BoundOptions, part_ceiling, part_text
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
from closure_nlp.planning.seeds import DEFAULT_BUDGET, DEFAULT_SEEDS, MAX_PLAN_SEEDS
from closure_nlp.report.plan_report import write_report


def add_plan(sub, common) -> None:
    p = arguments.model_parser(
        sub, common, "plan", "heuristic, iterative and placement", "contacts"
    )
    p.add_argument(
        "--seed",
        type=arguments.seed_value,
        default=0,
        help="random start of the heuristic (the first seed)",
    )
    p.add_argument(
        "--seeds",
        type=arguments.bounded_int(1, MAX_PLAN_SEEDS, "the number of seeds"),
        default=DEFAULT_SEEDS,
        metavar="N",
        help=f"plans from seeds S..S+N-1, the best returned (default {DEFAULT_SEEDS})",
    )
    p.add_argument(
        "--budget",
        type=arguments.budget_value,
        default=DEFAULT_BUDGET,
        metavar="SECONDS",
        help=f"no further seed starts after this (default {DEFAULT_BUDGET:g})",
    )
    p.add_argument(
        "--workers",
        type=arguments.bounded_int(1, arguments.MAX_WORKERS, "the number of worker processes"),
        metavar="K",
        help="processes the seeds run on (default: one per core)",
    )
    arguments.add_placement_options(p)
    p.add_argument(
        "--alternatives",
        type=arguments.bounded_int(0, arguments.MAX_ALTERNATIVES, "the number of alternatives"),
        default=4,
        metavar="N",
        help="further element sets placed when placement fails (default 4)",
    )
    p.add_argument(
        "--part-ceiling",
        action="store_true",
        help="also the certified ceiling on any placement of the contacts anywhere on the part "
        "(every element set), with the plan's gap to it; --bound-cells cells",
    )
    p.add_argument(
        "--out", metavar="DIR", help="write report.json, contacts.json, pictures and summary.md"
    )
    p.add_argument(
        "--up", choices=["x", "y", "z"], help="model axis drawn upwards (default: the model's)"
    )
    arguments.add_placing_options(p)
    add_loads_option(p, objective=True)
    p.set_defaults(run=cmd_plan)


def cmd_plan(args) -> None:
    from closure_nlp.placement.margin import on_original

    eligibility = setup.model_eligibility(args, args.contacts, closure=True)
    original = eligibility.model
    intent = setup.intent_keys(args, eligibility)
    loads = read_loads(args)
    with output.reading(args.model):
        eligibility = setup.with_margin(args, eligibility)
    placement_options, progress, close = setup.placement_setup(args, False, check_output_dir)
    try:
        if args.seed + args.seeds - 1 > MAX_SEED:
            raise output.InputError(
                "--seeds", f"seeds {args.seed}..{args.seed + args.seeds - 1} pass {MAX_SEED}"
            )
        # the loads steer the placements afterwards: every seed's is a start for them
        several = {"workers": args.workers, "budget": args.budget}
        several["stop_seeds"] = args.objective != "loads"
        result = plan(
            eligibility,
            seed=args.seed,
            seeds=args.seeds,
            placement=placement_options,
            progress=progress,
            alternatives=args.alternatives,
            **(several if args.seeds > 1 else {}),
        )
        if args.objective == "loads":
            from closure_nlp.planning.load_steering import steer_by_loads

            result = steer_by_loads(
                eligibility, result, loads, placement_options, progress, seed=args.seed
            )
    finally:
        close()
    part = None
    if args.part_ceiling:
        part = _part_ceiling(eligibility, placement_options, result)
    if args.margin:  # contacts' weights on the file's elements: the same positions
        result = dataclasses.replace(result, placement=on_original(result.placement, original))
    payload = result.to_dict()
    if part is not None:
        payload["part_ceiling"] = {
            "capacity_bound": part.value,
            "gap": part.gap,
            "cells": part.nodes,
            "root_bound": part.root_value,
            "seconds": part.seconds,
        }
    payload["margin"] = args.margin
    payload.update(intent)
    factors = None
    if loads is not None:
        from closure_nlp.criterion.load_factor import load_factors

        factors = load_factors(result.placement.contact_set, loads)
    factors_keys, factors_text = factors_answer(factors, args.objective)
    payload.update(factors_keys)
    output.check_finite(payload, args.model)  # before anything is written
    if args.out:
        options = {
            "contacts": args.contacts,
            "seed": args.seed,
            "seeds": args.seeds,
            "budget": args.budget,
            "type": args.type,
            "mu": args.mu,
            "f_max": args.f_max,
            **args.scale.to_dict(),  # mu_s, torque scale, reference point: the values used
            "placement": vars(placement_options),
            "alternatives": args.alternatives,
            "up": args.up or eligibility.model.up,
            "margin": args.margin,
            **({} if loads is None else {"loads": loads.to_dict(), "objective": args.objective}),
        }
        with staged_folder(args.out) as staged:  # all files of this run, or none
            written = write_report(
                original, result, staged, options, loads=loads, load_factors=factors
            )
        payload["out"] = {name: os.path.join(args.out, name) for name in written}
    h, it = result.heuristic, result.iterative
    text = (
        f"{output.shown(args.model)}: heuristic {output.joined_ids(h.elements)} "
        f"rho_hat = {certain(h.rho_hat, h.bounds)} "
        f"({h.seconds:.2f} s); iterative {output.joined_ids(it.elements)} "
        f"rho_hat = {certain(it.rho_hat, it.bounds)} "
        f"({it.seconds:.2f} s)\n"
        + "".join(
            f"placement on {output.joined_ids(a.elements)} ({a.source}): rho = {a.rho:.6g}"
            f"{' (force closure)' if a.force_closure else ''} ({a.seconds:.2f} s)\n"
            for a in result.attempts[1:]
        )
        + f"{setup.placement_text(result.placement, original)}"
        + f"{setup.margin_text(args, eligibility.model)}{factors_text}\n"
        + ("" if result.seeds is None else result.seeds.line() + "\n")
        + ("" if part is None else f"{part_text(part, eligibility.m)}\n")
        + f"total {result.seconds:.2f} s"
        + _compile_text(args)
        + (f"; report in {output.shown(args.out)}" if args.out else "")
    )
    output.emit(args, payload, text)
    if not result.force_closure:
        raise MethodError(f"{args.model}: {result.failure()}")
    if result.placement.robust is False:
        raise MethodError(
            f"{args.model}: no robust placement found: the placed contacts are force closure by "
            f"the file but not within the model's tolerance (support shift "
            f"{result.placement.shift:.3g} against -hi = {-result.placement.bounds[1]:.3g}); "
            + result.placement.to_be_robust_text(eligibility.model.units)
        )


def _part_ceiling(eligibility, options, result):
    """The certified ceiling over every placement on the part, the plan's placement its
    incumbent; ``--bound-cells`` cells (and ``--time-budget`` seconds) at most."""
    budget = float("inf") if options.time_budget is None else float(options.time_budget)
    bound = BoundOptions(gap=options.target_gap, time_budget=budget, max_nodes=options.bound_cells)
    return part_ceiling(Placer(eligibility, options), result.placement, bound)


def _compile_text(args) -> str:
    """The first run's compile of the kernels, which the plan's own total leaves out."""
    seconds = getattr(args, "compile_seconds", None)
    return "" if seconds is None else f" (and {seconds:.1f} s compiling the kernels, once)"
