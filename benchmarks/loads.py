"""Load factors against the independent SOCP: ``python -m benchmarks.loads [--sets N]``; plans
steered by rho and by load factors: ``python -m benchmarks.loads --steering [--seeds N]``;
element sets selected by rho_hat and by load factors: ``python -m benchmarks.loads --selection``.

Per contact type, ``N`` random sets with a load each (half inside the wrench set, half random
wrenches): the certified factor's agreement with cvxpy's SOCP on the forces, the bracket's
relative width and the milliseconds per factor of both. Prints JSON.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from benchmarks.bench import write_report
from closure_nlp.contact.random_sets import random_contact_set, random_load
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.crosscheck import load_factor_cvxpy
from closure_nlp.criterion.load_factor import load_factor

TYPES = ["fpc", "pcwf", "sfcl", "sfce"]


def bench_loads(sets: int = 50, seed: int = 0) -> dict:
    families = {}
    for kind in [*TYPES, "mixed"]:
        rng = np.random.default_rng(seed)
        rows = []
        for j in range(sets):
            m = {"fpc": 7, "mixed": 5}.get(kind, 4)
            types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
            cs = random_contact_set(rng, types, mu=0.5, mu_s=0.3, tilt=0.25)
            load = random_load(rng, cs, inside=j % 2 == 0)
            t0 = time.perf_counter()
            ours = load_factor(cs, load)
            t1 = time.perf_counter()
            socp, _ = load_factor_cvxpy(cs, load)
            t2 = time.perf_counter()
            lo, hi = ours.bounds
            natural = max(WrenchSlots.from_contacts(cs).row_scales()) / np.linalg.norm(load)
            inside = lo - 1e-7 * max(socp, natural) <= socp <= hi + 1e-7 * max(socp, natural)
            rows.append((ours, socp, inside, 1e3 * (t1 - t0), 1e3 * (t2 - t1)))
        held = [(o, s) for o, s, *_ in rows if not o.marginal]
        families[kind] = {
            "sets": sets,
            "held": len(held),
            "marginal": sets - len(held),
            "converged": int(sum(o.converged for o, *_ in rows)),
            "bracket_contains_socp": int(sum(bool(r[2]) for r in rows)),
            "max_relative_difference": float(
                max((abs(o.load_factor - s) / s for o, s in held), default=0)
            ),
            "max_bracket_width": float(
                max(((o.bounds[1] - o.bounds[0]) / o.bounds[1] for o, _ in held), default=0)
            ),
            "ours_ms": {
                "median": float(np.median([r[3] for r in rows])),
                "max": float(max(r[3] for r in rows)),
            },
            "socp_ms": {"median": float(np.median([r[4] for r in rows]))},
            "iterations_max": max(o.iterations for o, *_ in rows),
        }
    return {"benchmark": "loads", "families": families}


def main(argv=None) -> int:
    load_before = os.getloadavg()
    parser = argparse.ArgumentParser(prog="python -m benchmarks.loads", description=__doc__)
    parser.add_argument("--sets", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--steering", action="store_true", help="plans steered by rho and by loads instead"
    )
    parser.add_argument(
        "--selection", action="store_true", help="selection by rho_hat and by loads instead"
    )
    parser.add_argument(
        "--seeds", type=int, default=4, help="seeds of each plan (--steering, --selection)"
    )
    args = parser.parse_args(argv)
    from closure_nlp.criterion.warm_up import warm_up

    warm_up()
    load_factor(random_contact_set(np.random.default_rng(0), ["pcwf"] * 4), np.ones(6))
    if args.steering:
        write_report(bench_steering(seeds=args.seeds), load_before)
    elif args.selection:
        write_report(bench_selection(seeds=args.seeds), load_before)
    else:
        write_report(bench_loads(args.sets, args.seed), load_before)
    return 0


# Load cases of the steering comparison, in each model's frame (mm, N).
STEERING_LOADS = {
    "lamp": {
        "loads": [
            {"name": "gravity", "force": [0, 0, -1], "point": [0, 0, -20]},
            {"name": "push_x", "force": [0.5, 0, 0], "point": [0, 0, 10]},
            {"name": "twist", "force": [0, 0, 0], "torque": [0, 0, 5]},
        ]
    },
    "cup": {
        "loads": [
            {"name": "gravity", "force": [0, 0, -1], "point": [0, 0, 40]},
            {"name": "tilt", "force": [0.4, 0, 0], "point": [0, 0, 100]},
            {"name": "stir", "force": [0, 0, 0], "torque": [0, 0, 4]},
        ]
    },
}


def bench_steering(names=("lamp", "cup"), seeds: int = 4) -> dict:
    """Each example's plan over ``seeds`` seeds, steered by rho, then the same plan re-placed by
    the least load factor (:func:`closure_nlp.planning.load_steering.steer_by_loads`): both
    placements' least load factor and rho, and the steering's seconds."""
    from benchmarks.bench import PAPER_EXAMPLES, paper_eligibility
    from closure_nlp.criterion.load_factor import load_factors
    from closure_nlp.planning.load_steering import steer_by_loads
    from closure_nlp.planning.plan import plan

    out = {}
    for name in names:
        eligibility = paper_eligibility(name)
        loads = STEERING_LOADS[name]
        t0 = time.perf_counter()
        by_rho = plan(eligibility, seed=0, seeds=seeds, workers=1)
        t1 = time.perf_counter()
        by_loads = steer_by_loads(eligibility, by_rho, loads)
        t2 = time.perf_counter()
        rows = {}
        for label, result in (("rho", by_rho), ("loads", by_loads)):
            factors = load_factors(result.placement.contact_set, loads)
            rows[label] = {
                "load_factor": factors.load_factor,
                "cases": {n: f.load_factor for n, f in zip(factors.names, factors.factors)},
                "rho": result.placement.rho,
                "elements": list(result.placement.elements),
            }
        out[name] = {
            "type": PAPER_EXAMPLES[name]["type"],
            "seeds": seeds,
            "by_rho": rows["rho"],
            "by_loads": rows["loads"],
            "ratio": rows["loads"]["load_factor"] / rows["rho"]["load_factor"],
            "plan_seconds": t1 - t0,
            "steering_seconds": t2 - t1,
        }
    return {"benchmark": "load_steering", "models": out}


def bench_selection(names=("lamp", "cup"), seeds: int = 4) -> dict:
    """Per example and seed, the iterative selection by rho_hat and by the least load factor
    (:class:`closure_nlp.selection.load_value.LoadValue`): each chosen element set's least
    certified factor, evaluations and seconds; then contacts placed on it by the load factors,
    whose least factor never passes the element set's upper bound (``bound_kept``)."""
    from benchmarks.bench import PAPER_EXAMPLES, paper_eligibility
    from closure_nlp.criterion.load_factor import load_factors
    from closure_nlp.placement.load_objective import LoadObjective
    from closure_nlp.placement.options import PlacementOptions
    from closure_nlp.placement.place import Placer
    from closure_nlp.selection.algorithms import run_selection
    from closure_nlp.selection.load_value import LoadValue

    out = {}
    for name in names:
        eligibility = paper_eligibility(name)
        loads = STEERING_LOADS[name]
        objective = LoadObjective.of(eligibility, loads)
        placer = Placer(eligibility, PlacementOptions(bound=False), loads=loads)
        runs = []
        for seed in range(seeds):
            row = {"seed": seed}
            for label in ("rho", "loads"):
                value = LoadValue(eligibility, objective) if label == "loads" else None
                found = run_selection(eligibility, "iterative", seed=seed, value=value)
                factors = objective(eligibility.slots(found.elements)).factors
                placed = load_factors(placer(list(found.elements)).contact_set, loads)
                row[label] = {
                    "elements": list(found.elements),
                    "element_factor": factors.load_factor,
                    "element_factor_hi": factors.bounds[1],
                    "placed_factor": placed.load_factor,
                    "bound_kept": placed.load_factor <= factors.bounds[1] * (1 + 1e-9),
                    "evaluations": found.evaluations,
                    "seconds": found.seconds,
                }
            runs.append(row)
        by = {k: [r[k]["element_factor"] for r in runs] for k in ("rho", "loads")}
        placed = {k: [r[k]["placed_factor"] for r in runs] for k in ("rho", "loads")}
        out[name] = {
            "type": PAPER_EXAMPLES[name]["type"],
            "median_element_factor": {k: float(np.median(v)) for k, v in by.items()},
            "median_placed_factor": {k: float(np.median(v)) for k, v in placed.items()},
            "loads_at_least_rho": int(sum(a >= b for a, b in zip(by["loads"], by["rho"]))),
            "bound_kept": int(sum(r[k]["bound_kept"] for r in runs for k in ("rho", "loads"))),
            "runs": runs,
        }
    return {"benchmark": "load_selection", "seeds": seeds, "models": out}


if __name__ == "__main__":
    raise SystemExit(main())
