"""Load factors against the independent SOCP: ``python -m benchmarks.loads [--sets N]``.

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
    args = parser.parse_args(argv)
    from closure_nlp.criterion.warm_up import warm_up

    warm_up()
    load_factor(random_contact_set(np.random.default_rng(0), ["pcwf"] * 4), np.ones(6))
    write_report(bench_loads(args.sets, args.seed), load_before)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
