"""rho by every method we know, on one seeded suite, measured against certified bounds.

    python examples/compare_solvers.py [--small] [--out examples/out] [--seeds 3]

The suite: random contact sets (``closure_nlp.random_sets``) of every contact type and mixed,
m = 2..7, force closure and not. For each set the certified bounds ``lo <= rho <= hi``
(``closure_nlp.certify``, started at IPOPT's direction) are the yardstick; a method's error is
how far its rho falls outside ``[lo, hi]`` (0 inside). Methods:

* IPOPT: ``closure_nlp.quality.search_rho`` (our search alone, what rho cost before it was
  certified), solver built and warmed up first.
* SLSQP from +-e_k: the paper's multi-start SQP (``closure_nlp.bench.paper_baseline``).
* GraspIt!/Dex-Net style: every friction cone cut to 8 edges (soft fingers: 8 edges and the two
  spin tips), the convex hull of the union of all edge wrenches at ``f_max``, epsilon = distance
  from the origin to the nearest facet, sign flipped to rho's convention (0 when qhull finds no
  interior). This is the hull of the *union* of the contacts' wrenches (an L1 grasp wrench
  space with polyhedral cones), a smaller set than the paper's ``W_c^M`` (union of all
  Minkowski sums): its error says how much that choice changes the number, not a solver error.
* cvxpy SOCP: ``closure_nlp.crosscheck.distance_cvxpy``, exact for sets that are not force
  closure (and only there: it returns 0 for the others).
* cvxpy force-closure check: the verdict only (rank + SOCP margin).

The same methods (but GraspIt!, which has no element sets) then measure rho_hat of random
element sets of the example models (lamp 4 PCwF, cup 4 SFCl and 4 SFCe, pistol 7 FPC): the
support function of the union of the elements' vertex wrench sets, with many more local minima.

Writes ``compare_solvers.csv``, ``compare_solvers.md`` and ``compare_solvers.png`` to ``--out``
and prints the Markdown table. ``--small`` runs a CI-sized suite (about 30 s).
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path

import matplotlib
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from closure_nlp.bench import paper_baseline
from closure_nlp.certify import certified_bounds
from closure_nlp.contacts import ContactType, contact_specs
from closure_nlp.crosscheck import ball_minimum, force_closure_check
from closure_nlp.elements import load_model
from closure_nlp.eligibility import Eligibility
from closure_nlp.files import write_atomic
from closure_nlp.quality import search_rho
from closure_nlp.random_sets import random_contact_set
from closure_nlp.wrenches import WrenchSlots

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

ROOT = Path(__file__).resolve().parents[1]
TYPES = ["fpc", "pcwf", "sfcl", "sfce"]
KINDS = [*TYPES, "mixed"]
METHODS = {
    "ipopt": "IPOPT search (ours, without bounds)",
    "slsqp": "SLSQP from +-e_k (paper)",
    "graspit": "GraspIt!/Dex-Net 8-edge qhull (other set)",
    "cvxpy": "cvxpy SOCP distance (not closure only)",
    "cvxpy_fc": "cvxpy force-closure check (verdict only)",
    "certified": "certified bounds (ours: branch and bound / nearest point)",
}
EDGES = 8


def suite(small: bool, seeds: int):
    """(kind, m, seed, ContactSet) of the fixed seeded suite."""
    sizes = (2, 4, 7) if small else tuple(range(2, 8))
    for kind in KINDS:
        for m in sizes:
            for seed in range(1 if small else seeds):
                rng = np.random.default_rng(1000 * m + seed + 17 * len(kind))
                types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
                yield kind, m, seed, random_contact_set(rng, types, mu=0.5, mu_s=0.3, tilt=0.25)


ELEMENT_CASES = [("lamp", "pcwf", 4), ("cup", "sfcl", 4), ("cup", "sfce", 4), ("pistol", "fpc", 7)]


def element_suite(small: bool, seeds: int):
    """(kind, m, seed, Eligibility, element ids): random element sets of the example models."""
    for name, kind, m in ELEMENT_CASES:
        model = load_model(ROOT / "models" / f"{name}.model.json")
        eligibility = Eligibility(model, contact_specs(m, type=kind, mu=0.2, mu_s=0.2))
        for seed in range(2 if small else 4 * seeds):
            rng = np.random.default_rng(seed)
            yield f"{name} {kind}", m, seed, eligibility, rng.choice(len(model), m).tolist()


def edge_wrenches(contact_set) -> np.ndarray:
    """Wrenches of every contact's polyhedral cone edges at ``f_max``: (k, 6)."""
    G = contact_set.grasp_matrices()
    angles = 2 * np.pi * np.arange(EDGES) / EDGES
    out = []
    for Gi, c in zip(G, contact_set.contacts):
        forces = [np.array([1.0, 0.0, 0.0, 0.0])]
        if c.type is not ContactType.FPC:
            forces = [np.array([1.0, c.mu * np.cos(a), c.mu * np.sin(a), 0.0]) for a in angles]
        if c.type in (ContactType.SFCL, ContactType.SFCE):
            forces += [np.array([1.0, 0.0, 0.0, s * c.mu_s]) for s in (1.0, -1.0)]
        out += [c.f_max * Gi @ f for f in forces]
    return np.array(out)


def graspit_rho(contact_set) -> float:
    """-epsilon of the hull of the union of edge wrenches (0 without interior)."""
    try:
        hull = ConvexHull(edge_wrenches(contact_set))
    except (QhullError, ValueError):
        return 0.0
    return float(-(-hull.equations[:, -1]).min())


def timed(function, *args, **kwargs):
    t0 = time.perf_counter()
    value = function(*args, **kwargs)
    return value, 1e3 * (time.perf_counter() - t0)


def run(small: bool, seeds: int) -> list[dict]:
    """One row per (set, method): the contact sets, then the element sets (rho_hat)."""
    rows = []
    for kind, m, seed, cs in suite(small, seeds):
        search_rho(cs)  # build and warm the NLP of this shape: we time reuse
        rows += measure(
            {"family": "contacts", "kind": kind, "m": m, "seed": seed},
            WrenchSlots.from_contacts(cs),
            lambda _cs=cs: _as_tuple(search_rho(_cs)),
            lambda _cs=cs: graspit_rho(_cs),
        )
    for kind, m, seed, eligibility, elements in element_suite(small, seeds):
        eligibility(elements, certify=False)  # build and warm the NLP of this shape
        rows += measure(
            {"family": "elements", "kind": kind, "m": m, "seed": seed},
            eligibility.slots(elements),
            lambda _e=eligibility, _ids=elements: _as_tuple(_e(_ids, certify=False)),
        )
    return rows


def _as_tuple(result):
    """(rho or rho_hat, direction, verdict) of a RhoResult or an EligibilityResult."""
    value = getattr(result, "rho", getattr(result, "rho_hat", None))
    return value, result.direction, value < 0


def measure(base: dict, slots: WrenchSlots, ours, graspit=None) -> list[dict]:
    """Every method on one set, each error measured against the certified bounds."""
    rows = []
    (value, direction, verdict), ours_ms = timed(ours)
    bounds, bounds_ms = timed(certified_bounds, slots, direction)
    lo, hi = bounds
    certified = bounds.force_closure
    base = {**base, "lo": lo, "hi": hi, "certified": certified}

    def add(method, rho_value, ms, claim):
        error = max(lo - rho_value, rho_value - hi, 0.0) if rho_value is not None else None
        rows.append(
            {**base, "method": method, "rho": rho_value, "ms": ms, "error": error, "verdict": claim}
        )

    add("ipopt", value, ours_ms, verdict)
    baseline, ms = timed(paper_baseline, slots)
    add("slsqp", -baseline, ms, -baseline < 0)
    if graspit is not None:
        graspit_value, ms = timed(graspit)
        add("graspit", graspit_value, ms, graspit_value < 0)
    ball_minimum(slots)  # compile the SOCP of this shape once
    found, ms = timed(ball_minimum, slots)
    add("cvxpy", found.distance if certified is False else None, ms, found.distance == 0)
    check, ms = timed(force_closure_check, slots)
    add("cvxpy_fc", None, ms, check.force_closure)
    rows.append(
        {**base, "method": "certified", "rho": None, "ms": bounds_ms, "error": hi - lo,
         "verdict": certified, "converged": bounds.converged}
    )  # fmt: skip
    print(
        f"{base['family']} {base['kind']} m={base['m']} seed={base['seed']}: rho {value:+.6f} "
        f"in [{lo:+.9f}, {hi:+.9f}] ({bounds_ms:.0f} ms)",
        file=sys.stderr,
    )
    return rows


def summary(rows: list[dict]) -> list[dict]:
    """Per method: sets, median ms, worst errors by certified verdict, verdict mismatches."""
    out = []
    for method, label in METHODS.items():
        mine = [r for r in rows if r["method"] == method]
        if not mine:
            continue
        timed_rows = [
            r for r in mine if r["rho"] is not None or method in ("certified", "cvxpy_fc")
        ]

        def worst(closure, _mine=mine):
            errors = [
                r["error"] for r in _mine if r["error"] is not None and r["certified"] is closure
            ]
            return max(errors) if errors else None

        decided = [r for r in mine if r["certified"] is not None and method != "certified"]
        if method == "cvxpy":
            decided = []  # its verdict is only "distance 0": no claim about closure
        mismatches = sum(r["verdict"] != r["certified"] for r in decided)
        out.append(
            {
                "method": label,
                "sets": len(timed_rows),
                "median_ms": float(np.median([r["ms"] for r in timed_rows])),
                "median_ms_closure": _median([r["ms"] for r in timed_rows if r["certified"]]),
                "worst_closure": worst(True),
                "worst_not_closure": worst(False),
                "mismatches": mismatches if decided else None,
                "unconverged": sum(not r.get("converged", True) for r in mine),
            }
        )
    return out


def _median(values) -> float | None:
    return float(np.median(values)) if values else None


def _fmt(value, spec=".1e") -> str:
    return "-" if value is None else format(value, spec)


def table(rows: list[dict]) -> str:
    """One Markdown table per family (contact sets: rho; element sets: rho_hat)."""
    lines = []
    families = (("contacts", "rho of contact sets"), ("elements", "rho_hat of element sets"))
    for family, what in families:
        mine = [r for r in rows if r["family"] == family]
        if not mine:
            continue
        stats = summary(mine)
        n = len({(r["kind"], r["m"], r["seed"]) for r in mine})
        closure = sum(r["certified"] is True for r in mine if r["method"] == "certified")
        lines += [
            f"**{what}**: {n} sets ({closure} certified force closure / eligible)",
            "",
            "| method | sets | median ms | median ms, closure | worst error, closure "
            "| worst error, not closure | verdict mismatches |",
            "|---|---|---|---|---|---|---|",
        ]
        for s in stats:
            lines.append(
                f"| {s['method']} | {s['sets']} | {s['median_ms']:.1f} "
                f"| {_fmt(s['median_ms_closure'], '.1f')} | {_fmt(s['worst_closure'])} "
                f"| {_fmt(s['worst_not_closure'])} | {_fmt(s['mismatches'], 'd')} |"
            )
        budget = stats[-1]["unconverged"]
        lines += ["", f"Certified bounds stopped at the refinement budget: {budget}.", ""]
    lines += [
        "Error: distance of a method's value outside the certified [lo, hi]; for the certified "
        "bounds row, the gap hi - lo. The bounds start at IPOPT's direction. The GraspIt!/Dex-Net "
        "row measures a slightly different set (hull of the union of 8-edge cone wrenches, not "
        "the union of Minkowski sums), so its error is the modelling difference, not a solver "
        "error. cvxpy SOCP: sets certified not force closure only. Element sets: random ids on "
        "the example models, mu = 0.2, mu_s = 0.2 mm.",
    ]
    return "\n".join(lines) + "\n"


def chart(rows: list[dict], path: Path) -> None:
    stats, labels = [], []
    for family in ("contacts", "elements"):
        mine = summary([r for r in rows if r["family"] == family])
        stats += mine
        labels += [f"{s['method']} [{family}]" for s in mine]
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 6), sharey=True)
    left.barh(labels, [s["median_ms"] for s in stats], color="tab:blue")
    left.set_xscale("log")
    left.set_xlabel("median ms per set")
    worst = [
        max([e for e in (s["worst_closure"], s["worst_not_closure"]) if e is not None] or [np.nan])
        for s in stats
    ]
    right.barh(labels, np.maximum(worst, 1e-16), color="tab:red")  # nan: no error to show
    right.set_xscale("log")
    right.set_xlabel("worst error vs certified bounds (gap for the bounds)")
    left.invert_yaxis()
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    write_atomic(path, buffer.getvalue())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="CI-sized suite")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per (kind, m), full suite")
    parser.add_argument("--out", type=Path, default=ROOT / "examples" / "out")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds: must be >= 1, got {args.seeds}")
    rows = run(args.small, args.seeds)
    markdown = table(rows)
    buffer = io.StringIO()
    fields = ["family", "kind", "m", "seed", "method", "rho", "ms", "lo", "hi", "error", "verdict",
              "certified", "converged"]  # fmt: skip
    writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(args.out / "compare_solvers.csv", buffer.getvalue())
    write_atomic(args.out / "compare_solvers.md", markdown)
    chart(rows, args.out / "compare_solvers.png")
    print(markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
