"""The whole method in one call: heuristic, iterative selection, placement; and its report.

:func:`plan` chains the three steps on one :class:`~closure_nlp.eligibility.Eligibility` (so
every solver is built once); :func:`write_report` writes what a user keeps of a run: ``report.json``
(every number, the options and the versions), a picture like the paper's Fig. 1, a plot like its
Fig. 3 and a short Markdown summary. Every file is written atomically.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import os
import platform
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .contacts import SOFT_FINGERS, ContactSet, contact_set_from_dict
from .eligibility import Eligibility
from .files import load_json, write_atomic, write_json
from .numbers import certain, lengths
from .placement import PlacementOptions, PlacementResult, Placer
from .progress import Progress
from .selection import (
    SelectionOptions,
    SelectionResult,
    _multiset,
    heuristic,
    iterative,
    light_rho_hat,
    lone_contact,
)
from .solver_cache import cached
from .validation import is_whole

if TYPE_CHECKING:
    from .seeds import SeedSpread


@dataclass(frozen=True)
class Attempt:
    """One element set the plan placed contacts on: where it came from and how it ended."""

    elements: tuple[int, ...]
    source: str
    rho_hat: float
    rho: float
    force_closure: bool
    seconds: float

    def to_dict(self) -> dict:
        return {
            "elements": list(self.elements),
            "source": self.source,
            "rho_hat": self.rho_hat,
            "rho": self.rho,
            "force_closure": self.force_closure,
            "seconds": self.seconds,
        }


@dataclass(frozen=True)
class PlanResult:
    """The three steps of one run.

    ``heuristic`` and ``iterative`` are the first selection; ``placement`` is the best placement
    over every element set tried (the first that reached force closure), and ``attempts`` lists
    those sets in the order tried. A plan of several seeds is the chosen seed's, and ``seeds``
    holds every seed's plan and their spread (:class:`~closure_nlp.seeds.SeedSpread`).
    """

    heuristic: SelectionResult
    iterative: SelectionResult
    placement: PlacementResult
    seconds: float
    attempts: tuple[Attempt, ...] = ()
    reused: tuple[str, ...] = ()
    seeds: SeedSpread | None = None

    @property
    def force_closure(self) -> bool:
        return self.placement.force_closure

    def failure(self) -> str | None:
        """Why no force closure was reached, or ``None``."""
        if self.placement.force_closure:
            return None
        tried = len(self.attempts)
        eligible = sum(a.rho_hat < 0 for a in self.attempts)
        if not eligible:
            return (
                f"no eligible element set found (best rho_hat = {self.iterative.rho_hat:.6g}), "
                "so no placement can be force closure"
            )
        return (
            f"no force-closure placement found on {tried} element set(s) tried ({eligible} "
            f"eligible); best rho = {self.placement.rho:.6g}"
        )

    def to_dict(self) -> dict:
        return {
            "heuristic": self.heuristic.to_dict(),
            "iterative": self.iterative.to_dict(),
            "placement": self.placement.to_dict(),
            "attempts": [a.to_dict() for a in self.attempts],
            "seconds": self.seconds,
            "reused": list(self.reused),
            **({} if self.seeds is None else {"seeds": self.seeds.to_dict()}),
        }


def plan(
    eligibility: Eligibility,
    *,
    seed: int | None = 0,
    start=None,
    selection: SelectionOptions = SelectionOptions(),
    placement: PlacementOptions = PlacementOptions(),
    progress: Progress | None = None,
    placer: Placer | None = None,
    alternatives: int = 4,
    memo: dict | None = None,
    seeds: int | None = None,
    workers: int | None = None,
    budget: float | None = None,
) -> PlanResult:
    """Heuristic from ``seed`` (or ``start``), iterative from its result, then placement.

    With ``seeds`` = N, the plans of seeds ``seed, ..., seed + N - 1``, over ``workers``
    processes (default: one per core), no seed started after ``budget`` seconds: the best one,
    its ``seeds`` field every seed's result and the spread (:func:`closure_nlp.seeds.plan_seeds`;
    the same answer for any ``workers``).

    When the placement on an eligible set is not force closure, up to ``alternatives`` further
    element sets are placed, until one is: the next eligible sets the iterative run met (lowest
    rho_hat first), alternating with the results of new heuristic and iterative runs (seeds
    derived from ``seed``). ``placer`` (built on the same ``eligibility``) replaces
    ``placement``: loops over many runs pass one, so that its NLPs are built once.

    ``memo`` (optional, a dict a loop passes to every plan): the iterative run from a start set
    and the placement on an element set are deterministic, so a plan whose heuristic meets a set
    that an earlier plan on the same ``eligibility`` met takes their results from it instead of
    computing them again (a study's seeds often do: 64 of the fixture study's 240 tasks).
    :attr:`PlanResult.reused` names the steps taken from it, whose results keep the seconds
    their computation took; :attr:`PlanResult.seconds` is this plan's own time.
    """
    if not is_whole(alternatives) or alternatives < 0:
        raise ValueError(f"alternatives: expected an integer >= 0, got {alternatives!r}")
    alternatives = int(alternatives)
    if not (memo is None or isinstance(memo, dict)):
        raise TypeError(f"memo: expected a dict or None, got {type(memo).__name__}")
    if seeds is not None:
        from .seeds import plan_seeds

        return plan_seeds(
            eligibility,
            seed=seed,
            seeds=seeds,
            workers=workers,
            budget=budget,
            start=start,
            selection=selection,
            placement=placement,
            progress=progress,
            placer=placer,
            alternatives=alternatives,
            memo=memo,
        )
    if workers is not None or budget is not None:
        raise ValueError("workers, budget: only with seeds (a plan of several seeds)")
    t0 = time.perf_counter()
    if placer is None:
        placer = Placer(eligibility, placement)
    elif placer.eligibility is not eligibility:
        raise ValueError("placer: must be built on the same Eligibility as the plan")
    recall = _Recall(memo, eligibility, selection, placer, progress)
    first = heuristic(eligibility, start=start, seed=seed, options=selection, progress=progress)
    second = recall.iterative(first.elements, "iterative")
    best = recall.placement(second.elements, "placement")
    best_start = second.elements
    attempts = [_attempt(second.elements, "iterative", second.rho_hat, best)]
    if not _held(best) and alternatives and second.eligible:  # else 50 rounds failed
        candidates = _alternatives(eligibility, seed, selection, second, recall)
        for elements, source, value in itertools.islice(candidates, alternatives):
            found = recall.placement(elements, f"placement {len(attempts)}")
            attempts.append(_attempt(elements, source, value, found))
            if progress:
                progress("alternative", len(attempts) - 1, found.rho)
            if _robust_value(found) < _robust_value(best):
                best, best_start = found, elements
            if _held(found):
                break
    best = recall.ceiling(best_start, best)
    return PlanResult(
        first, second, best, time.perf_counter() - t0, tuple(attempts), tuple(recall.reused)
    )


def _held(result: PlacementResult) -> bool:
    """Force closure, and robust within the model's tolerance when it has one."""
    return bool(result.force_closure) and result.robust is not False


def _robust_value(result: PlacementResult) -> float:
    """rho plus the support shift within the model's tolerance (rho without one): what the
    plan steers by, so that a robust placement wins over a merely force-closure one."""
    return result.rho + result.shift


# Results one memo keeps (least recently used dropped first): a few KB each (pickled, 3.6 KB
# for the iterative run and the placement of a pistol 7-PCwF plan).
MEMO_SIZE = 256


class _Recall:
    """The plan's iterative runs and placements, through its ``memo`` when it has one; the
    names of the steps it took from the memo are in ``reused``.

    Placements are the exchange method's alone; the certified ceiling (when the placer's
    options ask for one) is computed once, for the placement the plan returns
    (:meth:`ceiling`): the placements on the other element sets tried are dropped, and with
    them their ceilings (a marginal set's cost as much as the placement itself)."""

    def __init__(self, memo, eligibility, selection, placer, progress):
        self.memo, self.eligibility, self.selection = memo, eligibility, selection
        self.placer, self.progress = placer, progress
        self.reused: list[str] = []

    def iterative(self, start, name: str) -> SelectionResult:
        return self._recall(
            ("iterative", self.eligibility, tuple(start), self.selection),
            lambda: iterative(
                self.eligibility, start, options=self.selection, progress=self.progress
            ),
            name,
        )

    def placement(self, elements, name: str) -> PlacementResult:
        return self._recall(
            ("placement", self.eligibility, tuple(elements), self.placer.options),
            lambda: self.placer(elements, progress=self.progress, ceiling=False),
            name,
        )

    def ceiling(self, elements, placed: PlacementResult) -> PlacementResult:
        """``placed`` (the exchange method's placement from ``elements``) with the placer's
        certified ceiling, and the better placement its search found, if any; ``seconds``
        counts both."""
        if not self.placer.options.bound:
            return placed
        from .placement_bound import bounded

        return self._recall(
            ("ceiling", self.eligibility, tuple(elements), self.placer.options),
            lambda: bounded(
                self.placer,
                list(elements),
                placed,
                time.perf_counter() - placed.seconds,
                self.progress,
            ),
            "ceiling",
        )

    def _recall(self, key, compute, name: str):
        # The key holds the eligibility itself (its identity): another model, specs or torque
        # scale is other work, and a held object's identity cannot be reused.
        if self.memo is None:
            return compute()
        if key in self.memo:
            self.reused.append(name)
        return cached(self.memo, key, compute, MEMO_SIZE)


def memo_entries(memo: dict, eligibility: Eligibility, skip=frozenset()) -> dict:
    """The entries of a plan memo on ``eligibility`` (keys not in ``skip``), keyed without it:
    what another process's memo on a copy of that eligibility can take (:func:`adopt_memo`).

    A memo key holds the eligibility itself (:class:`_Recall`), whose identity does not cross
    processes; the step, the element ids and the options do."""
    return {
        (key[0], *key[2:]): value
        for key, value in list(memo.items())
        if key not in skip and key[1] is eligibility
    }


def adopt_memo(memo: dict, eligibility: Eligibility, entries: dict) -> None:
    """Add :func:`memo_entries` (from a copy of ``eligibility``) to ``memo``, keeping its own
    entries and its size limit."""
    for (step, *rest), value in entries.items():
        key = (step, eligibility, *rest)
        if key not in memo:
            cached(memo, key, lambda value=value: value, MEMO_SIZE)


def _attempt(elements, source: str, rho_hat: float, placed: PlacementResult) -> Attempt:
    return Attempt(
        tuple(elements), source, rho_hat, placed.rho, placed.force_closure, placed.seconds
    )


FRESH_RUNS = 8  # new heuristic + iterative runs at most, when placements keep failing


def _alternatives(eligibility, seed, selection, second, recall: _Recall):
    """Further eligible element sets to place, each multiset once and none that no placement
    can make force closure (:func:`~closure_nlp.selection.lone_contact`, unless
    ``selection.placeable`` is off): the next set of the pool
    (sets the iterative runs met, lowest rho_hat first; those only screened by a light search
    are evaluated first and skipped unless eligible), then the result of a new heuristic +
    iterative run (seed derived from ``seed``), and so on alternately."""
    tried = {_multiset(eligibility, second.elements)}
    pool = _pool([], second, eligibility)

    def hopeless(elements) -> bool:
        """No placement on these elements is force closure (:func:`lone_contact`)."""
        return selection.placeable and lone_contact(eligibility, elements) is not None

    runs = 0
    while pool or runs < FRESH_RUNS:
        while pool:
            elements, value, proven = pool.pop(0)
            key = _multiset(eligibility, elements)
            if key in tried:
                continue
            tried.add(key)
            if hopeless(elements):
                continue
            if not proven:
                found = eligibility(elements, certify=False)
                if not found.eligible:
                    continue
                value = found.rho_hat
            yield elements, "iterative history", value
            break
        if runs == FRESH_RUNS:
            continue
        runs += 1
        derived = (
            None if seed is None else int(np.random.SeedSequence([seed, runs]).generate_state(1)[0])
        )
        found = heuristic(eligibility, seed=derived, options=selection, progress=recall.progress)
        fresh = recall.iterative(found.elements, f"iterative {runs}")
        pool = _pool(pool, fresh, eligibility)
        key = _multiset(eligibility, fresh.elements)
        if fresh.eligible and key not in tried and not hopeless(fresh.elements):
            tried.add(key)
            yield fresh.elements, f"new selection {runs} (heuristic + iterative)", fresh.rho_hat


def _pool(pool, run: SelectionResult, eligibility: Eligibility) -> list:
    """``pool`` with ``run``'s evaluated and screened sets, (elements, value, proven), lowest
    value first; its unfinished sets (full searches stopped once they could not win) get their
    full value now, from the same start, so they rank as if never stopped; its unranked sets
    (screens stopped once they could not win) get their light value now, from the screen's
    start: the value it would have given, so they rank as before."""
    finished = []
    for elements, warm in run.unfinished_sets:
        found = eligibility(elements, warm, certify=False)
        if found.eligible:
            finished.append((found.rho_hat, tuple(elements)))
    evaluated = sorted([(v, tuple(e)) for e, v in run.eligible_sets] + finished)
    pool = pool + [(e, v, True) for v, e in evaluated]
    unproven = [(v, tuple(e)) for e, v in run.candidate_sets]
    for elements, warm in run.unranked_sets:
        value, _ = light_rho_hat(eligibility, elements, warm)
        if value < 0:
            unproven.append((value, tuple(elements)))
    # equal values (symmetric parts have many) in the order of the elements
    pool += [(e, v, False) for v, e in sorted(unproven)]
    return sorted(pool, key=lambda item: item[1])


_VERSIONS_LOCK = threading.Lock()  # the IPOPT banner is caught by redirecting file descriptor 1


def versions() -> dict:
    """Versions of Python, this package, numpy, casadi and the IPOPT that casadi bundles."""
    with _VERSIONS_LOCK:
        return dict(_versions())


@lru_cache(maxsize=1)
def _versions() -> dict:
    import casadi

    from . import __version__

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


def summary_markdown(model, result: PlanResult, options: dict) -> str:
    """A short human summary of a run."""
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
            f"move {pl.shift:.3g}).",
            "",
        ]
    if pl.capacity_bound is not None:
        from .placement_bound import gap_text

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
    if result.seeds is not None:
        rows += ["", *_seeds_markdown(result.seeds)]
    return "\n".join(rows) + "\n"


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
            "(and their neighbours):",
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


def write_report(model, result: PlanResult, out_dir, options: dict) -> dict:
    """Write ``report.json``, ``contacts.json`` (a contact-set file of the placed contacts),
    ``placement.png``, ``history.png`` and ``summary.md`` in ``out_dir``; returns their paths
    by name."""
    from .drawing import PLOT_LOCK

    out = Path(out_dir)
    paths = {}
    contacts = result.placement.contact_file(model.name, model.units)
    if "margin" in options:  # how far every contact keeps from its element's boundary
        contacts["margin"] = options["margin"]
    report = {
        "model": model.name,
        **result.to_dict(),
        "contact_set": contacts,
        "options": options,
        "versions": versions(),
    }
    json.dumps(report, allow_nan=False)  # refuse NaN before anything is written
    with PLOT_LOCK:
        paths.update(_figures(model, result, out, options.get("up")))
    paths["summary.md"] = write_atomic(out / "summary.md", summary_markdown(model, result, options))
    paths["contacts.json"] = write_json(out / "contacts.json", contacts)
    paths["report.json"] = write_json(out / "report.json", report)
    return {name: str(p) for name, p in paths.items()}


def _figures(model, result: PlanResult, out: Path, up: str | None = None) -> dict:
    """``placement.png`` (the paper's Fig. 1, ``up`` the model axis drawn upwards; default:
    the model's) and ``history.png`` (its Fig. 3)."""
    from .drawing import draw_contacts, draw_model, model_extent, pyplot, save_figure

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
    draw_contacts(ax, final, sizes=140.0, scale=model_extent(model), label="placed contacts")
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
    from .drawing import pyplot, save_figure

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


__all__ = [
    "Attempt",
    "PlanResult",
    "adopt_memo",
    "load_contacts",
    "memo_entries",
    "plan",
    "summary_markdown",
    "versions",
    "write_report",
]
