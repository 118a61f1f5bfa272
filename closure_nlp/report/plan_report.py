"""What a user keeps of a plan: ``report.json`` (every number, the options and the versions), a
picture like the paper's Fig. 1, a plot like its Fig. 3 and a short Markdown summary. Every
file is written atomically."""

from __future__ import annotations

import contextlib
import io
import json
import os
import platform
import sys
import tempfile
import threading
from functools import lru_cache
from pathlib import Path

import numpy as np

from closure_nlp.base.files import load_json, write_atomic, write_json
from closure_nlp.base.formatting import certain, lengths
from closure_nlp.contact.contact_set import SOFT_FINGERS, ContactSet, contact_set_from_dict
from closure_nlp.placement.ceiling import gap_text
from closure_nlp.planning.single import PlanResult

_VERSIONS_LOCK = threading.Lock()  # the IPOPT banner is caught by redirecting file descriptor 1


def versions() -> dict:
    """Versions of Python, this package, numpy, casadi and the IPOPT that casadi bundles."""
    with _VERSIONS_LOCK:
        return dict(_versions())


@lru_cache(maxsize=1)
def _versions() -> dict:
    import casadi

    from closure_nlp._version import __version__

    return {
        "closure_nlp": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "casadi": casadi.__version__,
        "ipopt": _ipopt_version(),
    }


def _ipopt_version() -> str:
    """IPOPT states its version only in its banner: run a tiny solve and catch the banner, which
    casadi prints through Python's ``sys.stdout`` or, depending on the build, file descriptor 1."""
    import casadi as ca

    x = ca.SX.sym("x")
    options = {"print_time": False, "ipopt": {"print_level": 5}}
    solver = ca.nlpsol("version", "ipopt", {"x": x, "f": x**2}, options)
    sys.stdout.flush()
    saved = os.dup(1)
    text = io.StringIO()
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 1)
        try:
            with contextlib.redirect_stdout(text):
                solver(x0=1.0)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        capture.seek(0)
        banner = text.getvalue() + capture.read().decode(errors="replace")
    for line in banner.splitlines():
        if "Ipopt version" in line:
            return line.split("Ipopt version", 1)[1].split(",")[0].strip()
    return "unknown"


def summary_markdown(model, result: PlanResult, options: dict, load_factors=None) -> str:
    """A short human summary of a run (with ``load_factors``, a table of them)."""
    h, it, pl = result.heuristic, result.iterative, result.placement
    verdict = "force closure" if pl.force_closure else "NOT force closure"
    rows = [
        f"# {model.name}: {len(pl.contacts)} contacts ({options.get('type', '')})",
        "",
        "| step | elements | value | seconds | evaluations |",
        "|---|---|---|---|---|",
        f"| heuristic | {_ids(h.elements)} | rho_hat = {certain(h.rho_hat, h.bounds)} "
        f"| {h.seconds:.2f} "
        f"| {h.evaluations} |",
        f"| iterative | {_ids(it.elements)} | rho_hat = {certain(it.rho_hat, it.bounds)} "
        f"| {it.seconds:.2f} "
        f"| {it.evaluations} |",
        f"| placement | {_ids(pl.elements)} | rho = {certain(pl.rho, pl.bounds)} "
        f"| {pl.seconds:.2f} "
        f"| {pl.rounds} rounds |",
        "",
        f"Result: rho = {certain(pl.rho, pl.bounds)} ({verdict}); contacts at the element "
        f"centroids had rho = {certain(pl.start_rho)}. Total {result.seconds:.2f} s.",
        "",
    ]
    if pl.robust is not None:
        held = "robust" if pl.robust else "NOT robust"
        rows += [
            f"Within the model's tolerance the placement is {held} (the support function may "
            f"move {pl.shift:.3g})."
            + (f" It would be {pl.to_be_robust_text(model.units)}." if not pl.robust else ""),
            "",
        ]
    if pl.capacity_bound is not None:
        rows += [f"Placement quality: {gap_text(pl)}.", ""]
    if options.get("margin"):
        rows += [
            f"Every contact at least {options['margin']:g} from its element's boundary "
            "(the ceiling covers the same region).",
            "",
        ]
    if "torque_scale" in options and "reference_point" in options:  # the CLI's scale (scale.py)
        unit = f" {options.get('units')}" if options.get("units") else ""
        point = ", ".join(f"{x:.6g}" for x in options["reference_point"])
        auto = " (auto: 1 / the part's radius)" if options.get("torque_scale_auto") else ""
        soft = {t.type for t in result.placement.contact_set.contacts} & SOFT_FINGERS
        mu_s = options.get("mu_s")
        mu_s = ",".join(f"{v:.6g}" for v in (mu_s if isinstance(mu_s, list) else [mu_s]))
        rows += [
            f"Torques about [{point}]{unit}; torque scale {options['torque_scale']:.6g}{auto}"
            + (f"; mu_s {mu_s}{unit}." if soft and options.get("mu_s") is not None else "."),
            "",
        ]
    for i, c in enumerate(pl.contacts):
        pos = lengths(c.position, model, ", ")
        rows.append(f"- contact {i}: element {c.element}, position ({pos})")
    for a in result.attempts[1:]:
        verdict = "force closure" if a.force_closure else "not force closure"
        rows.append(
            f"- also placed on {_ids(a.elements)} ({a.source}, rho_hat = {certain(a.rho_hat)}): "
            f"rho = {certain(a.rho)} ({verdict})"
        )
    for mv in pl.moves:
        rows.append(
            f"- contact {mv.contact} moved from element {mv.source} to its neighbour "
            f"{mv.target}: rho {certain(mv.rho_before)} -> {certain(mv.rho_after)}"
        )
    if load_factors is not None:
        rows += ["", *_loads_markdown(load_factors, options)]
    if result.seeds is not None:
        rows += ["", *_seeds_markdown(result.seeds)]
    return "\n".join(rows) + "\n"


def _loads_markdown(factors, options: dict) -> list[str]:
    """Each load case's certified factor: how many times the case the contacts hold."""
    steered = options.get("objective") == "loads"
    rows = [
        f"Load factors (certified; least {certain(factors.load_factor, factors.bounds)}, "
        f"{factors.weakest}; placement steered by {'them' if steered else 'rho'}):",
        "",
        "| case | load factor | bounds |",
        "|---|---|---|",
    ]
    for name, f in zip(factors.names, factors.factors):
        marginal = " (marginal)" if f.marginal else ""
        rows.append(
            f"| {name} | {certain(f.load_factor, f.bounds)}{marginal} "
            f"| [{f.bounds[0]:.10g}, {f.bounds[1]:.10g}] |"
        )
    return rows


def _seeds_markdown(spread) -> list[str]:
    """The spread over seeds: one line, then every seed's outcome."""
    rows = [
        f"Best of {spread.line().removeprefix('seeds: ')}.",
        "",
        "| seed | rho | verdict | elements | seconds |",
        "|---|---|---|---|---|",
    ]
    for i, run in enumerate(spread.runs):
        chosen = " (chosen)" if i == spread.chosen else ""
        if run.stopped is not None:
            rows.append(
                f"| {run.seed} | - | stopped: {run.stopped} | {_ids(run.stopped.elements)} "
                f"| {run.seconds:.2f} |"
            )
            continue
        if not run.ok:
            rows.append(f"| {run.seed} | - | failed: {run.error} | - | {run.seconds:.2f} |")
            continue
        p = run.result.placement
        verdict = "force closure" if p.force_closure else "marginal" if p.marginal else "not"
        rows.append(
            f"| {run.seed}{chosen} | {p.rho:.4f} | {verdict} | {_ids(p.elements)} "
            f"| {run.seconds:.2f} |"
        )
    sets = spread.element_sets()
    if any(row["ceiling"] is not None for row in sets):
        rows += [
            "",
            "Element sets placed on, with the certified ceiling on -rho of any placement on them "
            "(and their neighbours; - where no seed there was among the better half, which alone "
            "get a ceiling):",
            "",
            "| elements | seeds | best rho | ceiling |",
            "|---|---|---|---|",
        ]
        for row in sets:
            ceiling = "-" if row["ceiling"] is None else f"{row['ceiling']:.4f}"
            rows.append(
                f"| {_ids(row['elements'])} | {row['seeds']} | {row['best_rho']:.4f} | {ceiling} |"
            )
    return rows


def _ids(ids) -> str:
    return ",".join(str(i) for i in ids)


def load_contacts(path) -> ContactSet:
    """A contact-set file, or the placed contacts of a plan's ``report.json``."""
    data = load_json(path)
    if isinstance(data, dict) and "placement" in data and "contacts" not in data:
        if "contact_set" not in data:
            raise ValueError("contact_set: missing from this report (written by an older version)")
        data = data["contact_set"]
    return contact_set_from_dict(data)


def write_report(
    model, result: PlanResult, out_dir, options: dict, *, loads=None, load_factors=None
) -> dict:
    """Write ``report.json``, ``contacts.json`` (a contact-set file of the placed contacts),
    ``placement.png``, ``history.png`` and ``summary.md`` in ``out_dir``; returns their paths
    by name. With ``loads`` and their ``load_factors`` on the placed contacts
    (:class:`~closure_nlp.criterion.load_factor.LoadFactors`), the factors are in the report and
    the summary and the loads are drawn on the placement."""
    from closure_nlp.report.drawing import PLOT_LOCK

    out = Path(out_dir)
    paths = {}
    contacts = result.placement.contact_file(model.name, model.units)
    if "margin" in options:  # how far every contact keeps from its element's boundary
        contacts["margin"] = options["margin"]
    report = {
        "model": model.name,
        **result.to_dict(),
        **({} if load_factors is None else load_factors.to_dict()),
        "contact_set": contacts,
        "options": options,
        "versions": versions(),
    }
    json.dumps(report, allow_nan=False)  # refuse NaN before anything is written
    with PLOT_LOCK:
        paths.update(_figures(model, result, out, options.get("up"), (loads, load_factors)))
    summary = summary_markdown(model, result, options, load_factors)
    paths["summary.md"] = write_atomic(out / "summary.md", summary)
    paths["contacts.json"] = write_json(out / "contacts.json", contacts)
    paths["report.json"] = write_json(out / "report.json", report)
    return {name: str(p) for name, p in paths.items()}


def _figures(model, result: PlanResult, out: Path, up: str | None = None, loads=(None,)) -> dict:
    """``placement.png`` (the paper's Fig. 1, ``up`` the model axis drawn upwards; default:
    the model's; ``loads``: (cases, their factors) drawn as arrows) and ``history.png`` (its
    Fig. 3)."""
    from closure_nlp.report.drawing import (
        draw_loads,
        draw_model,
        draw_with_fixed,
        model_extent,
        pyplot,
        save_figure,
    )

    paths = {}
    plt = pyplot()
    # Fig. 1: initial contacts (element centroids) small, final ones large, on chosen elements.
    start = [
        (model.elements[e].centroid, model.elements[e].inward_normal)
        for e in result.iterative.elements
    ]
    final = result.placement.contact_set
    fig = plt.figure(figsize=(7.0, 6.0))
    ax = fig.add_subplot(projection="3d")
    draw_model(
        model,
        (np.array([p for p, _ in start]), np.array([n for _, n in start])),
        ax,
        highlight=sorted(set(result.placement.elements) | set(result.iterative.elements)),
        contact_sizes=25.0,
        contact_colour="tab:blue",
        contact_label="start: element centroids",
        title=f"{model.name}: rho = {certain(result.placement.rho, result.placement.bounds)}",
        up=up,
    )
    fixed = len(final) - len(result.placement.contacts)  # contacts already in place: first
    draw_with_fixed(
        ax, final, fixed, sizes=140.0, scale=model_extent(model), label="placed contacts"
    )
    if loads[0] is not None:
        draw_loads(ax, loads[0], model, loads[1])
    paths["placement.png"] = save_figure(fig, out / "placement.png")
    plt.close(fig)
    # Fig. 3: rho_hat against the iteration number.
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    h = [v for _, v in result.heuristic.history]
    it = [v for _, v in result.iterative.history]
    ax.plot(range(len(h)), h, "o-", label="heuristic (contacts added)")
    ax.plot(range(len(h) - 1, len(h) - 1 + len(it)), it, ".-", label="iterative (swaps)")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_xlabel("iteration")
    ax.set_ylabel("rho(0, What_c^M)")
    ax.set_title(f"{model.name}: element selection")
    ax.legend()
    fig.tight_layout()
    paths["history.png"] = save_figure(fig, out / "history.png")
    plt.close(fig)
    if result.seeds is not None:
        paths["seeds.png"] = _seeds_figure(result, out / "seeds.png")
    return paths


def _seeds_figure(result: PlanResult, path: Path) -> Path:
    """rho of every seed, the chosen one marked, force closure and marginal told apart."""
    from closure_nlp.report.drawing import pyplot, save_figure

    plt = pyplot()
    spread = result.seeds
    fig, ax = plt.subplots(figsize=(6.0, 3.5))
    for label, colour, keep in (
        ("force closure", "tab:blue", lambda p: p.force_closure),
        ("marginal", "tab:orange", lambda p: p.marginal),
        ("not force closure", "tab:red", lambda p: not (p.force_closure or p.marginal)),
    ):
        runs = [r for r in spread.runs if r.ok and keep(r.result.placement)]
        if runs:
            ax.plot(
                [r.seed for r in runs],
                [r.result.placement.rho for r in runs],
                "o",
                color=colour,
                label=label,
            )
    chosen = spread.runs[spread.chosen]
    ax.plot(
        [chosen.seed],
        [chosen.result.placement.rho],
        "*",
        ms=16,
        mfc="none",
        color="black",
        label=f"chosen: seed {chosen.seed}",
    )
    ax.axhline(float(np.median(spread.rhos)), color="grey", lw=0.8, ls="--", label="median")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_xlabel("seed")
    ax.set_ylabel("rho (lower holds more)")
    ax.set_title(f"{len(spread.runs)} seeds")
    ax.legend(fontsize="small")
    fig.tight_layout()
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)
