"""rho by every method we know, on one seeded suite, measured against certified bounds.

    python examples/compare_solvers.py [--small] [--out examples/out] [--seeds 3]

The suite: random contact sets (``random_contact_set``) of every contact type and mixed,
m = 2..7, force closure and not. For each set the certified bounds ``lo <= rho <= hi``
(``certified_bounds``, started at IPOPT's direction) are the yardstick; a method's error is how
far its rho falls outside ``[lo, hi]`` (0 inside). Methods:

* IPOPT: ``search_rho`` with ``solver="ipopt"`` (our search alone, with the CasADi
  support-minimum NLP), solver built and warmed up first.
* SLSQP from +-e_k: the paper's multi-start SQP (``benchmarks.bench.paper_baseline``).
* GraspIt!/Dex-Net style: every friction cone cut to 8 edges (soft fingers: 8 edges and the two
  spin tips), the convex hull of the union of all edge wrenches at ``f_max``, epsilon = distance
  from the origin to the nearest facet, sign flipped to rho's convention (0 when qhull finds no
  interior). This is the hull of the *union* of the contacts' wrenches (an L1 grasp wrench
  space with polyhedral cones), a smaller set than the paper's ``W_c^M`` (union of all
  Minkowski sums): its error says how much that choice changes the number, not a solver error.
* cvxpy SOCP: ``closure_nlp.distance_cvxpy``, exact for sets that are not force
  closure (and only there: it returns 0 for the others).
* cvxpy force-closure check: the verdict only (rank + SOCP margin).

The same methods (but GraspIt!, which has no element sets) then measure rho_hat of random
element sets of the example models (lamp 4 PCwF, cup 4 SFCl and 4 SFCe, pistol 7 FPC): the
support function of the union of the elements' vertex wrench sets, with many more local minima.

Writes ``compare_solvers.csv``, ``compare_solvers.md`` and ``compare_solvers.png`` to ``--out``
and prints the Markdown table. ``--small`` runs a CI-sized suite (about 30 s).

``--peers`` runs the contact-set suite and ``examples/peer_cases`` through the implementations
users run instead (``examples/peers.py``: Klampt, Dex-Net, a GraspIt!-style L-inf epsilon; ``make
compare-peers`` sets up their environments), each set also with all normals flipped and all
lengths x10, against our certified verdict; writes ``compare_peers.csv/.md/.png``.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from dataclasses import replace
from pathlib import Path

import matplotlib
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from closure_nlp import (
    ContactSet,
    ContactType,
    Eligibility,
    contact_specs,
    load_contact_set,
    load_model,
    rho,
)

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

# examples/peers.py (the outside implementations), and benchmarks/ from the checkout: the
# internal pieces this comparison times one by one (the search without its certificate, the
# certificate alone, the conic cross-checks) and the paper's baseline.
sys.path[:0] = [str(Path(__file__).resolve().parent), str(Path(__file__).resolve().parents[1])]
import peers  # noqa: E402

from benchmarks.bench import paper_baseline  # noqa: E402
from benchmarks.internals import (  # noqa: E402
    SupportMinimizer,
    WrenchSlots,
    ball_minimum,
    certified_bounds,
    force_closure_check,
    random_contact_set,
    search_rho,
    write_atomic,
)

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
IPOPT = SupportMinimizer(solver="ipopt")  # the solver of record, as a column of its own


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
        specs = contact_specs(m, type=kind, mu=0.2, mu_s=0.2)
        eligibility = Eligibility(model, specs, torque_scale=1.0, minimizer=IPOPT)
        for seed in range(2 if small else 4 * seeds):
            rng = np.random.default_rng(seed)
            yield f"{name} {kind}", m, seed, eligibility, rng.choice(len(model), m).tolist()


def edge_wrenches(contact_set, edges: int = EDGES, owners: bool = False):
    """Wrenches of every contact's polyhedral cone edges at ``f_max``: (k, 6).

    The edges lie on the cone (an inscribed pyramid); soft fingers add the two spin tips. With
    ``owners``, also the (k,) index of the contact each row belongs to.
    """
    G = contact_set.grasp_matrices()
    angles = 2 * np.pi * np.arange(edges) / edges
    out, owner = [], []
    for i, (Gi, c) in enumerate(zip(G, contact_set.contacts)):
        forces = [np.array([1.0, 0.0, 0.0, 0.0])]
        if c.type is not ContactType.FPC:
            forces = [np.array([1.0, c.mu * np.cos(a), c.mu * np.sin(a), 0.0]) for a in angles]
        if c.type in (ContactType.SFCL, ContactType.SFCE):
            forces += [np.array([1.0, 0.0, 0.0, s * c.mu_s]) for s in (1.0, -1.0)]
        out += [c.f_max * Gi @ f for f in forces]
        owner += [i] * len(forces)
    return (np.array(out), np.array(owner)) if owners else np.array(out)


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
        search_rho(cs, minimizer=IPOPT)  # build and warm the NLP of this shape: we time reuse
        rows += measure(
            {"family": "contacts", "kind": kind, "m": m, "seed": seed},
            WrenchSlots.from_contacts(cs),
            lambda _cs=cs: _as_tuple(search_rho(_cs, minimizer=IPOPT)),
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
    _save_png(fig, path)


def _save_png(fig, path: Path) -> None:
    """The figure as a PNG at ``path``, written whole or not at all."""
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    write_atomic(path, buffer.getvalue())


# --- outside implementations (--peers) ----------------------------------------------------------

PEER_EDGES = {"klampt_4": 4, "klampt_8": 8, "klampt_64": 64}  # the others use EDGES
LINF_POINTS = 200_000  # GraspIt!'s sum of all point combinations: skip sets with more
VARIANTS = ("original", "flipped", "scaled")  # all normals negated; positions x10


def variant(contact_set: ContactSet, name: str) -> ContactSet:
    """The same grasp up to a change that cannot change force closure.

    Negating every normal negates every wrench (W -> -W: same distance to the origin); scaling
    every length (positions about the reference point, and mu_s, a length) by 10 multiplies
    every torque by 10, an invertible linear map.
    """
    if name == "original":
        return contact_set
    p = contact_set.reference_point
    if name == "flipped":
        changed = [replace(c, inward_normal=-c.inward_normal) for c in contact_set.contacts]
    else:
        changed = [
            replace(c, position=p + 10.0 * (c.position - p), mu_s=10.0 * c.mu_s)
            for c in contact_set.contacts
        ]
    return ContactSet(tuple(changed), contact_set.torque_scale, p)


def peer_sets(small: bool, seeds: int):
    """(family, kind, m, seed, ContactSet): the seeded suite, then examples/peer_cases."""
    for kind, m, seed, cs in suite(small, seeds):
        yield "suite", kind, m, seed, cs
    for path in sorted(peers.CASES.glob("*.contacts.json")):
        cs = load_contact_set(path)
        yield "cases", path.name.removesuffix(".contacts.json"), len(cs), 0, cs


def run_peers(small: bool, seeds: int, timeout: float) -> list[dict]:
    """One row per (set, variant, metric): ours (certified rho) and every installed peer's."""
    workers = {}
    for name in peers.PEERS:
        if peers.peer_python(name) is None:
            print(f"peer {name}: not set up (make compare-peers), skipped", file=sys.stderr)
        else:
            workers[name] = peers.PeerWorker(name, timeout)
    rows, linf_stop = [], {}
    try:
        for family, kind, m, seed, cs in peer_sets(small, seeds):
            search_rho(cs)  # build and warm the NLP of this shape: we time reuse
            ours, ours_ms = timed(rho, cs)
            lo, hi = ours.bounds
            wrenches = {k: edge_wrenches(cs, k) for k in (4, EDGES, 64)}
            base = {
                "family": family, "kind": kind, "m": m, "seed": seed, "lo": lo, "hi": hi,
                "certified": ours.force_closure, "marginal": ours.marginal,
                "fpc": sum(t is ContactType.FPC for t in cs.types),
                "l1_ours": max(0.0, -graspit_rho(cs)),
                **{f"lin_{k}": peers.polyhedral_closure(w) for k, w in wrenches.items()},
            }  # fmt: skip
            rows.append({**base, "variant": "original", "metric": "closure_nlp",
                         "status": "ok", "verdict": ours.force_closure, "value": ours.rho,
                         "ms": ours_ms})  # fmt: skip
            originals = {}
            for name in VARIANTS:
                changed = variant(cs, name)
                W, owner = edge_wrenches(changed, owners=True)
                request = peers.request(changed, W, owner)
                for peer, worker in workers.items():
                    if peer == "graspit":
                        if name != "original":
                            continue  # its verdicts cannot change: our own qhull
                        points = np.prod(np.bincount(owner) + 1.0)
                        if m >= linf_stop.get(kind, np.inf) or points > LINF_POINTS:
                            answer = {
                                "skipped": f"{points:.0f} sums; a smaller set timed out"
                                if points <= LINF_POINTS
                                else f"{points:.0f} sums"
                            }
                        else:
                            answer = worker.ask(request)
                            if "timeout" in answer:
                                linf_stop[kind] = m
                    else:
                        answer = worker.ask(request)
                    if name == "original":
                        originals[peer] = answer
                    rows += peer_rows({**base, "variant": name}, peer, answer, originals[peer])
            print(f"{family} {kind} m={m} seed={seed}: certified {ours.force_closure} "
                  f"[{lo:+.6f}, {hi:+.6f}]", file=sys.stderr)  # fmt: skip
    finally:
        for worker in workers.values():
            worker.close()
    return rows


def peer_rows(base: dict, peer: str, answer: dict, original: dict) -> list[dict]:
    """Rows of one peer's answer: every metric it offers, with its status.

    A verdict against the certified one (original sets), or one that a variant changed from the
    peer's own on the original set, gets its cause.
    """
    rows = []
    for metric in peers.PEERS[peer][1]:
        row = {**base, "metric": metric, "verdict": None, "value": None, "ms": None}
        failure = next((k for k in ("crash", "timeout", "skipped", "error") if k in answer), None)
        if failure:
            rows.append({**row, "status": failure, "message": answer[failure]})
            continue
        if metric not in answer:
            continue  # not offered for this set (Dex-Net's antipodal test: 2 PCwF only)
        result = answer[metric]
        if "error" in result:
            status = "unsupported" if result["error"].startswith("unsupported") else "error"
            rows.append({**row, "status": status, "message": result["error"]})
            continue
        rows.append({**row, "status": "ok", **result})
        if row["variant"] == "original" and result["verdict"] != base["certified"]:
            rows[-1]["cause"] = disagreement_cause(rows[-1], answer)
        before = original.get(metric, {}).get("verdict")
        if row["variant"] != "original" and before is not None and before != result["verdict"]:
            rows[-1]["cause"] = variant_cause(rows[-1], original[metric])
    return rows


def variant_cause(row: dict, before: dict) -> str:
    """Why flipping the normals or scaling the lengths changed a peer's verdict."""
    if row["variant"] == "flipped" and row["certified"]:
        # Both build a pyramid's edges in a frame taken from the normal: a flipped normal
        # gives other pyramids, and inscribed ones may lose a closure near the boundary.
        return "linearisation: flipped normals give other inscribed pyramids"
    if row["variant"] == "flipped":  # inscribed pyramids cannot give a closure the set lacks
        return "peer bug: one of the two verdicts claims a closure no inscribed cone can give"
    if row["metric"].startswith("dexnet"):
        return (
            "peer's tolerance: absolute thresholds against torques x10 (hull distance "
            f"{before.get('hull_distance', float('nan')):.1e} -> "
            f"{row.get('hull_distance') or float('nan'):.1e})"
        )
    return "peer's numerics: same normals and pyramids, lengths x10 (another unit), other verdict"


def disagreement_cause(row: dict, answer: dict) -> str:
    """Why a peer's verdict differs from the certified one, from what was measured on the set.

    ``answer`` holds the peer's other metrics on the same set (Klampt's 64-edge verdict).
    """
    metric = row["metric"]
    edges = PEER_EDGES.get(metric, EDGES)
    if row["certified"]:  # the peer misses a closure
        finer = answer.get("klampt_64", {}).get("verdict") if metric.startswith("klampt") else None
        if finer or not row[f"lin_{edges}"]:
            return f"linearisation: the inscribed {edges}-edge cones lose closure (" + (
                "Klampt's 64-edge test finds it)" if finer else "our LP on them agrees)"
            )
        return f"unexplained: our LP on {edges}-edge cones finds closure"
    if metric == "dexnet_antipodal":
        return "peer's model: the antipodal test ignores the twist about the contact line"
    if metric.startswith("dexnet") and (row.get("hull_distance") or 0.0) < 1e-3:
        return (
            "peer's tolerance: origin outside the hull but within 1e-3 (absolute) of it "
            f"({row['hull_distance']:.1e}), taken as inside: an equilibrium test"
        )
    if metric.startswith("klampt") and row["fpc"] > 0:
        return (
            "peer bug: a frictionless contact (friction 0) acts as a free force; any 3 "
            "non-collinear ones are called force closure"
        )
    if row["marginal"]:
        return "degeneracy: the certified bracket reaches 0 (a set without interior)"
    if row[f"lin_{edges}"]:
        return f"unexplained: our LP on the {edges}-edge cones finds closure, the certificate not"
    return "peer bug: closure claimed, which no inscribed cone can give (nor our LP on its edges)"


def _percentile(values, q) -> float | None:
    return float(np.percentile(values, q)) if values else None


def peer_summary(rows: list[dict]) -> list[dict]:
    """Per metric: agreement with the certified verdict, ms, failures, invariance, values."""
    out = []
    for metric, label in {"closure_nlp": "closure_nlp rho (certified)", **peers.METRICS}.items():
        mine = [r for r in rows if r["metric"] == metric]
        if not mine:
            continue
        original = [r for r in mine if r["variant"] == "original"]
        ok = [r for r in original if r["status"] == "ok"]
        ms = [r["ms"] for r in ok]
        verdicts = {(r["family"], r["kind"], r["m"], r["seed"]): r["verdict"] for r in ok}
        changed = {
            (r["family"], r["kind"], r["m"], r["seed"])
            for r in mine
            if r["variant"] != "original" and r["status"] == "ok"
            and verdicts.get((r["family"], r["kind"], r["m"], r["seed"]), r["verdict"])
            != r["verdict"]
        }  # fmt: skip
        count = {s: sum(r["status"] == s for r in mine) for s in ("error", "crash", "timeout")}
        entry = {
            "metric": metric, "label": label, "sets": len(original), "answered": len(ok),
            "agree": sum(r["verdict"] == r["certified"] for r in ok),
            "false_closure": sum(r["verdict"] and not r["certified"] for r in ok),
            "missed_closure": sum(r["certified"] and not r["verdict"] for r in ok),
            "variant_changes": len(changed),
            "unsupported": sum(r["status"] == "unsupported" for r in original),
            "skipped": sum(r["status"] == "skipped" for r in original),
            "errors": count["error"], "crashes": count["crash"], "timeouts": count["timeout"],
            "median_ms": _percentile(ms, 50), "p95_ms": _percentile(ms, 95),
            "median_ms_closure": _percentile([r["ms"] for r in ok if r["certified"]], 50),
        }  # fmt: skip
        entry["values"] = value_check(metric, ok)
        out.append(entry)
    return out


def value_check(metric: str, ok: list[dict]) -> str:
    """What the metric's values say against ours, where they are comparable at all."""
    closure = [r for r in ok if r["certified"] and r["value"] is not None and r["value"] > 0]
    slack = lambda r: 1e-6 * max(1.0, abs(r["lo"]))  # noqa: E731  (the certificate's tolerance)
    if metric == "dexnet_l1" and ok:
        diff = max(abs(r["value"] - r["l1_ours"]) for r in ok)
        above = sum(r["value"] > -r["lo"] + slack(r) for r in closure)
        return (f"L1 epsilon, another set: <= -rho on {len(closure) - above}/{len(closure)}; "
                f"scipy qhull on the same edges within {diff:.0e}")  # fmt: skip
    if metric == "graspit_linf" and closure:
        above = sum(r["value"] > -r["lo"] + slack(r) for r in closure)
        ratio = np.median([r["value"] / -r["lo"] for r in closure])
        return (f"L-inf epsilon <= -rho on {len(closure) - above}/{len(closure)}; "
                f"median epsilon / -rho {ratio:.3f}")  # fmt: skip
    if metric == "closure_nlp":
        return "rho in certified [lo, hi]"
    return "verdict only"


def peer_table(rows: list[dict]) -> str:
    stats = peer_summary(rows)
    n = len({(r["family"], r["kind"], r["m"], r["seed"]) for r in rows})
    closure = sum(r["verdict"] for r in rows if r["metric"] == "closure_nlp")
    lines = [
        f"**Peers on {n} contact sets** ({closure} certified force closure); verdicts against "
        "the certified one, on the original sets",
        "",
        "| implementation | answered | agree | false closure | missed closure "
        "| changed by flip/x10 | median ms | p95 ms | median ms, closure "
        "| crashes / errors / timeouts (all variants) "
        "| not run | values |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in stats:
        not_run = []
        if s["unsupported"]:
            not_run.append(f"{s['unsupported']} soft")
        if s["skipped"]:
            not_run.append(f"{s['skipped']} too large")
        lines.append(
            f"| {s['label']} | {s['answered']}/{s['sets']} | {s['agree']} | {s['false_closure']} "
            f"| {s['missed_closure']} | {s['variant_changes']} | {_fmt(s['median_ms'], '.2f')} "
            f"| {_fmt(s['p95_ms'], '.2f')} | {_fmt(s['median_ms_closure'], '.2f')} "
            f"| {s['crashes']} / {s['errors']} / {s['timeouts']} "
            f"| {', '.join(not_run) or '-'} | {s['values']} |"
        )
    lines += ["", "**Disagreements with the certified verdict** (original sets)", "",
              "| set | implementations | peer says | certified [lo, hi] | cause |",
              "|---|---|---|---|---|"]  # fmt: skip
    lines += _cause_lines([r for r in rows if r.get("cause") and r["variant"] == "original"])
    lines += ["", "**Verdicts changed by flipping every normal or scaling every length x10** "
              "(the certified verdict cannot change)", "",
              "| set | implementations | peer says | certified [lo, hi] | cause |",
              "|---|---|---|---|---|"]  # fmt: skip
    lines += _cause_lines([r for r in rows if r.get("cause") and r["variant"] != "original"])
    failures = [r for r in rows if r["status"] in ("crash", "error", "timeout")]
    if failures:
        lines += ["", "**Crashes, errors and timeouts**", ""]
        lines += [f"- {r['family']} {r['kind']} m={r['m']} seed={r['seed']} ({r['variant']}), "
                  f"{r['metric']}: {r['status']}: {r['message']}" for r in failures]  # fmt: skip
    return "\n".join(lines) + "\n"


def _cause_lines(rows: list[dict]) -> list[str]:
    """One table line per (set, variant, verdict, cause), the metrics that share it joined."""
    groups = {}
    for r in rows:
        name = f"{r['family']} {r['kind']} m={r['m']} seed={r['seed']}"
        if r["family"] == "cases":
            name = f"peer_cases/{r['kind']}"
        if r["variant"] != "original":
            name += f" ({r['variant']})"
        key = (name, r["verdict"], r["cause"], f"[{r['lo']:+.2e}, {r['hi']:+.2e}]")
        groups.setdefault(key, []).append(r["metric"])
    return [
        f"| {name} | {', '.join(metrics)} | {'closure' if verdict else 'not closure'} "
        f"| {bracket} | {cause} |"
        for (name, verdict, cause, bracket), metrics in groups.items()
    ]


def peer_chart(rows: list[dict], path: Path) -> None:
    stats = peer_summary(rows)
    labels = [s["label"] for s in stats]
    fig, (left, right) = plt.subplots(1, 2, figsize=(14, 6), sharey=True)
    y = np.arange(len(stats))
    median = [s["median_ms"] or np.nan for s in stats]
    p95 = [s["p95_ms"] or np.nan for s in stats]
    left.barh(y + 0.2, median, height=0.4, color="tab:blue", label="median")
    left.barh(y - 0.2, p95, height=0.4, color="tab:cyan", label="95th percentile")
    left.set_xscale("log")
    left.set_xlabel("ms per set (the peer's call alone)")
    left.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    parts = [("agree", "tab:green"), ("false_closure", "tab:red"),
             ("missed_closure", "tab:orange")]  # fmt: skip
    start = np.zeros(len(stats))
    for key, color in parts:
        widths = np.array([s[key] for s in stats], float)
        right.barh(y, widths, left=start, color=color, label=key.replace("_", " "))
        start += widths
    rest = np.array([s["sets"] - s["answered"] for s in stats], float)
    right.barh(y, rest, left=start, color="lightgrey", label="not answered (soft, large, failed)")
    right.set_xlabel("original sets: verdict against the certified one")
    right.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=9)
    left.set_yticks(y, labels)
    left.invert_yaxis()
    _save_png(fig, path)


def write_peers(rows: list[dict], out: Path) -> str:
    markdown = peer_table(rows)
    buffer = io.StringIO()
    fields = ["family", "kind", "m", "seed", "variant", "metric", "status", "verdict", "value",
              "ms", "certified", "marginal", "lo", "hi", "l1_ours", "lin_4", f"lin_{EDGES}",
              "lin_64", "hull_distance", "cause", "message"]  # fmt: skip
    writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / "compare_peers.csv", buffer.getvalue())
    write_atomic(out / "compare_peers.md", markdown)
    peer_chart(rows, out / "compare_peers.png")
    return markdown


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="CI-sized suite")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per (kind, m), full suite")
    parser.add_argument("--out", type=Path, default=ROOT / "examples" / "out")
    parser.add_argument(
        "--peers", action="store_true",
        help="run the outside implementations instead (make compare-peers sets them up)",
    )  # fmt: skip
    parser.add_argument("--timeout", type=float, default=20.0, help="--peers: s per set and peer")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds: must be >= 1, got {args.seeds}")
    if not args.timeout > 0:
        parser.error(f"--timeout: must be > 0, got {args.timeout}")
    if args.peers:
        print(write_peers(run_peers(args.small, args.seeds, args.timeout), args.out))
        return 0
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
