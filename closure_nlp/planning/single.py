"""One seed's plan: heuristic, iterative selection, placement.

:func:`plan_one` chains the three steps on one :class:`~closure_nlp.criterion.rho_hat.Eligibility`
(so
every solver is built once), through a memo of the steps other plans on it have taken.
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from closure_nlp.base.progress import Progress
from closure_nlp.base.solver_cache import cached
from closure_nlp.base.validation import is_whole
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.robustness import robust_value
from closure_nlp.placement import ceiling
from closure_nlp.placement.place import Placer
from closure_nlp.placement.result import PlacementResult
from closure_nlp.placement.spacing import SpacingError
from closure_nlp.selection.algorithms import (
    SelectionOptions,
    SelectionResult,
    _multiset,
    heuristic,
    iterative,
    light_rho_hat,
    lone_contact,
)

if TYPE_CHECKING:
    from closure_nlp.planning.seeds import SeedSpread


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
    holds every seed's plan and their spread (:class:`~closure_nlp.planning.seeds.SeedSpread`).
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


def check_plan_arguments(alternatives, memo) -> int:
    """``alternatives`` as an int, after checking it and ``memo`` (the plan's arguments)."""
    if not is_whole(alternatives) or alternatives < 0:
        raise ValueError(f"alternatives: expected an integer >= 0, got {alternatives!r}")
    if not (memo is None or isinstance(memo, dict)):
        raise TypeError(f"memo: expected a dict or None, got {type(memo).__name__}")
    return int(alternatives)


class CannotWin(Exception):
    """A seed stopped after its selection: the certified rho_hat of the set it selected
    (``floor``, no placement on that set has a lower rho) lies above ``beat``, the rho an
    earlier seed's placement reached, so its placement could not be the plan's."""

    def __init__(self, elements, floor: float, beat: float):
        super().__init__(
            f"its set's rho_hat >= {floor:.6g} cannot beat the rho {beat:.6g} of a seed "
            "placed before it"
        )
        self.elements, self.floor, self.beat = tuple(elements), float(floor), float(beat)

    def __reduce__(self):  # from a worker process, by its fields
        return CannotWin, (self.elements, self.floor, self.beat)


def selection_floor(selection: SelectionResult) -> float | None:
    """The certified lower end of the selected set's rho_hat (None when not certified): no
    placement on that set reaches a lower rho."""
    bounds = getattr(selection, "bounds", None)
    return None if bounds is None else float(bounds[0])


def select_one(
    eligibility: Eligibility,
    seed: int | None,
    *,
    start=None,
    selection: SelectionOptions = SelectionOptions(),
    memo: dict | None = None,
    **_,
) -> float | None:
    """The selection :func:`plan_one` makes from ``seed`` (heuristic, then iterative, kept in
    ``memo`` for the plan), and the certified lower end of its set's rho_hat
    (:func:`selection_floor`): what ranks the seeds of a plan before any is placed."""
    recall = _Recall(memo, eligibility, selection, None, None)
    found = recall.heuristic(seed, start)
    return selection_floor(recall.iterative(found.elements, "iterative"))


def plan_one(
    eligibility: Eligibility,
    placer: Placer,
    seed: int | None,
    *,
    start=None,
    selection: SelectionOptions = SelectionOptions(),
    progress: Progress | None = None,
    alternatives: int = 4,
    memo: dict | None = None,
    beat: Callable[[], float | None] | None = None,
) -> PlanResult:
    """One seed's plan by ``placer`` (built on ``eligibility``): heuristic from ``seed`` (or
    ``start``), iterative from its result, then placement (see
    :func:`closure_nlp.planning.plan.plan`). With ``beat`` (called after the selection: the
    best rho of the seeds before this one, or None), :class:`CannotWin` ends the plan after the
    selection when no placement on the selected set can reach a rho below it."""
    alternatives = check_plan_arguments(alternatives, memo)
    t0 = time.perf_counter()
    recall = _Recall(memo, eligibility, selection, placer, progress)
    first = recall.heuristic(seed, start)
    second = recall.iterative(first.elements, "iterative")
    floor = selection_floor(second)
    bar = None if beat is None else beat()
    if bar is not None and floor is not None and floor > bar:
        raise CannotWin(second.elements, floor, bar)
    best_start, unspaced = second.elements, None
    try:
        best = recall.placement(second.elements, "placement")
        attempts = [_attempt(second.elements, "iterative", second.rho_hat, best)]
    except SpacingError as exc:  # the alternatives may have room for the spacing
        best, unspaced, attempts = None, exc, []
    if (best is None or not _held(best)) and alternatives and second.eligible:
        candidates = _alternatives(eligibility, seed, selection, second, recall)
        for elements, source, value in itertools.islice(candidates, alternatives):
            try:
                found = recall.placement(elements, f"placement {len(attempts)}")
            except SpacingError:
                continue
            attempts.append(_attempt(elements, source, value, found))
            if progress:
                progress("alternative", len(attempts) - 1, found.rho)
            if best is None or _robust_value(found) < _robust_value(best):
                best, best_start = found, elements
            if _held(found):
                break
    if best is None:
        raise unspaced
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
    return robust_value(result.rho, result.shift)


# Results one memo keeps (least recently used dropped first): a few KB each (pickled, 3.6 KB
# for the iterative run and the placement of a pistol 7-PCwF plan).
MEMO_SIZE = 256


class _Recall:
    """The plan's heuristic and iterative runs and placements, through its ``memo`` when it has
    one; the names of the steps it took from the memo are in ``reused``.

    Placements are the exchange method's alone; the certified ceiling (when the placer's
    options ask for one) is computed once, for the placement the plan returns
    (:meth:`ceiling`): the placements on the other element sets tried are dropped, and with
    them their ceilings (a marginal set's cost as much as the placement itself)."""

    def __init__(self, memo, eligibility, selection, placer, progress):
        self.memo, self.eligibility, self.selection = memo, eligibility, selection
        self.placer, self.progress = placer, progress
        self.reused: list[str] = []

    def heuristic(self, seed, start) -> SelectionResult:
        return self._recall(
            (
                "heuristic",
                self.eligibility,
                seed,
                None if start is None else tuple(start),
                self.selection,
            ),
            lambda: heuristic(
                self.eligibility,
                start=start,
                seed=seed,
                options=self.selection,
                progress=self.progress,
            ),
            "heuristic",
        )

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
        return self._recall(
            ("ceiling", self.eligibility, tuple(elements), self.placer.options),
            lambda: ceiling.bounded(
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
    can make force closure (:func:`~closure_nlp.selection.algorithms.lone_contact`, unless
    ``selection.placeable`` is off): the next set of the pool
    (sets the iterative runs met, lowest rho_hat first; those only screened by a light search
    are evaluated first and skipped unless eligible), then the result of a new heuristic +
    iterative run (seed derived from ``seed``), and so on alternately."""
    tried = {_multiset(eligibility, second.elements)}
    pool = _Pool(eligibility)
    pool.add(second)

    def hopeless(elements) -> bool:
        """No placement on these elements is force closure (:func:`lone_contact`)."""
        return selection.placeable and lone_contact(eligibility, elements) is not None

    runs = 0
    while pool or runs < FRESH_RUNS:
        while pool:
            item = pool.pop()
            if item is None:  # the rest were not eligible
                break
            elements, value, proven = item
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
        pool.add(fresh)
        key = _multiset(eligibility, fresh.elements)
        if fresh.eligible and key not in tried and not hopeless(fresh.elements):
            tried.add(key)
            yield fresh.elements, f"new selection {runs} (heuristic + iterative)", fresh.rho_hat


class _Pool:
    """The iterative runs' further element sets, (elements, value, proven), lowest value plus
    the set's support shift within the tolerance first (equal ones: the earlier run's first,
    then proven before light values, then by value and elements).

    A run's unfinished sets (full searches stopped once they could not win) get their full
    value, and its unranked sets (screens stopped once they could not win) their light value,
    from the same start, so they rank as if never stopped, but only once they could come next:
    the value a stopped search had reached is never above the value it ends with, so a set
    whose stopped value lies above the next set's is not searched yet (most never are). A set
    whose value shows it is not eligible (light: not below 0) leaves the pool then."""

    RESOLVED, OPEN = 1, 0  # a set not searched yet comes first among equal keys

    def __init__(self, eligibility: Eligibility):
        self.eligibility = eligibility
        self.heap: list = []
        self.runs = 0
        self.order = itertools.count()  # never equal: the payloads are never compared

    def __bool__(self) -> bool:
        return bool(self.heap)

    def _push(self, value: float, state: int, run: int, kind: int, elements, payload) -> None:
        steer = robust_value(value, self.eligibility.shift(elements))
        rank = value if state == self.RESOLVED else 0.0
        item = (steer, state, run, kind, rank, tuple(elements), next(self.order), payload)
        heapq.heappush(self.heap, item)

    def add(self, run: SelectionResult) -> None:
        """``run``'s sets: proven (kind 0) and light values (kind 1)."""
        k, self.runs = self.runs, self.runs + 1
        for elements, value in run.eligible_sets:
            self._push(value, self.RESOLVED, k, 0, elements, (tuple(elements), value, True))
        floors = run.unfinished_floors or [-np.inf] * len(run.unfinished_sets)
        for (elements, warm), floor in zip(run.unfinished_sets, floors):
            self._push(floor, self.OPEN, k, 0, elements, ("full", warm))
        for elements, value in run.candidate_sets:
            self._push(value, self.RESOLVED, k, 1, elements, (tuple(elements), value, False))
        floors = run.unranked_floors or [-np.inf] * len(run.unranked_sets)
        for (elements, warm), floor in zip(run.unranked_sets, floors):
            self._push(floor, self.OPEN, k, 1, elements, ("light", warm))

    def pop(self):
        """The next set, or None when no set is left."""
        while self.heap:
            _, state, run, kind, _, elements, _, payload = heapq.heappop(self.heap)
            if state == self.RESOLVED:
                return payload
            how, warm = payload
            if how == "full":
                found = self.eligibility(elements, warm, certify=False)
                if found.eligible:
                    entry = (elements, found.rho_hat, True)
                    self._push(found.rho_hat, self.RESOLVED, run, kind, elements, entry)
            else:
                value, _ = light_rho_hat(self.eligibility, elements, warm)
                if value < 0:
                    entry = (elements, value, False)
                    self._push(value, self.RESOLVED, run, kind, elements, entry)
        return None


__all__ = [
    "Attempt",
    "CannotWin",
    "PlanResult",
    "adopt_memo",
    "memo_entries",
    "select_one",
    "selection_floor",
]
