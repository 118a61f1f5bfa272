"""The best of many seeds: plans from seeds ``S, S+1, ..., S+N-1``, over processes, with the spread.

One plan is one seed of the heuristic, and seeds differ a lot (fixture study, 20 seeds per group:
pistol 7 FPC median rho -0.2748, best -0.6494; stepped shaft 7 FPC median -0.2724, best -0.7125,
5 seeds marginal). :func:`plan_seeds` runs N seeds and returns the best placement with every
seed's outcome and their spread. Seeds run in worker processes when ``workers > 1``; each worker
keeps one plan memo (:func:`~closure_nlp.planning.plan.plan`), and every seed's new entries are
shipped to the seeds started after it, whichever worker runs them, so a seed that meets an
element set an earlier seed met takes its iterative run and placement from it (with
``workers=1`` one memo serves every seed). The memo returns what computing again gives, and
each seed's plan is deterministic, so the answer does not depend on the workers: N seeds over K
processes give what the N seeds give one by one (all but timings and ``reused``); the best is
chosen from the values alone (:func:`choose`), never by the order in which seeds finish.
"""

from __future__ import annotations

import functools
import math
import multiprocessing
import os
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from closure_nlp.base.cores import available_cores
from closure_nlp.base.errors import MethodError
from closure_nlp.base.interrupts import leave_to_parent
from closure_nlp.base.progress import Progress
from closure_nlp.base.tolerances import DEFAULT_TOLERANCES
from closure_nlp.base.validation import MAX_SEED
from closure_nlp.criterion.certificate import tolerance_unit
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.placement.ceiling import bounded
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning import single
from closure_nlp.planning.single import (
    MEMO_SIZE,
    CannotWin,
    adopt_memo,
    memo_entries,
    selection_floor,
)

# The command line's defaults: 8 seeds of a few seconds each fit well within the budget on 2
# cores (docs/benchmarks.md has the measured times); the budget stops starting seeds after a
# minute on a slower machine or a larger part.
DEFAULT_SEEDS = 8
DEFAULT_BUDGET = 60.0
MAX_PLAN_SEEDS = 10_000


@dataclass(frozen=True)
class SeedRun:
    """One seed's plan, or why it failed (``error``; a failed seed does not stop the others)."""

    seed: int
    result: object | None  # PlanResult
    error: str | None = None
    seconds: float = 0.0
    unit: float | None = None  # wrench_unit of the placement (choose's tie tolerance)
    stopped: CannotWin | None = None  # stopped after selection: its elements cannot win
    floor: float | None = None  # certified lowest rho on its selected set (stop_rule)

    @property
    def ok(self) -> bool:
        return self.result is not None

    def to_dict(self) -> dict:
        if self.stopped is not None:
            return {
                "seed": self.seed,
                "stopped": str(self.stopped),
                "selected": list(self.stopped.elements),
                "rho_hat_lo": self.stopped.floor,
                "seconds": self.seconds,
            }
        if self.result is None:
            return {"seed": self.seed, "error": self.error, "seconds": self.seconds}
        r = self.result
        p = r.placement
        return {
            "seed": self.seed,
            "rho": p.rho,
            "bounds": None if p.bounds is None else list(p.bounds),
            "force_closure": p.force_closure,
            "marginal": p.marginal,
            "selected": list(r.iterative.elements),
            "elements": list(p.elements),
            "capacity_bound": p.capacity_bound,
            "attempts": len(r.attempts),
            "reused": list(r.reused),
            "rho_unit": self.unit,
            "seconds": self.seconds,
        }


@dataclass(frozen=True)
class SeedSpread:
    """Every seed's outcome, which one was chosen, and the spread of rho over them.

    Attributes
    ----------
    runs : tuple of SeedRun
        In seed order; only the seeds started before the budget was spent.
    chosen : int
        Index in ``runs`` of the returned plan (:func:`choose`: force closure first, then the
        lowest rho, rhos within the certified accuracy tied and broken by the lowest seed).
    requested : int
        Seeds asked for; ``len(runs)`` is fewer when the budget stopped new ones.
    workers : int
        Processes the seeds ran on (1: in this process).
    budget : float or None
        Seconds after which no new seed was started.
    """

    runs: tuple[SeedRun, ...]
    chosen: int
    requested: int
    workers: int
    budget: float | None

    @property
    def rhos(self) -> np.ndarray:
        """rho of every seed that ended with a placement, in seed order: (k,)."""
        return np.array([run.result.placement.rho for run in self.runs if run.ok])

    def element_sets(self) -> list[dict]:
        """The element sets placed on (multisets, as sorted ids), how many seeds ended on each,
        the best rho there and the certified ceiling on ``-rho`` of any placement on them (the
        lowest of those seeds' ceilings, each of which covers the set; None without one); most
        often met first."""
        met: dict[tuple, list] = {}
        for run in self.runs:
            if run.ok:
                placed = run.result.placement
                key = tuple(sorted(placed.elements))
                met.setdefault(key, []).append((placed.rho, placed.capacity_bound))
        rows = []
        for key, found in met.items():
            ceilings = [c for _, c in found if c is not None]
            rows.append(
                {
                    "elements": list(key),
                    "seeds": len(found),
                    "best_rho": min(rho for rho, _ in found),
                    "ceiling": min(ceilings) if ceilings else None,
                }
            )
        return sorted(rows, key=lambda row: (-row["seeds"], row["best_rho"], row["elements"]))

    def to_dict(self) -> dict:
        rhos = self.rhos
        ok = [run for run in self.runs if run.ok]
        return {
            "requested": self.requested,
            "run": len(self.runs),
            "workers": self.workers,
            "budget": self.budget,
            "chosen_seed": self.runs[self.chosen].seed,
            "best_rho": self.runs[self.chosen].result.placement.rho,
            "median_rho": float(np.median(rhos)),
            "worst_rho": float(rhos.max()),
            "force_closure": sum(run.result.force_closure for run in ok),
            "marginal": sum(run.result.placement.marginal for run in ok),
            "stopped": sum(run.stopped is not None for run in self.runs),
            "failed": sum(not run.ok and run.stopped is None for run in self.runs),
            "element_sets": self.element_sets(),
            "runs": [run.to_dict() for run in self.runs],
        }

    def line(self) -> str:
        """One line of text: the spread, for the command line."""
        d = self.to_dict()
        cut = ""
        lost = any((run.error or "").startswith("WorkerLost") for run in self.runs)
        if d["run"] < d["requested"]:
            why = "a worker process ended" if lost else f"budget of {d['budget']:g} s spent"
            cut = f" of {d['requested']} ({why})"
        failed = ""
        if d["stopped"]:
            failed = (
                f", {d['stopped']} stopped after selection"
                " (their elements cannot beat the best placement)"
            )
        if d["failed"]:
            which = ", ".join(
                str(run.seed) for run in self.runs if not run.ok and run.stopped is None
            )
            failed += f", {d['failed']} failed (seed {which})"
        return (
            f"seeds: {d['run']}{cut} on {d['workers']} process(es): best rho = "
            f"{d['best_rho']:.6g} (seed {d['chosen_seed']}), median {d['median_rho']:.6g}, "
            f"worst {d['worst_rho']:.6g}; {d['force_closure']} force closure, "
            f"{d['marginal']} marginal{failed}; {len(d['element_sets'])} element set(s) placed on"
        )


def wrench_unit(eligibility: Eligibility, elements) -> float:
    """The wrench scale rho is measured against for contacts on ``elements``
    (:func:`~closure_nlp.criterion.certificate.tolerance_unit` of their slots): it follows
    ``f_max``, the
    length unit and the torque scale alike."""
    return float(tolerance_unit(eligibility.slots(elements)))


def choose(entries, tolerance: float = DEFAULT_TOLERANCES.certify) -> int:
    """Index of the entry a plan of several seeds returns.

    Force closure first; among those (or among all, when none is), every entry whose rho lies
    within ``tolerance * max(|best rho|, unit)`` of the lowest ties (the certified rho is known
    to that accuracy, relative to the wrench scale ``unit``, the largest of the entries'), and
    the lowest seed among the tied wins. The choice depends on the entries' values alone, never
    on their order or on round-off far below the certified accuracy (parallel and serial runs
    of the same seeds return the same seed).

    Parameters
    ----------
    entries : sequence of (seed, force_closure, rho, unit)
        ``unit``: :func:`wrench_unit` of the entry's placement (None or NaN: not known; the
        others' then, else 1).
    tolerance : float
        Relative accuracy of a certified rho (``Tolerances.certify``).

    Raises
    ------
    ValueError
        When ``entries`` is empty.
    """
    entries = [(int(s), bool(fc), float(r), u) for s, fc, r, u in entries]
    if not entries:
        raise ValueError("no seed ended with a placement")
    pool = [i for i, e in enumerate(entries) if e[1]] or list(range(len(entries)))
    units = [float(entries[i][3]) for i in pool if entries[i][3] is not None]
    units = [u for u in units if math.isfinite(u) and u > 0]
    lowest = min(entries[i][2] for i in pool)
    tie = tolerance * max(abs(lowest), max(units, default=1.0))
    tied = [i for i in pool if entries[i][2] <= lowest + tie]
    return min(tied, key=lambda i: entries[i][0])


def best_index(runs, tolerance: float = DEFAULT_TOLERANCES.certify) -> int:
    """The run a multi-seed plan returns (:func:`choose`; runs without a result never)."""
    ok = [i for i, run in enumerate(runs) if run.ok]
    entries = [
        (runs[i].seed, runs[i].result.force_closure, runs[i].result.placement.rho, runs[i].unit)
        for i in ok
    ]
    return ok[choose(entries, tolerance)]


def check_seed_options(seeds, workers, budget) -> tuple[int, int | None, float | None]:
    """Validated ``(seeds, workers, budget)``; ``ValueError``/``TypeError`` name the field."""
    if isinstance(seeds, bool) or not isinstance(seeds, int) or not 1 <= seeds <= MAX_PLAN_SEEDS:
        raise ValueError(f"seeds: expected an integer in [1, {MAX_PLAN_SEEDS}], got {seeds!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)):
        raise TypeError(f"workers: expected an integer or None, got {workers!r}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers: expected an integer >= 1, got {workers!r}")
    if budget is not None:
        if isinstance(budget, bool) or not isinstance(budget, (int, float)):
            raise TypeError(f"budget: expected a number of seconds or None, got {budget!r}")
        if not (math.isfinite(budget) and budget > 0):
            raise ValueError(f"budget: expected a positive number of seconds, got {budget!r}")
        budget = float(budget)
    return seeds, workers, budget


def plan_seeds(
    eligibility: Eligibility,
    *,
    seed: int = 0,
    seeds: int = DEFAULT_SEEDS,
    workers: int | None = None,
    budget: float | None = None,
    placement: PlacementOptions = PlacementOptions(),
    progress: Progress | None = None,
    placer: Placer | None = None,
    memo: dict | None = None,
    stop: bool = True,
    **plan_options,
):
    """The plans of seeds ``seed, seed + 1, ..., seed + seeds - 1``; the best, with the spread.

    Called by :func:`closure_nlp.planning.plan.plan` when it is given ``seeds``; see there for the
    other parameters. ``plan_options`` (``start``, ``selection``, ``alternatives``) go to every
    seed's plan as they are.

    Parameters
    ----------
    seeds : int
        Number of seeds.
    workers : int, optional
        Processes to run them on; default: one per available core, at most ``seeds``. 1 runs
        them one by one in this process (sharing ``memo`` and ``placer``).
    budget : float, optional
        Seconds after which no further seed is started (the seeds running finish).
    stop : bool
        Seeds are placed in the order of :func:`rank` and one that cannot win stops after its
        selection (:func:`stop_rule`); False: in seed order, every one placed.

    Returns
    -------
    PlanResult
        The chosen seed's plan (:func:`best_index`), its ``seconds`` the whole run's, and
        ``seeds`` the :class:`SeedSpread`.

    Raises
    ------
    Exception
        The first seed's error, when no seed ended with a placement.
    """
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise TypeError(f"seed: expected an integer with seeds, got {seed!r}")
    seeds, workers, budget = check_seed_options(seeds, workers, budget)
    if not 0 <= seed <= MAX_SEED - seeds + 1:
        raise ValueError(f"seed: seeds {seed}..{seed + seeds - 1} must lie in [0, {MAX_SEED}]")
    workers = min(seeds, workers or available_cores())
    if placer is not None and placer.eligibility is not eligibility:
        raise ValueError("placer: must be built on the same Eligibility as the plan")
    options = placement if placer is None else placer.options
    # The seeds are placed by the exchange method alone; the ceiling's root cell (whose
    # frictionless climb polishes placements: a second a seed) goes to the CONTENDERS placed
    # best, and the cells beyond it to the chosen seed's placement alone.
    seed_options = replace(options, bound=False) if options.bound else options
    root_options = replace(options, bound_cells=1, time_budget=None) if options.bound else None
    t0 = time.perf_counter()
    rooted, searched = {}, {}
    if workers == 1:
        placer = placer or Placer(eligibility, options)
        runner = placer
        if seed_options is not options:  # the same exchange NLPs, no ceiling
            runner = Placer(eligibility, seed_options, placer._caches)
        memo = {} if memo is None else memo
        floors = []
        for k in range(seeds):
            if floors and budget is not None and time.perf_counter() - t0 >= budget:
                break
            floors.append(_select(eligibility, memo, plan_options, seed + k) if stop else None)
        outcomes = []
        for k in rank(floors):
            if outcomes and budget is not None and time.perf_counter() - t0 >= budget:
                break
            beat = functools.partial(_to_beat, [run for run, _ in outcomes]) if stop else None
            outcomes.append(
                _run_one(eligibility, runner, memo, progress, plan_options, seed + k, beat)
            )
            _report(progress, outcomes)
        if root_options is not None:
            root = Placer(eligibility, root_options, placer._caches)
            for placed, which in _contenders(_final(outcomes, stop)):
                rooted.update(dict.fromkeys(which, _root(root, placed)))
    else:
        outcomes, rooted, searched = _in_processes(
            eligibility,
            (seed_options, root_options, options if _searches(options) else None),
            plan_options,
            seed,
            seeds,
            workers,
            budget,
            t0,
            progress,
            stop,
        )
    runs = _final(outcomes, stop)
    if not any(run.ok for run in runs):
        raise min(outcomes, key=lambda outcome: outcome[0].seed)[1]
    runs = [
        replace(run, result=replace(run.result, placement=rooted[run.seed]))
        if run.seed in rooted
        else run
        for run in runs
    ]
    chosen = best_index(runs, eligibility.minimizer.tolerances.certify)
    run = runs[chosen]
    placed = run.result.placement
    if root_options is not None and run.seed not in rooted:  # tied with a contender
        placer = placer or Placer(eligibility, options)
        placed = _root(Placer(eligibility, root_options, placer._caches), placed)
    if run.seed in searched:  # searched in a worker beside the other contenders' root cells
        placed = searched[run.seed]
    elif _searches(options):
        placed = _searched(placer or Placer(eligibility, options), placed, progress)
    runs[chosen] = replace(run, result=replace(run.result, placement=placed))
    spread = SeedSpread(tuple(runs), chosen, seeds, workers, budget)
    return replace(runs[chosen].result, seconds=time.perf_counter() - t0, seeds=spread)


# The share of the seeds whose placements get the ceiling's root cell (its climb may lift one
# past the best), the best by the exchange method alone, and at least CONTENDERS of them. The
# climb's placements owe little to the exchange method's: over the 34 windows of 8 seeds among
# seeds 0-23 of the pistol and the stepped shaft (7 FPC), the best after the root cell was the
# exchange method's best 25 times, its second 7 times, its fourth once and its fifth once
# (docs/benchmarks.md).
CONTENDERS = 2
CONTENDING_SHARE = 0.5


def _final(outcomes, stop: bool) -> list:
    """The seeds' runs (``outcomes`` in the order placed) in seed order, after
    :func:`stop_rule`."""
    runs = [run for run, _ in outcomes]
    return sorted(stop_rule(runs) if stop else runs, key=lambda run: run.seed)


def _contenders(runs) -> list:
    """The runs :func:`choose` ranks first (force closure, then the lowest rho, then the lowest
    seed) by their placements before any ceiling: :data:`CONTENDING_SHARE` of the seeds run,
    at least :data:`CONTENDERS`; as ``(placement, seeds)``, each placement once (seeds that met
    the same element set often end on the same contacts, whose root cell is then bounded once).
    """
    ok = [run for run in runs if run.ok]
    key = lambda run: (not run.result.force_closure, run.result.placement.rho, run.seed)  # noqa: E731
    count = max(CONTENDERS, math.ceil(CONTENDING_SHARE * len(runs)))
    picked: dict = {}
    for run in sorted(ok, key=key)[:count]:
        placed = run.result.placement
        same = (placed.elements, placed.rho, *(c.position.tobytes() for c in placed.contacts))
        picked.setdefault(same, (placed, []))[1].append(run.seed)
    return list(picked.values())


def _root(placer: Placer, placed):
    """``placed`` with the ceiling of ``placer``'s options (its root cell) and the better
    placement its climb found, if any: what one seed's plan gives with those options."""
    return bounded(placer, placed.elements, placed, time.perf_counter() - placed.seconds)


def _searches(options: PlacementOptions) -> bool:
    """The options' ceiling goes past its root cell (more cells, and time for them)."""
    return options.bound and options.bound_cells > 1 and options.time_budget != 0


def _searched(placer: Placer, placed, progress):
    """``placed`` (a seed's placement with its root ceiling) with the ceiling's search under
    ``placer``'s options over its own elements (and their neighbours, with
    ``bound_neighbours``), and the better placement that search found, if any."""
    t0 = time.perf_counter() - placed.seconds
    return bounded(placer, placed.elements, placed, t0, progress)


def _run_one(eligibility, placer, memo, progress, kwargs, seed: int, beat=None):
    """``(SeedRun, error or None)`` of one seed's plan: an error ends that seed only; with
    ``beat``, the seed stops after its selection when it cannot reach a rho below it."""
    t = time.perf_counter()
    try:
        result = single.plan_one(
            eligibility,
            placer,
            seed,
            memo=memo,
            progress=progress,
            **kwargs,
            **({} if beat is None else {"beat": beat}),
        )
    except CannotWin as stop:
        return SeedRun(seed, None, None, time.perf_counter() - t, stopped=stop), stop
    except Exception as exc:  # noqa: BLE001 - recorded; raised when every seed fails
        return SeedRun(seed, None, f"{type(exc).__name__}: {exc}", time.perf_counter() - t), exc
    unit = wrench_unit(eligibility, result.placement.elements)
    floor = selection_floor(result.iterative)
    return SeedRun(seed, result, None, time.perf_counter() - t, unit, floor=floor), None


def rank(floors) -> list[int]:
    """The order the seeds are placed in (offsets from the first seed): lowest certified
    rho_hat of the selected set first (the likeliest to win, whose rho then stops the seeds
    that cannot win), ties and uncertified sets after, in seed order."""
    return sorted(
        range(len(floors)),
        key=lambda k: (floors[k] is None, 0.0 if floors[k] is None else floors[k], k),
    )


def _select(eligibility, memo, kwargs, seed: int) -> float | None:
    """:func:`~closure_nlp.planning.single.select_one` of ``seed``; None when it fails (the
    seed's plan meets the same error, and records it)."""
    try:
        return single.select_one(eligibility, seed, memo=memo, **kwargs)
    except Exception:  # noqa: BLE001 - the plan of that seed reports it
        return None


def _to_beat(runs) -> float | None:
    """The lowest rho of ``runs`` (the seeds before the next one, in seed order), or None."""
    rhos = [run.result.placement.rho for run in runs if run.ok]
    return min(rhos) if rhos else None


def stop_rule(runs) -> list:
    """``runs`` (in the order placed, :func:`rank`) as one by one: a seed whose selected set's
    certified rho_hat lies above the lowest rho of the seeds placed before it is stopped after
    its selection (no placement on that set can be the plan's; a tie goes to the earlier seed
    anyway: a seed of a lower floor, or of the same and a lower number).

    A seed in a worker process was given, instead of that rho, the lowest rho of the seeds
    before it whose outcome was final when it started (never lower), so it stopped only where
    it would one by one; one that ran on and would have stopped is stopped here: the answer
    is that of the seeds one by one whatever the processes."""
    out = []
    for run in runs:
        beat = _to_beat(out)
        if run.stopped is not None:  # stopped in a worker: the rho it stopped at, one by one
            stop = CannotWin(run.stopped.elements, run.stopped.floor, beat)
            run = replace(run, stopped=stop)
        elif run.ok and beat is not None and run.floor is not None and run.floor > beat:
            stop = CannotWin(run.result.iterative.elements, run.floor, beat)
            run = SeedRun(run.seed, None, None, run.seconds, stopped=stop)
        out.append(run)
    return out


def _report(progress, outcomes) -> None:
    """``progress("seed", seeds done, best rho so far)``."""
    if progress:
        runs = [run for run, _ in outcomes]
        best = runs[best_index(runs)].result.placement.rho if any(r.ok for r in runs) else math.nan
        progress("seed", len(runs), best)


# A worker process's solvers and memo, made once by _start_worker and used by every seed it runs.
_WORKER: dict = {}

# How often a worker looks whether the process that started it is still there (where the
# system cannot end it with its parent).
ORPHAN_POLL = 0.5


def _start_worker(eligibility, options, kwargs, parent: int, bars=None) -> None:
    """``options``: the seeds' placement options, the root ceiling's and the chosen seed's
    search's (each None when there is none)."""
    leave_to_parent()  # Ctrl-C ends the parent's wait, which then ends the workers
    die_with_parent(parent)
    seed_options, root_options, search_options = options
    placer = Placer(eligibility, seed_options)

    def sharing(options):  # the same exchange NLPs
        return None if options is None else Placer(eligibility, options, placer._caches)

    _WORKER.update(
        eligibility=eligibility,
        placer=placer,
        root=sharing(root_options),
        search=sharing(search_options),
        memo={},
        kwargs=kwargs,
        bars=bars,
    )


def _shared_beat(k: int) -> float | None:
    """The rho seed ``k`` (offset from the first) is to beat, as the parent last wrote it
    (:func:`_bars`), None before any."""
    bars = _WORKER.get("bars")
    value = None if bars is None else bars[k]
    return None if value is None or math.isnan(value) else value


def die_with_parent(parent: int) -> None:
    """End this worker, quietly, as soon as ``parent`` (the process that runs the seeds) ends:
    a parent killed by SIGTERM, SIGHUP or SIGKILL runs no code that could stop its workers, and
    a worker left behind ran its seed to the end (up to 15 s) and then printed a traceback of
    the pipe it could no longer write to.

    On Linux the kernel sends the worker SIGKILL when the process that forked it ends
    (``PR_SET_PDEATHSIG``); that is the forkserver, not ``parent``, under forkserver or spawn,
    so a daemon thread also checks every :data:`ORPHAN_POLL` seconds that ``parent`` is still
    there."""
    import ctypes
    import signal

    if os.getppid() == parent:
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # not Linux: the thread below alone
            pass
        if os.getppid() != parent:  # the parent ended before the request was made
            os._exit(0)

    def watch() -> None:
        while True:
            time.sleep(ORPHAN_POLL)
            try:
                os.kill(parent, 0)
            except ProcessLookupError:
                os._exit(0)  # no flush, no traceback: nobody reads this worker's output now
            except PermissionError:  # the pid now belongs to another user's process
                os._exit(0)

    threading.Thread(target=watch, name="orphan-watch", daemon=True).start()


def _worker_select(seed: int):
    """The selection of ``seed`` in this worker (:func:`_select`): its floor, and the steps
    it added to the memo, for the others."""
    w = _WORKER
    before = set(w["memo"])
    floor = _select(w["eligibility"], w["memo"], w["kwargs"], seed)
    return floor, memo_entries(w["memo"], w["eligibility"], skip=before)


def _worker_seed(k: int, seed: int, shared: dict):
    """Seed ``seed`` in this worker, its memo first given the steps the other workers shipped
    (``shared``); returns the steps this seed added, for the others."""
    w = _WORKER
    adopt_memo(w["memo"], w["eligibility"], shared)
    before = set(w["memo"])
    beat = functools.partial(_shared_beat, k)
    run = (w["eligibility"], w["placer"], w["memo"], None, w["kwargs"], seed, beat)
    outcome = _run_one(*run)
    return k, outcome, memo_entries(w["memo"], w["eligibility"], skip=before)


def _root_here(placed, search: bool = False):
    """``placed`` with its root ceiling, in this worker (:func:`_root`), and with ``search``
    that placement after the ceiling's search too (:func:`_searched`; None when it failed:
    the parent's own search then reports it, if it is the chosen seed's)."""
    found = _root(_WORKER["root"], placed)
    if not search or _WORKER["search"] is None:
        return found, None
    try:
        return found, _searched(_WORKER["search"], found, None)
    except Exception:  # noqa: BLE001 - searched again, and raised, where it is needed
        return found, None


def _share(shared: dict, entries: dict) -> None:
    """``shared`` with a seed's new memo entries; the oldest dropped beyond the memo's size."""
    shared.update(entries)
    while len(shared) > MEMO_SIZE:
        del shared[next(iter(shared))]


def _context():
    """fork when this process runs one thread (the workers start at once, with the solvers
    already built); forkserver otherwise (forking a threaded process is unsafe)."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


class WorkerLost(MethodError):
    """A worker process ended while it ran seeds (killed, out of memory): those seeds' error."""


def _in_processes(eligibility, options, kwargs, seed, seeds, workers, budget, t0, progress, stop):
    """The seeds over ``workers`` processes, at most ``workers`` running at a time (so the
    budget stops new ones), gathered in the order placed; the :func:`_contenders`' root
    ceilings by seed, and the first contender's search (``options``: the seeds' placement
    options, the root's and the search's, each or None), by seed. An interrupt or error ends
    the workers at once.

    A worker that dies (killed, out of memory) breaks the pool: the seeds running then are
    recorded as failed with the reason, no further seed starts, and the seeds that finished
    are the answer (a pool that only replaced the worker left its seed's result unsent and
    the wait without end)."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    done: dict[int, tuple] = {}
    shared: dict = {}  # the steps the seeds computed, shipped to every seed started after
    context = _context()
    bars = context.Array("d", [math.nan] * seeds, lock=False)  # each seed's rho to beat
    pool = ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=_start_worker,
        initargs=(eligibility, options, kwargs, os.getpid(), bars),
    )
    running: dict = {}  # future -> k
    broken = None
    try:
        floors = {} if stop else dict.fromkeys(range(seeds))
        for k in range(seeds) if stop else ():  # queued at once: the budget stops the rest
            running[pool.submit(_worker_select, seed + k)] = k
        while running:
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                k = running.pop(future)
                try:
                    floors[k], entries = future.result()
                except BrokenProcessPool as exc:
                    broken = broken or exc
                    continue
                _share(shared, entries)
            if running and budget is not None and time.perf_counter() - t0 >= budget and floors:
                for future in running:
                    future.cancel()
                running = {f: k for f, k in running.items() if not f.cancelled()}
        if broken is not None:
            raise WorkerLost(
                "a worker process ended abruptly while it ran the seeds' selections (killed, "
                "or out of memory)"
            ) from broken
        selected = []  # the seeds selected before the budget was spent, from the first
        while len(selected) in floors:
            selected.append(floors[len(selected)])
        order = rank(selected)
        seeds = len(order)
        k = 0
        while k < seeds or running:
            while broken is None and k < seeds and len(running) < workers:
                # The first wave starts at once whatever the pool's start-up cost; after it,
                # a spent budget starts no further seed.
                if k >= workers and budget is not None and time.perf_counter() - t0 >= budget:
                    seeds = k
                    break
                # the shared steps as a copy: pickled later, in the pool's thread
                running[pool.submit(_worker_seed, k, seed + order[k], dict(shared))] = k
                k += 1
            if not running:
                break
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in sorted(finished, key=running.get):
                i = running.pop(future)
                try:
                    item = future.result()
                except BrokenProcessPool as exc:
                    broken = broken or exc
                    lost = WorkerLost(
                        f"a worker process ended abruptly while it ran seed {seed + order[i]} "
                        "(killed, or out of memory); the seeds that finished are kept"
                    )
                    run = SeedRun(
                        seed + order[i], None, f"WorkerLost: {lost}", time.perf_counter() - t0
                    )
                    done[i] = (run, lost)
                    continue
                done[item[0]] = item[1]
                _share(shared, item[2])
                for i, beat in enumerate(_bars(done, seeds) if stop else ()):
                    bars[i] = math.nan if beat is None else beat
            _report(progress, [done[i] for i in sorted(done)])
            if broken is not None and not running:
                break
        outcomes = [done[i] for i in sorted(done)]
        rooted, searched = {}, {}
        if options[1] is not None and broken is None:
            # the first contender is most often the chosen one: its search runs now, beside
            # the others' root cells, and is kept only if it is chosen
            picked = _contenders(_final(outcomes, stop))
            futures = [
                (pool.submit(_root_here, placed, i == 0), which)
                for i, (placed, which) in enumerate(picked)
            ]
            for future, which in futures:
                try:
                    found, after = future.result()
                except BrokenProcessPool:  # those seeds keep the exchange method's placement
                    continue
                rooted.update(dict.fromkeys(which, found))
                if after is not None:
                    searched.update(dict.fromkeys(which, after))
    finally:
        _end_workers(pool)
    return outcomes, rooted, searched


def _bars(done: dict, seeds: int) -> list:
    """For each seed (offset from the first), a rho it may be given to beat while the seeds
    before it are not all done: never below the lowest rho of the seeds before it one by one
    (:func:`stop_rule`), so it stops only where it would one by one; None when none is known.

    Two such values: the lowest rho of the seeds whose outcomes are final (every seed before
    them done, the stop rule applied), and, for a seed ``j`` before it that ended with a
    placement, ``max(rho_j, floor_j)``: one by one ``j`` either keeps its ``rho_j``, or stops
    because ``floor_j`` lies above the rho before it (which bounds the later seeds' too)."""
    final = _to_beat(stop_rule(_final_prefix(done)))
    out, known = [], final
    for k in range(seeds):
        out.append(known)
        run = done[k][0] if k in done else None
        if run is not None and run.ok and run.floor is not None:
            value = max(run.result.placement.rho, run.floor)
            known = value if known is None else min(known, value)
    return out


def _final_prefix(done: dict) -> list:
    """The runs of seeds 0, 1, ... (offsets from the first seed) up to the first not done."""
    runs = []
    while len(runs) in done:
        runs.append(done[len(runs)][0])
    return runs


def _end_workers(pool) -> None:
    """Stop every worker now (SIGTERM: a running seed is not waited for) and the pool."""
    processes = dict(getattr(pool, "_processes", None) or {})
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes.values():
        if process.is_alive():
            process.terminate()
    for process in processes.values():
        process.join()


__all__ = [
    "DEFAULT_BUDGET",
    "DEFAULT_SEEDS",
    "SeedRun",
    "SeedSpread",
    "WorkerLost",
    "best_index",
    "check_seed_options",
    "choose",
    "plan_seeds",
    "wrench_unit",
]
