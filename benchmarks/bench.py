"""Benchmarks that print JSON: ``python -m benchmarks.bench WHAT`` (``rho``, ``rho-hat``,
``certify``, ``engine``, ``batch``, ``startup``, ``select``, ``plan``, ``plans``, ``seeds``,
``gap``, ``part-ceiling``, ``characterize``, ``real-meshes``, ``intent``, ``dexnet``).

Timings are medians over seeded random cases with every solver built and warmed up first, and
each is compared in the same process with a paper-style baseline: scipy SLSQP started from the
12 directions ``+-e_k`` (the paper's fmincon active-set runs). Errors are measured against the
lowest support value any method found at a unit direction: every such value is an upper bound on
``min p``, so the lowest is the best estimate of the global minimum.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from closure_nlp.base.tolerances import DEFAULT_TOLERANCES
from closure_nlp.contact.contact_set import Contact, ContactSet, ContactType
from closure_nlp.contact.random_sets import BENCH_CASES, random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import SearchOptions, SupportMinimizer, certified_rho
from closure_nlp.model.elements import load_model
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
from closure_nlp.selection.algorithms import SelectionOptions, heuristic, iterative


def _timed(times_ms: list, repeats: int, call):
    """``call()`` ``repeats`` times, each one's milliseconds appended to ``times_ms``; the last
    value."""
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = call()
        times_ms.append(1e3 * (time.perf_counter() - t0))
    return value


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
        search=SearchOptions(
            samples=1024, descent_iterations=60, ipopt_starts=12, element_ipopt_starts=12
        )
    )
    report = {"benchmark": "rho", "cases_per_family": cases, "repeats": repeats, "families": {}}
    for name, types in BENCH_CASES.items():
        rng = np.random.default_rng(seed)
        sets = [WrenchSlots.from_contacts(random_contact_set(rng, types)) for _ in range(cases)]
        minimizer(sets[0])  # build and warm the solver once: we measure reuse
        ours_ms, base_ms, ours_v, base_v, best_v = [], [], [], [], []
        for slots in sets:
            found = _timed(ours_ms, repeats, lambda s=slots: minimizer(s))
            base = _timed(base_ms, 1, lambda s=slots: paper_baseline(s))
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


def bench_certify(cases: int = 20, seed: int = 0, models_dir=None) -> dict:
    """Certified rho (search + certificate) per family and certified rho_hat of 4 lamp facets.

    Reports, in one process: ms of the full search alone (what rho cost before it was
    certified), of the certified path (the light seed search, then the certificate: each and
    both), against SLSQP from ``+-e_k`` (uncertified, the paper's approach); the
    bracket widths relative to ``max(|rho|, unit)``; how many brackets converged to 1e-6.
    """
    from closure_nlp.criterion.certificate import tolerance_unit

    minimizer = SupportMinimizer()
    families = {name: types for name, types in BENCH_CASES.items()}
    report = {"benchmark": "certify", "cases_per_family": cases, "families": {}}
    eligibility = paper_eligibility("lamp", models_dir or MODELS_DIR)
    rng = np.random.default_rng(seed)
    lamp = [eligibility.slots(rng.integers(0, len(eligibility.model), 4).tolist())]
    lamp += [
        eligibility.slots(rng.integers(0, len(eligibility.model), 4).tolist())
        for _ in range(cases - 1)
    ]
    groups = {
        name: [
            WrenchSlots.from_contacts(random_contact_set(np.random.default_rng(seed + k), types))
            for k in range(cases)
        ]
        for name, types in families.items()
    }
    groups["rho_hat lamp 4 facets"] = lamp
    seed = minimizer.seeding()
    for name, sets in groups.items():
        minimizer(sets[0])  # build and warm the solver once: we measure reuse
        search_ms, seed_ms, cert_ms, base_ms = [], [], [], []
        widths, converged, closure = [], [], []
        for slots in sets:
            t0 = time.perf_counter()
            minimizer(slots)  # the full search alone: what rho cost before it was certified
            t1 = time.perf_counter()
            found = seed(slots)  # the certified path: the light seed, then the certificate
            t2 = time.perf_counter()
            certified = certified_rho(slots, found, minimizer)
            t3 = time.perf_counter()
            paper_baseline(slots)
            t4 = time.perf_counter()
            search_ms.append(1e3 * (t1 - t0))
            seed_ms.append(1e3 * (t2 - t1))
            cert_ms.append(1e3 * (t3 - t2))
            base_ms.append(1e3 * (t4 - t3))
            lo, hi = certified.bounds
            widths.append((hi - lo) / max(abs(lo), tolerance_unit(slots)))
            converged.append(certified.converged)
            closure.append(certified.force_closure)
        total = np.add(seed_ms, cert_ms)
        closed = np.array(closure)
        report["families"][name] = {
            "force_closure_share": float(closed.mean()),
            "search_ms": _stats(search_ms),
            "seed_search_ms": _stats(seed_ms),
            "certificate_ms": _stats(cert_ms),
            "certified_total_ms": _stats(total),
            "certified_total_ms_closure_sets": _stats(total[closed]) if closed.any() else None,
            "baseline_slsqp_ms": _stats(base_ms),
            "certified_vs_search_median": float(np.median(total) / np.median(search_ms)),
            "baseline_vs_certified_median": float(np.median(base_ms) / np.median(total)),
            "relative_width_max": float(max(widths)),
            "converged": f"{sum(converged)}/{len(converged)}",
        }
    return report


def cylinder_set(kind: str, m: int, mu: float = 0.5, mu_s: float = 0.2) -> ContactSet:
    """``m`` contacts around a unit cylinder (axis z), heights alternating +-0.3: a round part
    held by a gripper, whose weakest directions repeat under its symmetry."""
    angles = 2 * np.pi * np.arange(m) / m
    pts = np.column_stack([np.cos(angles), np.sin(angles), 0.3 * (-1.0) ** np.arange(m)])
    normals = -np.column_stack([np.cos(angles), np.sin(angles), np.zeros(m)])
    return ContactSet(tuple(Contact(p, n, kind, mu=mu, mu_s=mu_s) for p, n in zip(pts, normals)))


def opposite_pair(mu: float, mu_s: float) -> ContactSet:
    """Two soft fingers pinching a part from opposite sides: a circle of equally weak
    directions when ``mu_s >= mu``."""
    return ContactSet(
        (
            Contact([0, 0, 1], [0, 0, -1], ContactType.SFCE, mu=mu, mu_s=mu_s),
            Contact([0, 0, -1], [0, 0, 1], ContactType.SFCE, mu=mu, mu_s=mu_s),
        )
    )


def tetrahedral(kind: str = "pcwf", mu: float = 0.5, mu_s: float = 0.2) -> ContactSet:
    """Four contacts at the vertices of a regular tetrahedron pushing to its centre: isotropic,
    its symmetry axes run through a contact or between two."""
    v = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
    return ContactSet(tuple(Contact(p, -p, kind, mu=mu, mu_s=mu_s) for p in v))


def ring(kind: str, m: int, mu: float = 0.5, mu_s: float = 0.2) -> ContactSet:
    """``m`` contacts equally spaced round a circle in one plane, pushing to its centre: a
    turn, a mirror, and the flip across that plane."""
    a = 2 * np.pi * np.arange(m) / m
    P = np.column_stack([np.cos(a), np.sin(a), np.zeros(m)])
    return ContactSet(tuple(Contact(p, -p, kind, mu=mu, mu_s=mu_s) for p in P))


def engine_families(cases: int, seed: int = 0) -> dict:
    """The certified-rho families of ``bench engine``: name -> list of ContactSet, or
    ``("lamp", element lists)`` for rho_hat of 4 lamp facets."""
    families = {
        name: [random_contact_set(np.random.default_rng(seed + k), types) for k in range(cases)]
        for name, types in BENCH_CASES.items()
    }
    rng = np.random.default_rng(seed)
    facets = len(load_model(MODELS_DIR / "lamp.model.json"))
    families["rho_hat lamp 4 facets"] = (
        "lamp",
        [rng.integers(0, facets, 4).tolist() for _ in range(cases)],
    )
    families["4 SFCe cylinder"] = [cylinder_set("sfce", 4)]
    families["6 SFCe cylinder"] = [cylinder_set("sfce", 6)]
    families["2 opposite SFCe"] = [
        opposite_pair(mu, mu_s) for mu, mu_s in ((0.5, 0.5), (0.5, 1.0), (0.2, 0.2))
    ]
    families["tetrahedral 4 PCwF"] = [tetrahedral(mu=mu) for mu in (0.5, 0.2)]
    families["ring of 4 SFCe"] = [ring("sfce", 4)]
    families["ring of 6 SFCe"] = [ring("sfce", 6)]
    for m in (200, 1000, 2000):
        families[f"{m} PCwF"] = [
            random_contact_set(np.random.default_rng(seed + k), ["pcwf"] * m)
            for k in range(max(1, cases // (10 if m == 200 else 20)))
        ]
    return families


# Run by ``bench engine --baseline DIR`` with DIR's closure_nlp first on the path: the same
# measurement of another checkout (the sets travel as contact-set dicts or lamp facet lists).
_ENGINE_RUNNER = """
import json, sys, time
import numpy as np
from closure_nlp.criterion.certificate import tolerance_unit
from closure_nlp.contact.contact_set import contact_set_from_dict
from closure_nlp.criterion.support_minimum import SupportMinimizer, certified_rho, certified_search
from closure_nlp.contact.wrenches import WrenchSlots
spec = json.loads(sys.stdin.read())
minimizer = SupportMinimizer(**spec.get("minimizer", {}))
if spec["kind"] == "lamp":
    from benchmarks.bench import paper_eligibility
    eligibility = paper_eligibility("lamp", spec["models"])
    slots = [eligibility.slots(e) for e in spec["sets"]]
else:
    slots = [WrenchSlots.from_contacts(contact_set_from_dict(d)) for d in spec["sets"]]
threads = {"workers": spec["workers"]} if "workers" in spec else {}  # not in old checkouts
certified_search(minimizer, slots[0], **threads)  # solvers built and kernels compiled first
out = []
for s in slots:
    t = time.perf_counter()
    r = certified_search(minimizer, s, **threads)
    seconds = time.perf_counter() - t
    lo, hi = r.bounds
    width = (hi - lo) / max(abs(lo), tolerance_unit(s))
    out.append([seconds, width, bool(r.converged), getattr(r.stats, "solver", "ipopt")])
    print(json.dumps(out[-1]), flush=True)
"""


def _engine_family(spec: dict, python_path: str, timeout: float) -> list:
    """[seconds, relative width, converged, solver] per set of one family, measured in a
    subprocess with ``python_path`` first; the sets finished when ``timeout`` passes."""
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": python_path}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _ENGINE_RUNNER],
            input=json.dumps(spec),
            capture_output=True,
            text=True,
            env=env,
            cwd=python_path,  # ``python -c`` puts the working folder first on the path
            timeout=timeout,
        ).stdout
    except subprocess.TimeoutExpired as stopped:
        done = stopped.stdout or ""
        done = done.decode() if isinstance(done, bytes) else done
    return [json.loads(line) for line in done.splitlines() if line.startswith("[")]


def _engine_stats(rows: list, cases: int) -> dict:
    if not rows:
        return {"finished": f"0/{cases}"}
    seconds = [r[0] for r in rows]
    return {
        "finished": f"{len(rows)}/{cases}",
        "certified_ms": _stats(1e3 * np.array(seconds)),
        "relative_width_max": float(max(r[1] for r in rows)),
        "converged": f"{sum(r[2] for r in rows)}/{len(rows)}",
        "solvers": sorted({r[3] for r in rows}),
    }


def bench_engine(
    cases: int = 20, seed: int = 0, baseline=None, timeout: float = 300.0, names=None
) -> dict:
    """Certified rho (seed search and certificate) per family, with this checkout's default
    solver in one thread and with two (``two_threads``: a long certificate's rounds dealt to
    both), with ``solver="ipopt"`` and, given ``baseline`` (a checkout's folder, e.g. a
    ``git worktree`` of an earlier commit), with that checkout: each family in its own
    subprocess, one after the other, every solver built and kernel compiled before timing,
    at most ``timeout`` seconds per family and checkout. Medians and ratios run / ours."""
    here = str(Path(__file__).resolve().parents[1])
    runs = {
        "ours": (here, {"minimizer": {}, "workers": 1}),
        "two_threads": (here, {"minimizer": {}, "workers": 2}),
        "ipopt": (here, {"minimizer": {"solver": "ipopt"}, "workers": 1}),
    }
    if baseline is not None:
        runs["baseline"] = (str(Path(baseline).resolve()), {"minimizer": {}})
    report = {"benchmark": "engine", "cases_per_family": cases, "families": {}}
    for name, sets in engine_families(cases, seed).items():
        if names and name not in names:
            continue
        if isinstance(sets, tuple):
            spec = {"kind": "lamp", "sets": sets[1], "models": str(MODELS_DIR)}
        else:
            spec = {"kind": "contacts", "sets": [cs.to_dict() for cs in sets]}
        entry = {}
        for run, (path, how) in runs.items():
            rows = _engine_family({**spec, **how}, path, timeout)
            entry[run] = _engine_stats(rows, len(spec["sets"]))
        for run in ("two_threads", "ipopt", "baseline"):
            if run in entry and "certified_ms" in entry[run] and "certified_ms" in entry["ours"]:
                ratio = (
                    entry[run]["certified_ms"]["median"] / entry["ours"]["certified_ms"]["median"]
                )
                entry[f"ratio_{run}_over_ours"] = float(ratio)
        report["families"][name] = entry
        print(json.dumps({name: entry}), file=sys.stderr, flush=True)  # a long run's progress
    return report


MODELS_DIR = Path(__file__).resolve().parents[1] / "models"

# The paper's examples (section 6): mu = 0.2, mu_s = 0.2 mm, f^U = 1; its reported numbers.
PAPER_EXAMPLES = {
    "lamp": {"type": "pcwf", "m": 4, "heuristic": (19.12, -0.0806), "iterative": (462.82, -0.8654)},
    "cup": {"type": "sfce", "m": 4, "heuristic": (20.86, -0.1124), "iterative": (645.84, -0.3131)},
    "pistol": {
        "type": "fpc",
        "m": 7,
        "heuristic": (32.52, -0.2705),
        "iterative": (704.32, -0.9971),
    },
}


def paper_eligibility(name: str, models_dir=MODELS_DIR) -> Eligibility:
    """The model and contacts of one of the paper's three examples."""
    setup = PAPER_EXAMPLES[name]
    model = load_model(Path(models_dir) / f"{name}.model.json")
    return Eligibility(
        model, contact_specs(setup["m"], type=setup["type"], mu=0.2, mu_s=0.2), torque_scale=1.0
    )


def default_eligibility(model, m: int, kind, mu: float = 0.2) -> Eligibility:
    """``m`` contacts of ``kind`` on ``model`` with the command line's defaults: the automatic
    torque scale and mu_s (from the part's radius)."""
    return Eligibility(model, contact_specs(m, type=kind, mu=mu, model=model), torque_scale="auto")


def bench_rho_hat(cases: int = 20, repeats: int = 3, seed: int = 0, models_dir=MODELS_DIR):
    """ms per rho_hat of 4 random lamp facets with 4 PCwFs, ours against the baseline."""
    eligibility = paper_eligibility("lamp", models_dir)
    rng = np.random.default_rng(seed)
    sets = [rng.integers(0, len(eligibility.model), 4).tolist() for _ in range(cases)]
    eligibility(sets[0])
    ours_ms, base_ms, errors = [], [], []
    for elements in sets:
        found = _timed(ours_ms, repeats, lambda e=elements: eligibility(e))
        base = _timed(base_ms, 1, lambda e=elements: paper_baseline(eligibility.slots(e)))
        errors.append(-found.rho_hat - base)  # > 0: the baseline found a lower value
    return {
        "benchmark": "rho_hat",
        "case": "lamp, 4 random facets, 4 PCwF (mu 0.2)",
        "cases": cases,
        "ours_ms": _stats(ours_ms),
        "baseline_ms": _stats(base_ms),
        "speedup_median": float(np.median(base_ms) / np.median(ours_ms)),
        "worst_ours_above_baseline": float(max(errors)),
    }


def bench_select(seeds: int = 10, models_dir=MODELS_DIR) -> dict:
    """Heuristic and iterative selection on the three example models over ``seeds`` seeds."""
    report = {"benchmark": "select", "seeds": seeds, "models": {}}
    for name, setup in PAPER_EXAMPLES.items():
        eligibility = paper_eligibility(name, models_dir)
        eligibility([0] * setup["m"])  # build the solvers once: we measure reuse
        runs = {"heuristic": [], "iterative": []}
        for seed in range(seeds):
            first = heuristic(eligibility, seed=seed)
            then = iterative(eligibility, first.elements)
            runs["heuristic"].append(first)
            runs["iterative"].append(then)
        entry = {"type": setup["type"], "contacts": setup["m"]}
        for algorithm, results in runs.items():
            values = [r.rho_hat for r in results]
            entry[algorithm] = {
                "seconds": _stats([r.seconds for r in results]),
                "seconds_best": float(min(r.seconds for r in results)),
                "rho_hat_median": float(np.median(values)),
                "rho_hat_best": float(min(values)),
                "eligible_share": float(np.mean([r.eligible for r in results])),
                "evaluations_median": float(np.median([r.evaluations for r in results])),
                "paper_seconds": setup[algorithm][0],
                "paper_rho_hat": setup[algorithm][1],
                "speedup_vs_paper_median": float(
                    setup[algorithm][0] / np.median([r.seconds for r in results])
                ),
            }
        report["models"][name] = entry
    return report


def bench_characterize(subdivisions=(5, 7, 8), noise: float = 0.0) -> dict:
    """Seconds and peak memory of :func:`characterize` on icospheres (20,480, 327,680 and
    1,310,720 faces by default), each in a fresh process so that its peak resident set is its
    own. ``noise`` moves every vertex radially by that fraction of the radius (normal random,
    seeded): a surface cut into thousands of patches and regions, where a cost per patch that
    grows with the mesh shows."""
    import subprocess

    code = (
        "import json, resource, sys, time, numpy as np, trimesh\n"
        "from closure_nlp.model.characterize import characterize\n"
        "mesh = trimesh.creation.icosphere(subdivisions=int(sys.argv[1]))\n"
        "noise = float(sys.argv[2])\n"
        "if noise:\n"
        "    rng = np.random.default_rng(0)\n"
        "    mesh.vertices *= 1 + noise * rng.standard_normal((len(mesh.vertices), 1))\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "t = time.perf_counter()\n"
        "model = characterize(mesh)\n"
        "seconds = time.perf_counter() - t\n"
        "peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "print(json.dumps({'faces': len(mesh.faces), 'noise': noise,\n"
        "    'seconds': round(seconds, 2), 'peak_rss_mb': round(peak / 1024),\n"
        "    'rss_before_mb': round(before / 1024), 'elements': model.counts()}))\n"
    )
    runs = []
    for sub in subdivisions:
        out = subprocess.run(
            [sys.executable, "-c", code, str(sub), repr(float(noise))],
            capture_output=True,
            text=True,
            check=True,
        )
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {"work": "characterize an icosphere (default options)", "load": load, "runs": runs}


def bench_model_size(subdivisions=(3, 4, 5), repeats: int = 3) -> dict:
    """``eligibility`` and ``select`` (4 PCwF, seed 0) through the CLI on models of every facet
    of an icosphere (1,280, 5,120 and 20,480 facets by default), each run in a fresh process
    (what a user's command costs, nothing kept from a former run): medians of ``repeats``, and
    each size's seconds per element against the smallest's (1.0: linear)."""
    import subprocess
    import tempfile

    import trimesh

    from closure_nlp.model.elements import Element, Model, save_model

    code = (
        "import contextlib, io, json, sys, time\n"
        "t = time.perf_counter()\n"
        "from closure_nlp.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    code = main(sys.argv[1:])\n"
        "print(json.dumps({'code': code, 'seconds': time.perf_counter() - t}))\n"
    )
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        for sub in subdivisions:
            mesh = trimesh.creation.icosphere(subdivisions=sub)
            elements = tuple(
                Element("facet", mesh.vertices[f], -mesh.face_normals[k], name=f"elements[{k}]")
                for k, f in enumerate(mesh.faces)
            )
            pairs = tuple(sorted({tuple(sorted(p)) for p in mesh.face_adjacency.tolist()}))
            path = Path(folder) / f"sphere{sub}.model.json"
            mesh.export(Path(folder) / f"sphere{sub}.stl")
            save_model(Model(elements, pairs, mesh=f"sphere{sub}.stl"), path)
            row = {"elements": len(elements)}
            for command, extra in (
                ("eligibility", ["--elements", "0,1,2,3"]),
                ("select", ["--contacts", "4", "--seed", "0"]),
            ):
                argv = [command, str(path), "--type", "pcwf", "--json", *extra]
                times = []
                for _ in range(repeats):
                    out = subprocess.run(
                        [sys.executable, "-c", code, *argv],
                        capture_output=True,
                        text=True,
                        check=True,
                    )
                    answer = json.loads(out.stdout.strip().splitlines()[-1])
                    if answer["code"] != 0:
                        raise RuntimeError(f"{command} on {len(elements)} facets: {out.stderr}")
                    times.append(answer["seconds"])
                row[f"{command}_s"] = round(float(np.median(times)), 3)
            runs.append(row)
    for row in runs:
        for command in ("eligibility", "select"):
            per = row[f"{command}_s"] / row["elements"]
            row[f"{command}_per_element_vs_smallest"] = round(
                per / (runs[0][f"{command}_s"] / runs[0]["elements"]), 3
            )
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {
        "work": "eligibility and select (4 PCwF) via the CLI on icosphere facet models",
        "load": load,
        "runs": runs,
    }


# The exhaustive options (full search for every neighbour, every neighbour-move trial to the full
# budget, the default search in every exchange round, no check at a run's end): the baseline
# that ``bench plan`` runs in the same process, on the same solvers, for its ratios; and the
# faster placement options. Not in the baseline (no option restores them): the start's
# certificate deferred to when it is needed, the linear exchange NLP of frictionless contacts,
# the faster support evaluation of FPC and element slots, the neighbour-move trials skipped
# because they provably cannot win, and the search's budget counted in basins.
BASELINE_SELECTION = SelectionOptions(screen=False)
BASELINE_PLACEMENT = PlacementOptions(move_rounds=0, round_search=False, validate=False)
FAST_PLACEMENT = PlacementOptions(screen=True, probe_rounds=6)


def bench_plan(seeds: int = 3, models_dir=MODELS_DIR, names=None) -> dict:
    """``plan`` on each example model over ``seeds`` seeds: the default options (``current``),
    with :data:`FAST_PLACEMENT` (``fast``) and the baseline (:data:`BASELINE_SELECTION`,
    :data:`BASELINE_PLACEMENT`); medians of each step's seconds, rho, and the ratios baseline /
    current and baseline / fast. Solvers are built and warmed up first (one
    plan of each kind on another seed), and the order of the two alternates over the seeds."""
    modes = {
        "current": (SelectionOptions(), PlacementOptions()),
        "fast": (SelectionOptions(), FAST_PLACEMENT),
        "baseline": (BASELINE_SELECTION, BASELINE_PLACEMENT),
    }
    report = {"benchmark": "plan", "seeds": seeds, "models": {}}
    for name in names or PAPER_EXAMPLES:
        setup = PAPER_EXAMPLES[name]
        eligibility = paper_eligibility(name, models_dir)
        placers = {k: Placer(eligibility, p) for k, (_, p) in modes.items()}
        for k, (selection, _) in modes.items():  # warm-up: every NLP shape built
            plan(eligibility, seeds=1, seed=seeds + 100, selection=selection, placer=placers[k])
        runs = {k: [] for k in modes}
        for seed in range(seeds):
            order = list(modes)[seed % 3 :] + list(modes)[: seed % 3]  # rotate the order
            for k in order:
                t0 = time.perf_counter()
                result = plan(
                    eligibility,
                    seed=seed,
                    seeds=1,
                    selection=modes[k][0],
                    placer=placers[k],
                    alternatives=0,
                )
                runs[k].append((result, time.perf_counter() - t0))
        entry = {"type": setup["type"], "contacts": setup["m"]}
        for k, results in runs.items():
            entry[k] = {
                "total_s": float(np.median([s for _, s in results])),
                "heuristic_s": float(np.median([r.heuristic.seconds for r, _ in results])),
                "iterative_s": float(np.median([r.iterative.seconds for r, _ in results])),
                "placement_s": float(np.median([r.placement.seconds for r, _ in results])),
                "iterative_evaluations": float(
                    np.median([r.iterative.evaluations for r, _ in results])
                ),
                "placement_rounds": float(np.median([r.placement.rounds for r, _ in results])),
                "rho_median": float(np.median([r.placement.rho for r, _ in results])),
                "force_closure_share": float(
                    np.mean([r.placement.force_closure for r, _ in results])
                ),
                "total_s_each": [s for _, s in results],
            }
        for mode in ("current", "fast"):
            for step in ("total_s", "iterative_s", "placement_s"):
                entry[f"ratio_{step}_{mode}"] = entry["baseline"][step] / entry[mode][step]
        pairs = list(zip(runs["current"], runs["baseline"]))
        entry["same_selection_share"] = float(
            np.mean([a.iterative.elements == b.iterative.elements for (a, _), (b, _) in pairs])
        )
        report["models"][name] = entry
    return report


# The fixture study's 7-FPC groups (examples/studies/fixtures.toml: f_max 1, torque scale 1,
# placement starts 2) and the best rho of its 20 seeds.
FIXTURE_TARGETS = {
    "pistol": ("models/pistol.model.json", -0.6494),
    "stepped_shaft": ("examples/studies/models/stepped_shaft.model.json", -0.7125),
}


# One process per checkout: the command line's plan options for one example, every solver built
# and kernel compiled by a plan on another seed first; then one JSON line per seed read on stdin.
_PLANS_RUNNER = """
import json, sys, time
from closure_nlp.cli import main as cli
from closure_nlp.cli import setup
from closure_nlp.placement.place import Placer
from closure_nlp.planning.plan import plan
argv = json.loads(sys.argv[1])
args = cli.build_parser().parse_args(argv)
eligibility = setup.model_eligibility(args, args.contacts, closure=True)
placer = Placer(eligibility, setup.placement_options(args, False))
plan(eligibility, seed=1000, placer=placer)
print("ready", flush=True)
for line in sys.stdin:
    t = time.perf_counter()
    r = plan(eligibility, seeds=1, seed=int(line), placer=placer)
    wall = time.perf_counter() - t
    p = r.placement
    print(json.dumps({
        "wall_s": wall,
        "selection_s": r.heuristic.seconds + r.iterative.seconds,
        "placement_s": p.seconds,
        "ceiling_s": getattr(p, "bound_seconds", 0.0),
        "rho": p.rho,
        "force_closure": bool(p.force_closure),
        "rounds": p.rounds,
        "attempts": len(r.attempts),
        "ceiling": getattr(p, "capacity_bound", None),
    }), flush=True)
"""

# The command lines of ``bench plans``: each example as the README plans it (CLI defaults,
# automatic torque scale, mu 0.2, mu_s 0.2 as in the paper), one seed at a time.
PLANS_ARGV = {
    name: ["--contacts", str(setup["m"]), "--type", setup["type"], "--mu", "0.2", "--mu-s", "0.2"]
    for name, setup in PAPER_EXAMPLES.items()
}


def bench_plans(seeds=(1, 2, 3), baseline=None, names=None, extra=()) -> dict:
    """The command line's default plan of one seed on each example (:data:`PLANS_ARGV`, plus
    ``extra`` flags): wall seconds, the selection's, the placement's and its ceiling's, and rho,
    medians over ``seeds``. Each checkout (this one; ``baseline``, another checkout's folder,
    e.g. a ``git worktree`` of an earlier commit) runs in its own process, its solvers built and
    kernels compiled first; the seeds alternate between them (the order swapped every seed), so
    both see the same load. Ratios baseline / ours."""
    import subprocess

    here = str(Path(__file__).resolve().parents[1])
    checkouts = {"ours": here}
    if baseline is not None:
        checkouts["baseline"] = str(Path(baseline).resolve())
    report = {"benchmark": "plans", "seeds": list(seeds), "load_before": _load(), "models": {}}
    for name in names or PAPER_EXAMPLES:
        argv = ["plan", str(MODELS_DIR / f"{name}.model.json"), *PLANS_ARGV[name], *extra]
        procs = {}
        for run, path in checkouts.items():
            procs[run] = subprocess.Popen(
                [sys.executable, "-c", _PLANS_RUNNER, json.dumps(argv)],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                env={**os.environ, "PYTHONPATH": path, "MPLBACKEND": "Agg"},
                cwd=path,  # ``python -c`` puts the working folder first on the path
            )
        rows = {run: [] for run in checkouts}
        try:
            for proc in procs.values():
                if proc.stdout.readline().strip() != "ready":
                    raise RuntimeError(f"bench plans: a runner for {name} did not start")
            for i, seed in enumerate(seeds):
                order = list(procs) if i % 2 == 0 else list(procs)[::-1]
                for run in order:
                    procs[run].stdin.write(f"{seed}\n")
                    procs[run].stdin.flush()
                    rows[run].append(json.loads(procs[run].stdout.readline()))
        finally:
            for proc in procs.values():
                proc.stdin.close()
                proc.wait()
        entry = {}
        for run, found in rows.items():
            entry[run] = {
                key: float(np.median([r[key] for r in found]))
                for key in ("wall_s", "selection_s", "placement_s", "ceiling_s", "rho")
            }
            entry[run]["rho_each"] = [r["rho"] for r in found]
            entry[run]["force_closure"] = sum(r["force_closure"] for r in found)
        if "baseline" in entry:
            for key in ("wall_s", "placement_s"):
                entry[f"ratio_{key}_baseline_over_ours"] = (
                    entry["baseline"][key] / entry["ours"][key]
                )
        report["models"][name] = entry
        print(json.dumps({name: entry}), file=sys.stderr, flush=True)  # a long run's progress
    report["load_after"] = _load()
    return report


STARTUP_COMMAND = "rho examples/box_7fpc.contacts.json"
_COMPILED_LINE = "compiled the numeric kernels in "


def _cli_run(
    python_path: str, args: list, env: dict, tty: bool, timeout: float, stdout: bool = False
) -> dict:
    """One ``python -m closure_nlp.cli.main`` subprocess with ``python_path`` first: its wall and
    CPU
    seconds (the children's rusage), exit status and stderr (through a pseudo-terminal when
    ``tty``: the compile notice is shown on terminals only), and with ``stdout`` its stdout."""
    import resource
    import subprocess

    master = slave = None
    if tty:
        import pty

        master, slave = pty.openpty()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "closure_nlp.cli", *args],
        stdout=subprocess.PIPE if stdout else subprocess.DEVNULL,
        stderr=slave if tty else subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": python_path, **env},
        cwd=python_path,
        timeout=timeout,
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if tty:
        os.close(slave)
        chunks = []
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the terminal's other end is closed and drained
                break
            if not chunk:
                break
            chunks.append(chunk)
        os.close(master)
        stderr = b"".join(chunks).decode(errors="replace").replace("\r\n", "\n")
    else:
        stderr = done.stderr.decode(errors="replace")
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    out = done.stdout.decode(errors="replace") if stdout else None
    return {"wall": wall, "cpu": cpu, "status": done.returncode, "stderr": stderr, "stdout": out}


def _startup_checkout(python_path: str, argv: list, cache: str, timeout: float) -> dict:
    """The cold run of one checkout: a fresh numba cache, the command line on a terminal."""
    run = _cli_run(python_path, argv, {"NUMBA_CACHE_DIR": cache}, True, timeout)
    lines = [line for line in run["stderr"].splitlines() if "numeric kernels" in line]
    said = [line for line in lines if line.startswith(_COMPILED_LINE)]
    reported = float(said[0][len(_COMPILED_LINE) :].split()[0]) if len(said) == 1 else None
    return {
        "cold_wall_s": run["wall"],
        "cold_cpu_s": run["cpu"],
        "exit_status": run["status"],
        "notice_lines": lines,  # "compiling ..." then "compiled ... in X s", once
        "notice_seconds": reported,
    }


def bench_startup(
    repeats: int = 5, baseline=None, timeout: float = 1800.0, command: str = STARTUP_COMMAND
) -> dict:
    """Start-up of ``closure-nlp COMMAND`` (default :data:`STARTUP_COMMAND`; its paths relative
    to each checkout): cold (a fresh ``NUMBA_CACHE_DIR``, so every kernel compiles; run on a
    pseudo-terminal, where the CLI says that it compiles and how long) and warm (the same
    command again, the kernels from that cache; median wall and CPU seconds of ``repeats``
    runs). Each run is its own process; given ``baseline`` (another checkout's folder) the same
    for it, the warm runs alternating."""
    import shlex
    import tempfile

    argv = shlex.split(command)
    runs = {"ours": str(Path(__file__).resolve().parents[1])}
    if baseline is not None:
        runs["baseline"] = str(Path(baseline).resolve())
    report = {"load_before": _load(), "command": command}
    with tempfile.TemporaryDirectory() as folder:
        caches = {name: str(Path(folder) / name) for name in runs}
        for name, path in runs.items():
            report[name] = _startup_checkout(path, argv, caches[name], timeout)
            print(json.dumps({name: report[name]}), file=sys.stderr, flush=True)
        warm = {name: [] for name in runs}
        for _ in range(repeats):
            for name, path in runs.items():
                env = {"NUMBA_CACHE_DIR": caches[name]}
                run = _cli_run(path, argv, env, False, timeout)
                if run["status"] != 0:
                    raise RuntimeError(f"{name}: exit {run['status']}: {run['stderr'][-300:]}")
                warm[name].append(run)
    for name in runs:
        report[name]["warm_wall_s"] = _stats([r["wall"] for r in warm[name]])
        report[name]["warm_cpu_s"] = _stats([r["cpu"] for r in warm[name]])
    if baseline is not None:
        report["ratios"] = {  # baseline / ours: above 1, ours starts faster
            "cold_cpu": report["baseline"]["cold_cpu_s"] / report["ours"]["cold_cpu_s"],
            "warm_wall_median": report["baseline"]["warm_wall_s"]["median"]
            / report["ours"]["warm_wall_s"]["median"],
        }
    report["load_after"] = _load()
    return report


BATCH_TYPES = ["pcwf"] * 4


def bench_batch(files: int = 200, repeats: int = 3, timeout: float = 600.0) -> dict:
    """Certified rho of many files through the command line: ``closure-nlp rho --json --quiet``
    on ``files`` random 4-PCwF contact sets (seeds 0, 1, ...) in one process, and on the first
    of them alone (a one-file run: the start), alternating, ``repeats`` times each, the kernels
    from this checkout's cache. Per file: the median wall (and CPU) of all less that of one,
    over ``files - 1``; the answers' own ``seconds`` (every run's answers, and the force-closure
    sets' and the others' apart); how many brackets converged."""
    import tempfile

    here = str(Path(__file__).resolve().parents[1])
    report = {"benchmark": "batch", "files": files, "repeats": repeats, "load_before": _load()}
    runs = {"one": [], "all": []}
    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for k in range(files):
            contact_set = random_contact_set(np.random.default_rng(k), BATCH_TYPES)
            paths.append(str(Path(folder) / f"s{k:04d}.contacts.json"))
            Path(paths[-1]).write_text(json.dumps(contact_set.to_dict()))
        for _ in range(repeats):
            for name, chosen in (("one", paths[:1]), ("all", paths)):
                argv = ["rho", "--json", "--quiet", *chosen]
                run = _cli_run(here, argv, {}, False, timeout, stdout=True)
                if run["status"] != 0:
                    raise RuntimeError(f"rho: exit {run['status']}: {run['stderr'][-300:]}")
                runs[name].append(run)
    answers = [json.loads(line) for run in runs["all"] for line in run["stdout"].splitlines()]
    for name, done in runs.items():
        report[name] = {
            "wall_s": _stats([r["wall"] for r in done]),
            "cpu_s": _stats([r["cpu"] for r in done]),
        }
    for key in ("wall", "cpu"):  # none from a single file: its run is the start's
        whole, one = (float(np.median([r[key] for r in runs[n]])) for n in ("all", "one"))
        report[f"per_file_{key}_ms"] = 1e3 * (whole - one) / (files - 1) if files > 1 else None
    closure = [a["force_closure"] for a in answers]
    parts = {
        "all": answers,
        "force_closure": [a for a, c in zip(answers, closure) if c],
        "others": [a for a, c in zip(answers, closure) if not c],
    }
    report["answer_ms"] = {
        name: _stats([1e3 * a["seconds"] for a in part]) for name, part in parts.items() if part
    }
    report["force_closure"] = f"{sum(closure) // repeats}/{files}"
    report["converged"] = f"{sum(a['converged'] for a in answers)}/{len(answers)}"
    report["load_after"] = _load()
    return report


def _load() -> float:
    import os

    return float(os.getloadavg()[0])


def _seed_entry(result, wall: float) -> dict:
    spread = result.seeds.to_dict()
    rhos = [r["rho"] for r in spread["runs"] if "rho" in r]
    return {
        "wall_s": wall,
        "seeds_run": spread["run"],
        "workers": spread["workers"],
        "chosen_seed": spread["chosen_seed"],
        "seeds_each": [r["seed"] for r in spread["runs"] if "rho" in r],
        "best_rho": spread["best_rho"],
        "single_seed_median_rho": float(np.median(rhos)),
        "worst_rho": spread["worst_rho"],
        "force_closure": spread["force_closure"],
        "marginal": spread["marginal"],
        "failed": spread["failed"],
        "memo_reuses": sum(len(r.get("reused", [])) for r in spread["runs"]),
        "element_sets": len(spread["element_sets"]),
        "rho_each": rhos,
    }


def _spin(n: int) -> int:
    total = 0
    for i in range(n):
        total += i * i
    return total


def control_speedup(workers: int, tasks: int = 8, n: int = 4_000_000) -> dict:
    """The machine's parallelism now: ``tasks`` equal pure-Python loops one by one, then over
    ``workers`` forked processes (how the seeds run). Whatever the code, the seeds cannot run
    faster in parallel than this ratio: under Linux's autogroup scheduling, a busy session of
    another user takes its share of the cores from all of this session's processes together."""
    import multiprocessing

    load = _load()
    t0 = time.perf_counter()
    for _ in range(tasks):
        _spin(n)
    serial = time.perf_counter() - t0
    t0 = time.perf_counter()
    with multiprocessing.get_context("fork").Pool(workers) as pool:
        pool.map(_spin, [n] * tasks, chunksize=1)
    parallel = time.perf_counter() - t0
    return {
        "workers": workers,
        "serial_s": serial,
        "parallel_s": parallel,
        "speedup": serial / parallel,
        "load_before": load,
        "load_after": _load(),
    }


def bench_seeds(
    seeds: int = 8,
    root=MODELS_DIR.parent,
    parts=("efficiency", "fixtures", "examples"),
    efficiency_model: str = "lamp",
) -> dict:
    """Plans of several seeds. ``efficiency``: ``seeds`` seeds of one example one by one
    (one process, one memo) and over the available cores, in the same run; the ratio of their
    wall times, with the load before and after, and ``control`` (:func:`control_speedup` right
    after: the parallelism the machine offered). ``fixtures``: the command line's default plan
    (:data:`~closure_nlp.planning.seeds.DEFAULT_SEEDS` seeds,
    :data:`~closure_nlp.planning.seeds.DEFAULT_BUDGET`)
    on the fixture study's pistol and stepped shaft 7-FPC groups, against the study's best of
    20 seeds. ``examples``: best of ``seeds`` against the median single seed of the same runs,
    on the three examples (the bench plan setting)."""
    from closure_nlp.base.cores import available_cores
    from closure_nlp.planning.seeds import DEFAULT_BUDGET, DEFAULT_SEEDS

    root = Path(root)
    report = {"benchmark": "seeds", "seeds": seeds, "cores": available_cores()}
    if "efficiency" in parts:
        eligibility = paper_eligibility(efficiency_model, root / "models")
        entry = {"model": efficiency_model, "load_before": _load()}
        for mode, workers in (("serial", 1), ("parallel", available_cores())):
            t0 = time.perf_counter()
            result = plan(eligibility, seed=0, seeds=seeds, workers=workers)
            entry[mode] = _seed_entry(result, time.perf_counter() - t0)
            entry[f"load_after_{mode}"] = _load()
        entry["same_answer"] = entry["serial"]["rho_each"] == entry["parallel"]["rho_each"]
        entry["speedup"] = entry["serial"]["wall_s"] / entry["parallel"]["wall_s"]
        entry["control"] = control_speedup(available_cores())
        entry["speedup_over_control"] = entry["speedup"] / entry["control"]["speedup"]
        report["efficiency"] = entry
    if "fixtures" in parts:
        report["fixtures"] = {}
        for name, (path, study_best) in FIXTURE_TARGETS.items():
            model = load_model(root / path)
            eligibility = Eligibility(model, contact_specs(7, type="fpc"), torque_scale=1.0)
            load = _load()
            t0, cpu = time.perf_counter(), _cpu_seconds()
            result = plan(
                eligibility,
                seed=0,
                seeds=DEFAULT_SEEDS,
                budget=DEFAULT_BUDGET,
                placement=PlacementOptions(starts=2),
            )
            entry = _seed_entry(result, time.perf_counter() - t0)
            entry.update(
                cpu_s=_cpu_seconds() - cpu,  # this process's and its workers'
                load_before=load,
                load_after=_load(),
                study_best_rho=study_best,
                within_10_percent=bool(result.placement.rho <= 0.9 * study_best),
                within_10_s=bool(entry["wall_s"] <= 10.0),
                budget_s=DEFAULT_BUDGET,
            )
            report["fixtures"][name] = entry
    if "examples" in parts:
        report["examples"] = {}
        for name in PAPER_EXAMPLES:
            if name == efficiency_model and "efficiency" in report:  # the same runs
                report["examples"][name] = report["efficiency"]["parallel"]
                continue
            eligibility = paper_eligibility(name, root / "models")
            load = _load()
            t0 = time.perf_counter()
            result = plan(eligibility, seed=0, seeds=seeds)
            entry = _seed_entry(result, time.perf_counter() - t0)
            entry.update(load_before=load, load_after=_load())
            report["examples"][name] = entry
    return report


GAP_BUDGETS = {"lamp": 30.0, "cup": 30.0, "pistol": 60.0}


def _gap_run(placer, elements, exchange, budget: float, **settings) -> dict:
    """One search of the ceiling for ``bench_gap``: its JSON entry."""
    from closure_nlp.placement.ceiling import BoundOptions, capacity_bound, relative_gap

    load = _load()
    found = capacity_bound(
        placer,
        elements,
        exchange,
        BoundOptions(gap=0.0, time_budget=budget, **settings),
    )
    reached = {}
    for target in (0.05, 0.02, 0.01):
        times = [t for t, c, best, _ in found.history if (relative_gap(c, best) or 1) <= target]
        reached[f"seconds_to_{target:g}"] = times[0] if times else None
    return {
        "exchange_gap": relative_gap(found.value, -exchange.bounds[1]),
        "final_rho": exchange.rho if found.placement is None else found.placement.rho,
        "improvement": (found.capacity + exchange.bounds[1]) / -exchange.bounds[1],
        "root_bound": found.root_value,
        "capacity_bound": found.value,
        "gap": found.gap,
        "nodes": found.nodes,
        "open_cells": found.open_cells,
        "polishes": found.polishes,
        "seconds": found.seconds,
        **reached,
        "load_before": load,
        "load_after": _load(),
    }


# The ceiling's exhaustive settings, for a comparison in the same process (bench gap --compare):
# every exchange run the schedule asks for, every working-set direction a row of every cell's
# LP (the LP solver itself is the same in both runs).
EXHAUSTIVE_BOUND = {"polish_share": 1.0, "lp_rows": 0}


def bench_gap(
    names=None,
    seed: int = 1,
    neighbours: bool = False,
    models_dir=MODELS_DIR,
    compare: bool = False,
    budgets=None,
) -> dict:
    """The certified gap of the exchange method's placement on each example's selected elements
    (``plan`` with ``seed``; CLI defaults: automatic torque scale and mu_s, mu 0.2), then the
    ceiling's branch and bound for :data:`GAP_BUDGETS` seconds (target gap 0: it runs the whole
    budget, and the time at which 2% and 5% were reached is reported). ``neighbours``: the
    ceiling covers the neighbours of each element as well (the default placement's domain).
    ``compare``: the same search with :data:`EXHAUSTIVE_BOUND` too, in the same process, right
    after (``exhaustive`` in each model's entry)."""
    budgets = {**GAP_BUDGETS, **(budgets or {})}
    report = {"benchmark": "gap", "seed": seed, "neighbours": neighbours, "models": {}}
    for name in names or PAPER_EXAMPLES:
        setup = PAPER_EXAMPLES[name]
        model = load_model(Path(models_dir) / f"{name}.model.json")
        eligibility = default_eligibility(model, setup["m"], setup["type"])
        moves = 20 if neighbours else 0
        placer = Placer(eligibility, PlacementOptions(bound=False, neighbour_moves=moves))
        planned = plan(eligibility, seeds=1, seed=seed, placer=placer, alternatives=0)
        exchange = planned.placement
        budget = budgets.get(name, 30.0)

        entry = {
            "type": setup["type"],
            "contacts": setup["m"],
            "elements": list(planned.iterative.elements),
            "exchange_rho": exchange.rho,
            "exchange_seconds": exchange.seconds,
            **_gap_run(placer, planned.iterative.elements, exchange, budget),
        }
        if compare:
            entry["exhaustive"] = _gap_run(
                placer, planned.iterative.elements, exchange, budget, **EXHAUSTIVE_BOUND
            )
        report["models"][name] = entry
    return report


# Contact sets of every type the default placement's gap is measured on (bench gap --family):
# 3 and 4 contacts with friction, 7 frictionless (fewer are never force closure).
GAP_FAMILY = (("pcwf", 3), ("pcwf", 4), ("sfcl", 3), ("sfcl", 4), ("sfce", 3), ("sfce", 4))
GAP_FAMILY_FRICTIONLESS = (("fpc", 7),)


def bench_gap_family(
    names=None, seed: int = 1, variants=None, models_dir=MODELS_DIR, mu: float = 0.5
) -> dict:
    """The default placement's certified gap on contact sets of every type (:data:`GAP_FAMILY`,
    mu ``mu``; 7 FPC on the pistol) on each example: one plan of ``seed`` per set (automatic
    torque scale), its placement's gap and seconds under each of ``variants`` (name ->
    PlacementOptions keyword arguments; default: the defaults alone), in the same process, so
    that their times compare at the same load."""
    variants = variants or {"default": {}}
    report = {"benchmark": "gap-family", "seed": seed, "mu": mu, "rows": []}
    for name in names or PAPER_EXAMPLES:
        model = load_model(Path(models_dir) / f"{name}.model.json")
        family = GAP_FAMILY + (GAP_FAMILY_FRICTIONLESS if name == "pistol" else ())
        for kind, m in family:
            eligibility = default_eligibility(model, m, kind, mu)
            row = {"model": name, "type": kind, "contacts": m}
            for label, settings in variants.items():
                placer = Placer(eligibility, PlacementOptions(**settings))
                load = _load()
                t0 = time.perf_counter()
                placed = plan(eligibility, seeds=1, seed=seed, placer=placer).placement
                row[label] = {
                    "rho": placed.rho,
                    "capacity_bound": placed.capacity_bound,
                    "gap": placed.gap,
                    "gap_reached": placed.gap_reached,
                    "bound_nodes": placed.bound_nodes,
                    "bound_seconds": placed.bound_seconds,
                    "placement_seconds": placed.seconds,
                    "plan_seconds": time.perf_counter() - t0,
                    "load": load,
                }
            report["rows"].append(row)
    for label in variants:
        gaps = [r[label]["gap"] for r in report["rows"] if r[label]["gap"] is not None]
        bound = [r[label]["bound_seconds"] for r in report["rows"]]
        report[f"{label}_gap_median"] = float(np.median(gaps)) if gaps else None
        report[f"{label}_gap_max"] = max(gaps) if gaps else None
        report[f"{label}_bound_seconds_median"] = float(np.median(bound))
    return report


def bench_part_ceiling(
    names=None, seeds: int = 8, cells: int = 200, budget: float = 600.0, models_dir=MODELS_DIR
) -> dict:
    """The certified ceiling on any placement anywhere on each example (every element set:
    :func:`~closure_nlp.placement.ceiling.part_ceiling`) after at most ``cells`` cells or
    ``budget`` seconds, against the default plan of ``seeds`` seeds (CLI defaults: mu 0.2,
    automatic torque scale and mu_s): the plan's gap to the best possible on the whole part."""
    from closure_nlp.placement.ceiling import BoundOptions, part_ceiling

    report = {"benchmark": "part-ceiling", "seeds": seeds, "cells": cells, "models": {}}
    for name in names or PAPER_EXAMPLES:
        setup = PAPER_EXAMPLES[name]
        model = load_model(Path(models_dir) / f"{name}.model.json")
        eligibility = default_eligibility(model, setup["m"], setup["type"])
        t0 = time.perf_counter()
        planned = plan(eligibility, seed=0, seeds=seeds).placement
        plan_seconds = time.perf_counter() - t0
        load = _load()
        options = BoundOptions(gap=0.0, time_budget=budget, max_nodes=cells)
        found = part_ceiling(Placer(eligibility, PlacementOptions()), planned, options)
        report["models"][name] = {
            "type": setup["type"],
            "contacts": setup["m"],
            "plan_rho": planned.rho,
            "plan_seconds": plan_seconds,
            "plan_elements_ceiling": planned.capacity_bound,
            "part_root_bound": found.root_value,
            "part_ceiling": found.value,
            "gap": found.gap,
            "cells": found.nodes,
            "seconds": found.seconds,
            "load_before": load,
            "load_after": _load(),
        }
    return report


UNITS_GRASPS = {"4 PCwF": (4, "pcwf"), "7 FPC": (7, "fpc")}


def bench_units(
    margins=(0.0, 0.02, 0.05), seed: int = 0, cells: int = 200, lp_centre: bool = False
) -> dict:
    """Same part, same answer: pybullet's domino characterized in metres and, from the same
    triangles scaled x1000, in millimetres; elements selected once (``plan`` in metres, seed
    ``seed``), then placed in both units on those elements (no neighbour moves; automatic
    torque scale and mu_s, mu 0.2) with the ceiling over them for ``cells`` cells or a 2%
    gap (a budget of cells, not seconds: the same work in both units, whatever the load),
    under margins of ``margins`` times the part's size (the largest side of its bounding box).
    Each pair's certified capacities must differ by at most the larger gap times the smaller
    ceiling (``agree``); ``work`` compares the exchange rounds, cells and seconds of the two
    units (mm over m); ``lp_centre``: placed with
    :attr:`~closure_nlp.placement.options.PlacementOptions.lp_centre`. Needs pybullet's data
    (``pybullet_data``)."""
    import trimesh

    from closure_nlp.model.characterize import characterize_mesh
    from closure_nlp.model.elements import part_size
    from closure_nlp.model.scale import resolve
    from closure_nlp.placement.margin import with_margin

    try:
        import pybullet_data
    except ImportError:
        return {"benchmark": "units", "skipped": "pybullet_data is not installed"}
    path = Path(pybullet_data.getDataPath()) / "domino" / "domino.obj"
    models = {}
    for units, factor in (("m", 1.0), ("mm", 1000.0)):
        mesh = trimesh.load(str(path), force="mesh")
        mesh.apply_scale(factor)
        models[units] = characterize_mesh(mesh, units=units, name="domino").model
    report = {
        "benchmark": "units",
        "part": "pybullet domino",
        "seed": seed,
        "lp_centre": lp_centre,
        "grasps": {},
    }
    for grasp, (m, kind) in UNITS_GRASPS.items():
        rows = []
        elements = None
        for margin in margins:
            row = {"margin": margin}
            for units, model in models.items():
                size = part_size(model.elements)
                shrunk, dropped = with_margin(model, margin * size)
                scale = resolve(model)
                specs = contact_specs(m, type=kind, mu_s=scale.mu_s)
                eligibility = Eligibility(shrunk, specs, scale.torque_scale)
                if elements is None:
                    elements = list(plan(eligibility, seeds=1, seed=seed).iterative.elements)
                if any(e in dropped for e in elements):
                    row[units] = {"error": "an element is too small for the margin"}
                    continue
                load, t0 = _load(), time.perf_counter()
                options = PlacementOptions(
                    neighbour_moves=0, bound_cells=cells, lp_centre=lp_centre
                )
                placed = Placer(eligibility, options)(elements)
                row[units] = {
                    "rounds": placed.rounds,
                    "margin_length": margin * size,
                    "exchange_rho": placed.exchange_rho,
                    "rho": placed.rho,
                    "capacity": -placed.bounds[1],
                    "capacity_bound": placed.capacity_bound,
                    "gap": placed.gap,
                    "bound_nodes": placed.bound_nodes,
                    "seconds": time.perf_counter() - t0,
                    "load": load,
                }
            a, b = row.get("m", {}), row.get("mm", {})
            if a.get("gap") is not None and b.get("gap") is not None:
                allowed = max(a["gap"], b["gap"]) * min(a["capacity_bound"], b["capacity_bound"])
                larger = max(a["capacity"], b["capacity"])
                difference = abs(a["capacity"] - b["capacity"])
                row["difference"] = difference / larger
                row["agree"] = bool(difference <= allowed + 1e-6 * larger)
            if "rounds" in a and "rounds" in b:
                row["work"] = {
                    key: b[key] / a[key] if a[key] else None
                    for key in ("rounds", "bound_nodes", "seconds")
                }
            rows.append(row)
        report["grasps"][grasp] = {"elements": elements, "rows": rows}
    return report


# pybullet_data's meshes (metres) that ``bench real-meshes`` plans on, with the characterize
# flags each needs; and the contact mixes planned on each.
REAL_MESHES = {
    "duck": ("duck.obj", []),
    "bunny": ("bunny.obj", []),
    "soccerball": ("soccerball.obj", []),
    "cube": ("cube.obj", []),
    "sphere_smooth": ("sphere_smooth.obj", []),
    "teddy": ("teddy2_VHACD_CHs.obj", ["--merge-bodies"]),
}
# Meshes no default was chosen with (``--meshes held-out``): what the tool does on parts unseen.
HELD_OUT_MESHES = {
    "mug": ("objects/mug.obj", []),
    "domino": ("domino/domino.obj", []),
    "jenga": ("jenga/jenga.obj", []),
    "lego": ("lego/lego.obj", []),
    "random_002": ("random_urdfs/002/002.obj", ["--merge-bodies"]),
    "random_003": ("random_urdfs/003/003.obj", ["--merge-bodies"]),
}
REAL_MIXES = {
    "4 pcwf": ["--contacts", "4", "--type", "pcwf", "--mu", "0.5"],
    "3 sfce": ["--contacts", "3", "--type", "sfce", "--mu", "0.5"],
}


def _cli_json(argv: list) -> tuple[int, dict | None, float, float]:
    """``closure-nlp ARGV --json --quiet`` in this process: exit status, its JSON (None when it
    printed none), wall seconds and CPU seconds of this process and of the worker processes
    it ran (what the load of a shared machine moves least)."""
    import contextlib
    import io

    from closure_nlp.cli.main import main as cli_main

    out, err = io.StringIO(), io.StringIO()
    t, cpu = time.perf_counter(), _cpu_seconds()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli_main([*argv, "--json", "--quiet"])
    wall, cpu = time.perf_counter() - t, _cpu_seconds() - cpu
    text = out.getvalue().strip()
    found = json.loads(text.splitlines()[-1]) if text else None
    if found is None and err.getvalue():
        found = {"error": err.getvalue().strip().splitlines()[-1][:200]}
    return status, found, wall, cpu


def _cpu_seconds() -> float:
    """CPU seconds of this process and of its child processes that have ended (a plan's
    workers end with it)."""
    import resource

    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def bench_real_meshes(names=None, seed: int = 0, seeds: int = 1, data_path=None, extra=()) -> dict:
    """Characterize and plan on pybullet's meshes as a new user would: ``closure-nlp
    characterize MESH`` (default options; :data:`REAL_MESHES` gives the flags each needs), then
    ``closure-nlp plan`` of each contact mix of :data:`REAL_MIXES` (``seeds`` seeds from
    ``seed``, ``extra`` flags), in this process (kernels compiled before). Per mesh: the
    elements and repairs; per plan: its exit status, verdicts, rho, robust_rho, gap, the plan's
    own seconds, the wall time of the command and this process's CPU seconds in it (a shared
    machine's load moves the wall time by a factor of several, the CPU time far less). Meshes
    it cannot find are listed under ``skipped`` (pybullet's data is not a dependency:
    ``data_path``, or ``pybullet_data``)."""
    import tempfile

    if data_path is None:
        try:
            import pybullet_data
        except ImportError:
            return {"benchmark": "real-meshes", "skipped": "pybullet_data is not installed"}
        data_path = pybullet_data.getDataPath()
    report = {"benchmark": "real-meshes", "seed": seed, "seeds": seeds, "meshes": {}, "runs": {}}
    report["skipped"] = []
    with tempfile.TemporaryDirectory() as folder:
        for name in names or REAL_MESHES:
            file, flags = {**REAL_MESHES, **HELD_OUT_MESHES}[name]
            path = Path(data_path) / file
            if not path.is_file():
                report["skipped"].append(name)
                continue
            model = str(Path(folder) / f"{name}.model.json")
            status, found, wall, _ = _cli_json(["characterize", str(path), "--out", model, *flags])
            report["meshes"][name] = {"exit": status, "seconds": wall, **(found or {})}
            if status != 0:
                continue
            for mix, argv in REAL_MIXES.items():
                status, found, wall, cpu = _cli_json(
                    ["plan", model, *argv, "--seed", str(seed), "--seeds", str(seeds), *extra]
                )
                placed = (found or {}).get("placement", {})
                report["runs"][f"{name}, {mix}"] = {
                    "exit": status,
                    "force_closure": placed.get("force_closure"),
                    "robust": placed.get("robust"),
                    "rho": placed.get("rho"),
                    "robust_rho": placed.get("robust_rho"),
                    "gap": placed.get("gap"),
                    "seconds": (found or {}).get("seconds"),
                    "wall_seconds": wall,
                    "cpu_seconds": cpu,
                    "elements": placed.get("contacts")
                    and [c["element"] for c in placed["contacts"]],
                    **(
                        {"to_be_robust": placed["to_be_robust"]} if "to_be_robust" in placed else {}
                    ),
                    **({"error": found["error"]} if found and "error" in found else {}),
                }
                print(
                    json.dumps({f"{name}, {mix}": report["runs"][f"{name}, {mix}"]}),
                    file=sys.stderr,
                    flush=True,
                )  # a long run's progress
    runs = report["runs"].values()
    held = sum(bool(r["force_closure"] and r["robust"]) for r in runs)
    report["robust_force_closure"] = f"{held}/{len(runs)}"
    for key in ("seconds", "cpu_seconds"):
        times = [r[key] for r in runs if r[key] is not None]
        report[f"plan_{key}"] = {"max": max(times, default=None), "median": _median(times)}
    return report


def _median(values):
    return float(np.median(values)) if values else None


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (empty where there is none)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ""
    for line in text.splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return ""


def mesh_sampled_sets(count: int, m: int = 4, seed: int = 0, model: str = "lamp"):
    """``count`` sets of ``m`` contacts at random points of an example's mesh, inward normals of
    their triangles: positions (count, m, 3), normals, the torque scale and reference point of
    the part (``1 / radius`` about the centre of its bounding box)."""
    import trimesh

    mesh = trimesh.load(str(MODELS_DIR / f"{model}.stl"), force="mesh")
    points, faces = trimesh.sample.sample_surface(mesh, count * m, seed=seed)
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    radius = float(np.linalg.norm(points - centre, axis=1).max())
    P = points.reshape(count, m, 3)
    U = -np.asarray(mesh.face_normals)[faces].reshape(count, m, 3)
    return P, U, 1.0 / radius, centre


def bench_throughput(sets: int = 1000, seed: int = 0, workers=(1, 2), tol=None) -> dict:
    """Certified rho per second of mesh-sampled 4-PCwF sets (mu 0.5; mixed verdicts) by
    rho_many, one worker and each count of ``workers`` in threads and in processes, in this
    process, alternated; every run's columns checked equal to the first's. ``tol``: the
    relative bracket asked of every set (rho_many's, 1e-6 when None).

    Each run gives the sets as arrays (``runs``) and, right after, as ContactSets built one by
    one from the same arrays, the building timed too (``per_set_runs``): the path that certifies
    each set through :func:`rho` from its ContactSet, with the same answers."""
    from closure_nlp import ContactSet, rho_many

    P, U, scale, centre = mesh_sampled_sets(sets, seed=seed)
    kwargs = {"mu": 0.5, "torque_scale": scale, "reference_point": centre}
    rho_many(P[:8], U[:8], workers=1, tol=tol, **kwargs)  # solvers built outside the timings

    def arrays(k, pool):
        return rho_many(P, U, workers=k, pool=pool, tol=tol, **kwargs)

    def per_set(k, pool):
        made = [ContactSet.from_arrays(p, u, **kwargs) for p, u in zip(P, U)]
        return rho_many(made, workers=k, pool=pool, tol=tol)

    runs, per_set_runs, first, same = {}, {}, None, True
    for pool in ("threads", "processes"):
        for k in workers:
            for table, call in ((runs, arrays), (per_set_runs, per_set)):
                t = time.perf_counter()
                columns = call(k, pool)
                seconds = time.perf_counter() - t
                table[f"{pool} {k}"] = {"seconds": seconds, "sets_per_second": sets / seconds}
                if first is None:
                    first = columns
                same &= bool(np.array_equal(first.bounds, columns.bounds))
                same &= bool(np.array_equal(first.direction, columns.direction))
    fc = first.force_closure
    # widths relative to max(|rho|, the set's scale), as the certificate's 1e-6 is (a set
    # without interior has rho 0 and a bracket of round-off round it)
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.certificate import tolerance_unit

    scales = [
        tolerance_unit(WrenchSlots.from_contacts(ContactSet.from_arrays(p, u, **kwargs)))
        for p, u in zip(P, U)
    ]
    unit = np.maximum(np.abs(first.rho), scales)
    return {
        "sets": sets,
        "tol": DEFAULT_TOLERANCES.certify if tol is None else tol,
        "force_closure_share": float(fc.mean()),
        "median_ms": {
            "all": float(1e3 * np.median(first.seconds)),
            "force_closure": float(1e3 * np.median(first.seconds[fc])) if fc.any() else None,
        },
        "widest_relative_bracket": float(np.max(np.diff(first.bounds, axis=1)[:, 0] / unit)),
        "converged": int(first.converged.sum()),
        "runs": runs,
        "per_set_runs": per_set_runs,
        "same_columns_every_run": same,
    }


def _within(value: float, lo: float, hi: float, scale: float) -> float:
    """How far ``value`` lies outside ``[lo, hi]``, relative to ``scale`` (0 inside)."""
    return max(lo - value, value - hi, 0.0) / scale


def _floor(inner) -> float:
    """The lower end of an epsilon's sandwich: ``-hi`` of the inscribed cones' rho where that
    set is force closure; none otherwise (an epsilon is then the origin's signed distance to
    a facet, which these bounds do not hold)."""
    return -inner.bounds[1] if inner.bounds[1] < 0 else -np.inf


def bench_dexnet(cases: int = 200, sets: int = 200, linf_sets: int = 5, seed: int = 0) -> dict:
    """Ferrari-Canny epsilons of linearised cones (``benchmarks.ferrari_canny``: qhull, written
    from Dex-Net's and GraspIt!'s conventions) against certified rho on the same contacts, each
    timed in this process.

    * ``7 FPC`` (random sets): a frictionless cone is one ray, so the L-infinity set (each normal
      force at most 1) *is* W_c^M with ``f_max`` 1: on closure sets epsilon_Linf must lie in the
      certified ``[-hi, -lo]``.
    * ``4 PCwF`` (mesh-sampled on the lamp, mu 0.5, Dex-Net's 8 edges): the L1 set (normal forces
      summing to at most 1) lies inside W_c^M and holds W_c^M of ``mu cos(pi / k)`` shrunk by
      ``m``, so ``-hi(mu cos(pi / k)) / m <= epsilon_L1 <= -lo(mu)`` on closure sets (the left
      side where ``mu cos(pi / k)`` is force closure);
      epsilon_Linf of 4 edges on ``linf_sets`` closure sets, between ``-hi(mu cos(pi / 4))`` and
      ``-lo(mu)`` ((k + 1)^m points: 625 for 4 edges, 6561 for 8).
    """
    from benchmarks.ferrari_canny import edge_wrenches, epsilon_l1, epsilon_linf
    from closure_nlp import ContactSet, rho

    def timed(call):
        t = time.perf_counter()
        value = call()
        return value, 1e3 * (time.perf_counter() - t)

    def arrays(cs):
        P = np.array([c.position for c in cs.contacts])
        N = np.array([c.inward_normal for c in cs.contacts])
        return P, N

    report = {"benchmark": "dexnet"}
    rows = []
    for k in range(cases):
        cs = random_contact_set(np.random.default_rng(seed + k), ["fpc"] * 7)
        P, N = arrays(cs)
        W = edge_wrenches(P, N, 0.0, 1, cs.torque_scale, cs.reference_point)
        ours, ours_ms = timed(lambda cs=cs: rho(cs))
        linf, linf_ms = timed(lambda W=W: epsilon_linf(W))
        l1, l1_ms = timed(lambda W=W: epsilon_l1(W))
        rows.append((ours, ours_ms, linf, linf_ms, l1, l1_ms, float(np.abs(W).max())))
    fc = [r for r in rows if r[0].force_closure]
    off = [_within(r[2], -r[0].bounds[1], -r[0].bounds[0], r[6]) for r in fc]
    report["7 FPC"] = {
        "sets": cases,
        "force_closure": len(fc),
        "linf_outside_certified_max": float(max(off, default=0.0)),
        "linf_minus_minus_rho_max": float(
            max((abs(r[2] + r[0].rho) / r[6] for r in fc), default=0.0)
        ),  # fmt: skip
        "l1_over_minus_rho": _stats([r[4] / -r[0].rho for r in fc]) if fc else None,
        "median_ms": {
            "rho": float(np.median([r[1] for r in rows])),
            "linf_qhull": float(np.median([r[3] for r in rows])),
            "l1_qhull": float(np.median([r[5] for r in rows])),
        },
    }
    P, U, scale, centre = mesh_sampled_sets(sets, seed=seed)
    mu, edges, m = 0.5, 8, P.shape[1]
    rows, linf_rows = [], []
    for j in range(sets):
        cs = ContactSet.from_arrays(P[j], U[j], mu=mu, torque_scale=scale, reference_point=centre)
        W = edge_wrenches(P[j], U[j], mu, edges, scale, centre)
        ours, ours_ms = timed(lambda cs=cs: rho(cs))
        l1, l1_ms = timed(lambda W=W: epsilon_l1(W))
        row = {"ours": ours, "ours_ms": ours_ms, "l1": l1, "l1_ms": l1_ms}
        if ours.force_closure:
            row["inner"] = rho(ContactSet.from_arrays(
                P[j], U[j], mu=mu * np.cos(np.pi / edges), torque_scale=scale,
                reference_point=centre))  # fmt: skip
            if len(linf_rows) < linf_sets:
                W4 = edge_wrenches(P[j], U[j], mu, 4, scale, centre)
                linf, linf_ms = timed(lambda W4=W4: epsilon_linf(W4))
                inner4 = rho(ContactSet.from_arrays(
                    P[j], U[j], mu=mu * np.cos(np.pi / 4), torque_scale=scale,
                    reference_point=centre))  # fmt: skip
                linf_rows.append((ours, inner4, linf, linf_ms))
        rows.append(row)
    fc = [r for r in rows if r["ours"].force_closure]
    unit = max(abs(r["ours"].rho) for r in rows)
    l1_off = [_within(r["l1"], _floor(r["inner"]) / m, -r["ours"].bounds[0], unit) for r in fc]
    linf_off = [_within(x, _floor(inner), -o.bounds[0], unit) for o, inner, x, _ in linf_rows]
    ours_ms = np.array([r["ours_ms"] for r in rows])
    l1_ms = np.array([r["l1_ms"] for r in rows])
    fc_mask = np.array([r["ours"].force_closure for r in rows])
    report["4 PCwF"] = {
        "sets": sets,
        "mu": mu,
        "edges": edges,
        "force_closure": len(fc),
        "l1_closure": int(sum(r["l1"] > 0 for r in rows)),
        "l1_closure_not_ours": int(sum(r["l1"] > 0 and not r["ours"].force_closure for r in rows)),
        "l1_outside_sandwich_max": float(max(l1_off, default=0.0)),
        "l1_over_minus_rho": _stats([r["l1"] / -r["ours"].rho for r in fc]) if fc else None,
        "linf_4_edges": {
            "sets": len(linf_rows),
            "outside_sandwich_max": float(max(linf_off, default=0.0)),
            "over_minus_rho": _stats([x / -o.rho for o, _, x, _ in linf_rows])
            if linf_rows
            else None,
            "median_ms": float(np.median([r[3] for r in linf_rows])) if linf_rows else None,
        },
        "median_ms": {
            "rho": float(np.median(ours_ms)),
            "l1_qhull": float(np.median(l1_ms)),
            "rho_closure": float(np.median(ours_ms[fc_mask])) if fc_mask.any() else None,
            "l1_qhull_closure": float(np.median(l1_ms[fc_mask])) if fc_mask.any() else None,
        },
        "ratio_l1_over_rho_median": float(np.median(l1_ms) / np.median(ours_ms)),
    }
    return report


def machine(load_before: tuple[float, ...]) -> dict:
    """Where and when a report was measured: cores, CPU model, the 1-minute load average before
    and after the run (other processes share the cores; the milliseconds move with them), date."""
    return {
        "cores": os.cpu_count(),
        "cpu": cpu_model(),
        "load": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "date": time.strftime("%Y-%m-%d"),
    }


def write_report(report: dict, load_before: tuple[float, ...]) -> None:
    """The report as JSON on stdout, with the machine it was measured on."""
    json.dump({**report, "machine": machine(load_before)}, sys.stdout, indent=2)
    sys.stdout.write("\n")


def main(argv=None) -> int:
    load_before = os.getloadavg()
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench", description=__doc__)
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("rho", help="rho(0, W_c^M) per evaluation against SLSQP from +-e_k")
    p.add_argument("--cases", type=int, default=30)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("rho-hat", help="rho(0, What_c^M) of 4 lamp facets against SLSQP")
    p.add_argument("--cases", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("certify", help="certified rho and rho_hat: search, certificate, SLSQP")
    p.add_argument("--cases", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("engine", help="certified rho per family: ours, ipopt, a baseline checkout")
    p.add_argument("--cases", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--baseline", help="folder of another checkout (e.g. a git worktree)")
    p.add_argument("--timeout", type=float, default=300.0, help="seconds per family and run")
    p.add_argument("--families", help="comma-separated family names (default: all)")
    p = sub.add_parser("select", help="heuristic and iterative selection on the example models")
    p.add_argument("--seeds", type=int, default=10)
    p = sub.add_parser("characterize", help="seconds and peak memory of characterize")
    p.add_argument("--subdivisions", type=int, nargs="+", default=[5, 7, 8])
    p.add_argument("--noise", type=float, default=0.0, help="radial noise, x radius")
    p = sub.add_parser("model-size", help="eligibility and select against the model's size")
    p.add_argument("--subdivisions", type=int, nargs="+", default=[3, 4, 5])
    p.add_argument("--repeats", type=int, default=3)
    p = sub.add_parser("plan", help="plan on the example models, against the exhaustive options")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--models", default=",".join(PAPER_EXAMPLES), help="e.g. lamp,cup")
    p = sub.add_parser("plans", help="the command line's plan per example, against a checkout")
    p.add_argument("--seeds", default="1,2,3", help="comma-separated seeds")
    p.add_argument("--models", default=",".join(PAPER_EXAMPLES), help="e.g. lamp,cup")
    p.add_argument("--baseline", help="folder of another checkout (e.g. a git worktree)")
    p.add_argument("--flags", default="", help="further plan flags, e.g. '--bound-cells 40'")
    p = sub.add_parser("seeds", help="plans of several seeds: efficiency, fixtures, examples")
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--parts", default="efficiency,fixtures,examples")
    p.add_argument("--model", default="lamp", help="the example of the efficiency part")
    p = sub.add_parser("gap", help="certified gap of the placement on the example models")
    p.add_argument("--models", default=",".join(PAPER_EXAMPLES), help="e.g. lamp,cup")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--neighbours", action="store_true", help="the ceiling over neighbours too")
    p.add_argument("--compare", action="store_true", help="the exhaustive settings too, after")
    p.add_argument("--budget", type=float, help="seconds per model (default: 30, pistol 60)")
    p.add_argument("--family", action="store_true", help="default placements of every type")
    p.add_argument("--variants", help='JSON: name -> PlacementOptions keywords, e.g. {"a": {}}')
    p = sub.add_parser("part-ceiling", help="certified ceiling over the whole part vs the plan")
    p.add_argument("--models", default=",".join(PAPER_EXAMPLES), help="e.g. lamp,cup")
    p.add_argument("--seeds", type=int, default=8, help="seeds of the plan (default 8)")
    p.add_argument("--cells", type=int, default=200, help="cells of the ceiling (default 200)")
    p.add_argument("--budget", type=float, default=600.0, help="seconds of it (default 600)")
    p = sub.add_parser("startup", help="cold compile and warm start of a command line")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--baseline", help="folder of another checkout (e.g. a git worktree)")
    p.add_argument("--command", default=STARTUP_COMMAND, help=f"default: {STARTUP_COMMAND!r}")
    p = sub.add_parser("batch", help="certified rho per file: the CLI's rho on many files")
    p.add_argument("--files", type=int, default=200)
    p.add_argument("--repeats", type=int, default=3)
    p = sub.add_parser("throughput", help="certified rho per second of many sets (rho_many)")
    p.add_argument("--sets", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    p.add_argument("--tol", type=float, help="relative bracket of every set (default 1e-6)")
    p = sub.add_parser("intent", help="the block's fixture with intent against without")
    p.add_argument("--seeds", default="0,1,2", help="comma-separated seeds")
    p = sub.add_parser("dexnet", help="Ferrari-Canny L1 / L-inf epsilons (qhull) against rho")
    p.add_argument("--cases", type=int, default=200, help="7-FPC sets")
    p.add_argument("--sets", type=int, default=200, help="mesh-sampled 4-PCwF sets")
    p.add_argument("--linf-sets", type=int, default=5, help="closure sets given L-inf")
    p.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("units", help="pybullet's domino in m and mm, placed under margins")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cells", type=int, default=200, help="cells of each ceiling (default 200)")
    p.add_argument("--lp-centre", action="store_true", help="PlacementOptions(lp_centre=True)")
    p = sub.add_parser("real-meshes", help="characterize and plan on pybullet's meshes")
    p.add_argument(
        "--meshes", default=",".join(REAL_MESHES), help="e.g. duck,cube; held-out: the unseen ones"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seeds", type=int, default=1, help="seeds per plan (default 1)")
    p.add_argument("--flags", default="", help="further plan flags, e.g. '--no-bound'")
    args = parser.parse_args(argv)
    if args.what == "startup":  # its own processes and caches: nothing to warm up here
        report = bench_startup(args.repeats, args.baseline, command=args.command)
        write_report(report, load_before)
        return 0
    from closure_nlp.criterion.warm_up import warm_up

    warm_up()  # a kernel compiled inside a timed call would count its compile as its cost
    if args.what == "seeds":
        report = bench_seeds(args.seeds, parts=args.parts.split(","), efficiency_model=args.model)
    elif args.what == "rho":
        report = bench_rho(args.cases, args.repeats, args.seed)
    elif args.what == "rho-hat":
        report = bench_rho_hat(args.cases, args.repeats, args.seed)
    elif args.what == "certify":
        report = bench_certify(args.cases, args.seed)
    elif args.what == "engine":
        names = args.families.split(",") if args.families else None
        report = bench_engine(args.cases, args.seed, args.baseline, args.timeout, names)
    elif args.what == "characterize":
        report = bench_characterize(args.subdivisions, args.noise)
    elif args.what == "model-size":
        report = bench_model_size(args.subdivisions, args.repeats)
    elif args.what == "plan":
        report = bench_plan(args.seeds, names=args.models.split(","))
    elif args.what == "plans":
        seeds = [int(x) for x in args.seeds.split(",")]
        report = bench_plans(seeds, args.baseline, args.models.split(","), args.flags.split())
    elif args.what == "batch":
        report = bench_batch(args.files, args.repeats)
    elif args.what == "throughput":
        counts = tuple(int(k) for k in args.workers.split(","))
        report = bench_throughput(args.sets, args.seed, counts, args.tol)
    elif args.what == "intent":
        from benchmarks.intent import bench_intent

        report = bench_intent([int(x) for x in args.seeds.split(",")])
    elif args.what == "dexnet":
        report = bench_dexnet(args.cases, args.sets, args.linf_sets, args.seed)
    elif args.what == "units":
        report = bench_units(seed=args.seed, cells=args.cells, lp_centre=args.lp_centre)
    elif args.what == "real-meshes":
        names = list(HELD_OUT_MESHES) if args.meshes == "held-out" else args.meshes.split(",")
        report = bench_real_meshes(names, args.seed, args.seeds, extra=args.flags.split())
    elif args.what == "part-ceiling":
        names = args.models.split(",")
        report = bench_part_ceiling(names, args.seeds, args.cells, args.budget)
    elif args.what == "gap" and args.family:
        variants = json.loads(args.variants) if args.variants else None
        report = bench_gap_family(args.models.split(","), args.seed, variants)
    elif args.what == "gap":
        names = args.models.split(",")
        budgets = {name: args.budget for name in names} if args.budget else None
        report = bench_gap(names, args.seed, args.neighbours, compare=args.compare, budgets=budgets)
    else:
        report = bench_select(args.seeds)
    write_report(report, load_before)
    return 0


if __name__ == "__main__":
    sys.exit(main())
