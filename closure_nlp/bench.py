"""Benchmarks that print JSON: ``python -m closure_nlp.bench rho``.

Timings are medians over seeded random cases with every solver built and warmed up first, and
each is compared in the same process with a paper-style baseline: scipy SLSQP started from the
12 directions ``+-e_k`` (the paper's fmincon active-set runs). Errors are measured against the
lowest support value any method found at a unit direction: every such value is an upper bound on
``min p``, so the lowest is the best estimate of the global minimum.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from scipy.optimize import minimize

from .quality import SearchOptions, SupportMinimizer
from .random_sets import BENCH_CASES, random_contact_set
from .wrenches import WrenchSlots


def paper_baseline(slots: WrenchSlots) -> float:
    """``min p(u)`` over the sphere by SLSQP from ``+-e_k``: the paper's approach."""
    best = np.inf
    sphere = {"type": "eq", "fun": lambda u: u @ u - 1.0, "jac": lambda u: 2.0 * u}
    for u0 in np.vstack([np.eye(6), -np.eye(6)]):
        res = minimize(
            lambda u: slots.evaluate(u)[0][0],
            u0,
            jac=lambda u: slots.evaluate(u)[1][0],
            constraints=[sphere],
            method="SLSQP",
            options={"ftol": 1e-10, "maxiter": 500},
        )
        u = res.x / np.linalg.norm(res.x)
        best = min(best, float(slots.support(u)[0]))
    return best


def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(v)),
        "p25": float(np.percentile(v, 25)),
        "p75": float(np.percentile(v, 75)),
        "max": float(v.max()),
    }


def bench_rho(cases: int = 30, repeats: int = 3, seed: int = 0) -> dict:
    """ms per rho evaluation (solver reused) for each case family, ours against the baseline."""
    minimizer = SupportMinimizer()
    thorough = SupportMinimizer(
        search=SearchOptions(samples=512, descent_iterations=60, ipopt_starts=6)
    )
    report = {"benchmark": "rho", "cases_per_family": cases, "repeats": repeats, "families": {}}
    for name, types in BENCH_CASES.items():
        rng = np.random.default_rng(seed)
        sets = [WrenchSlots.from_contacts(random_contact_set(rng, types)) for _ in range(cases)]
        minimizer(sets[0])  # build and warm the solver once: we measure reuse
        ours_ms, base_ms, ours_v, base_v, best_v = [], [], [], [], []
        for slots in sets:
            for _ in range(repeats):
                t0 = time.perf_counter()
                found = minimizer(slots)
                ours_ms.append(1e3 * (time.perf_counter() - t0))
            t0 = time.perf_counter()
            base = paper_baseline(slots)
            base_ms.append(1e3 * (time.perf_counter() - t0))
            ours_v.append(found.value)
            base_v.append(base)
            best_v.append(min(found.value, base, thorough(slots).value))
        ours_err = np.array(ours_v) - best_v
        base_err = np.array(base_v) - best_v
        report["families"][name] = {
            "force_closure_share": float(np.mean(np.array(ours_v) > 0)),
            "ours_ms": _stats(ours_ms),
            "baseline_ms": _stats(base_ms),
            "speedup_median": float(np.median(base_ms) / np.median(ours_ms)),
            "ours_worst_error": float(ours_err.max()),
            "baseline_worst_error": float(base_err.max()),
            "baseline_misses": int(np.sum(base_err > 1e-6 * np.maximum(1, np.abs(best_v)))),
            "ours_misses": int(np.sum(ours_err > 1e-6 * np.maximum(1, np.abs(best_v)))),
        }
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m closure_nlp.bench", description=__doc__)
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("rho", help="rho(0, W_c^M) per evaluation against SLSQP from +-e_k")
    p.add_argument("--cases", type=int, default=30)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.what == "rho":
        report = bench_rho(args.cases, args.repeats, args.seed)
    json.dump(report, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
