"""Selecting eligible elements: the heuristic and the iterative algorithms (paper section 5).

Both steer by rho_hat = rho(0, What_c^M) (:mod:`closure_nlp.criterion.rho_hat`), plus the support
shift of the set within the tolerance when there is one (:meth:`Eligibility.shift`): the robust
value, so that a set of exact elements wins over one of coarse facets; or by another value of
element sets called like the eligibility (``value``: e.g. minus the least load factor,
:class:`~closure_nlp.selection.load_value.LoadValue`). The heuristic grows
a set from ``i0`` random (or given) elements, each time adding the element whose best vertex
wrench lies furthest along ``u*``, the direction that separates the current set from the origin
(or its weakest side once the set is eligible). The iterative algorithm swaps one element at a time
for the neighbour that lowers rho_hat most, until ``m`` consecutive positions give no descent.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from closure_nlp.base.errors import MethodError
from closure_nlp.base.progress import Progress
from closure_nlp.base.validation import as_flag, as_id_list, is_whole
from closure_nlp.contact.contact_set import ContactType
from closure_nlp.contact.count import require_closure_count
from closure_nlp.criterion.rho_hat import (
    Eligibility,
    EligibilityResult,
    check_usable,
    element_set_keys,
)
from closure_nlp.criterion.robustness import robust_value
from closure_nlp.criterion.support_minimum import SearchOptions, signed_distance

# The light search that ranks the iterative algorithm's neighbours: few samples, one IPOPT run.
SCREEN_SEARCH = SearchOptions(
    samples=16, smoothing=(), ipopt_starts=1, element_ipopt_starts=1, ipopt_polish=False
)


@dataclass(frozen=True)
class SelectionOptions:
    """Options of both algorithms.

    Attributes
    ----------
    initial : int
        ``i0``, the number of random start elements of the heuristic (``1 <= i0 < m``).
    restarts : int
        Heuristic rounds tried before giving up on finding an eligible set.
    descent : float
        A swap counts as descent only if it lowers rho_hat by more than
        ``descent * max(1, |rho_hat|)``: solver round-off never makes the iteration cycle.
    max_iterations : int
        Cap on iterative steps (a step = one position ``i`` tried).
    screen : bool
        Iterative algorithm: rank the neighbours by a light search (:data:`SCREEN_SEARCH`) and
        give the full search only to those that can still beat the best; the light value is
        never above the full one (the full search starts from its direction), so the choice is
        the same. ``False``: the full search for every neighbour.
    placeable : bool
        A plan places no further element set (after the iterative result) that no placement
        can make force closure by :func:`lone_contact`: rho_hat, which lets a contact use its
        whole element, may count such sets eligible. ``False``: it places them too.
    """

    initial: int = 1
    restarts: int = 50
    descent: float = 1e-9
    max_iterations: int = 10_000
    screen: bool = True
    placeable: bool = True

    def __post_init__(self) -> None:
        for name, low in (("initial", 1), ("restarts", 1), ("max_iterations", 1)):
            value = getattr(self, name)
            if not is_whole(value) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
            object.__setattr__(self, name, int(value))
        if not (isinstance(self.descent, (int, float)) and self.descent >= 0):
            raise ValueError(f"descent: expected a number >= 0, got {self.descent!r}")
        object.__setattr__(self, "screen", as_flag(self.screen, "screen"))
        object.__setattr__(self, "placeable", as_flag(self.placeable, "placeable"))


@dataclass(frozen=True)
class SelectionResult:
    """Outcome of one selection run.

    Attributes
    ----------
    elements : tuple of int
        One element id per contact.
    rho_hat : float
    eligible : bool
    direction : (6,) float
        ``u*`` of the final set.
    history : tuple of (int, float)
        ``(iteration, rho_hat)`` after every step, iteration 0 being the start (Fig. 3).
    evaluations : int
        rho_hat computations made by this run.
    seconds : float
    rounds : int
        Heuristic rounds used (1 if the first round was eligible); 0 for the iterative algorithm.
    screened : int
        Iterative algorithm: light searches that ranked neighbours (``options.screen``); not
        counted in ``evaluations``.
    eligible_sets : tuple of (tuple of int, float)
        Iterative algorithm: the other eligible sets it evaluated and their rho_hat, lowest
        steering value (rho_hat plus the tolerance's shift) first (the next candidates when
        placement on the result fails).
    candidate_sets : tuple of (tuple of int, float)
        Iterative algorithm: neighbour sets the light search ranked but the run never fully
        evaluated, with light values below zero, lowest first. A light value is never above the
        full rho_hat, so these are candidates, not proven eligible: evaluate before use.
    unranked_sets : tuple of (tuple of int, (6,) float)
        Iterative algorithm: neighbour sets whose screen stopped as soon as it showed that they
        could not win (so they have no light value), and that may be eligible, each with the
        direction its screen started from. A plan that needs more element sets runs their
        light search then, from that direction: the value the screen would have given.
    unfinished_sets : tuple of (tuple of int, (6,) float)
        Iterative algorithm: neighbour sets whose full search stopped as soon as it showed that
        they could not win, each with the direction that search started from. A plan that needs
        more element sets runs their full search then, from that direction: the value the
        iterative run would have found, so they rank among :attr:`eligible_sets` as before.
    unranked_floors, unfinished_floors : tuple of float
        For each of :attr:`unranked_sets` (:attr:`unfinished_sets`) the value its stopped search
        had reached: the light (full) search from its start, run to the end, never gives less
        (a plan ranks them without running it while better sets are left). Empty when the run
        steered by another value than rho_hat.
    bounds : (float, float)
        Certified ``lo <= rho_hat <= hi`` of the final set (the search steered by the search's
        values; the reported one is certified).
    marginal, converged : bool
        As in :class:`~closure_nlp.criterion.rho_hat.EligibilityResult`.
    """

    elements: tuple[int, ...]
    rho_hat: float
    eligible: bool
    direction: np.ndarray
    history: tuple[tuple[int, float], ...]
    evaluations: int
    seconds: float
    rounds: int = 0
    eligible_sets: tuple[tuple[tuple[int, ...], float], ...] = ()
    candidate_sets: tuple[tuple[tuple[int, ...], float], ...] = ()
    screened: int = 0
    unranked_sets: tuple[tuple[tuple[int, ...], np.ndarray], ...] = ()
    unfinished_sets: tuple[tuple[tuple[int, ...], np.ndarray | None], ...] = ()
    unranked_floors: tuple[float, ...] = ()
    unfinished_floors: tuple[float, ...] = ()
    bounds: tuple[float, float] | None = None
    marginal: bool = False
    converged: bool = True

    def to_dict(self) -> dict:
        return {
            **element_set_keys(self),
            "history": [{"iteration": k, "rho_hat": v} for k, v in self.history],
            "evaluations": self.evaluations,
            "screened": self.screened,
            "seconds": self.seconds,
        }


def heuristic(
    eligibility: Eligibility,
    *,
    start=None,
    seed: int | None = 0,
    options: SelectionOptions = SelectionOptions(),
    progress: Progress | None = None,
    value=None,
) -> SelectionResult:
    """Steps 1-5 of the heuristic algorithm.

    Parameters
    ----------
    eligibility : Eligibility
        The model, the ``m`` contact specs and the solvers.
    start : sequence of int, optional
        The ``i0`` start elements (``1 <= i0 < m``, or ``m`` to just evaluate them); random
        from ``seed`` when omitted, and for every restart.
    seed : int, optional
    options : SelectionOptions
    progress : callable, optional
    value : callable, optional
        What ranks element sets, lower better, called as ``eligibility`` is and with its
        ``certify`` and ``evaluations`` (default: rho_hat by ``eligibility``, plus the set's
        shift within the tolerance; :class:`~closure_nlp.selection.load_value.LoadValue`: minus
        the least load factor). Every field of the result named ``rho_hat`` is then that value.

    Returns
    -------
    SelectionResult
        The first eligible set found, else (after ``options.restarts`` rounds) the set with the
        lowest rho_hat, with ``eligible`` False.

    Raises
    ------
    ValueError
        When the contact specs can never give force closure (:mod:`closure_nlp.contact.count`).
    """
    require_closure_count(eligibility.all_specs)
    t0 = time.perf_counter()
    m = eligibility.m
    usable = np.flatnonzero(eligibility.model.usable)
    source = eligibility if value is None else value
    evaluations0 = source.evaluations
    rng = np.random.default_rng(seed)
    given = None if start is None else _check_start(eligibility, start)
    if given is None and not options.initial < m:
        raise ValueError(f"initial: must be < m = {m}, got {options.initial}")
    best: tuple[EligibilityResult, list] | None = None
    for round_ in range(1, options.restarts + 1):
        if given and round_ == 1:
            chosen = list(given)
        else:
            chosen = usable[rng.integers(0, len(usable), options.initial)].tolist()
        history = []
        # A complete set is certified at once: the certificate's light seed search replaces the
        # full one, and the verdict that ends the rounds is the certified one.
        found = source(chosen, partial=True, certify=len(chosen) == m)
        history.append((0, found.rho_hat))
        while len(chosen) < m:
            # an element's support value along u*, less what its tolerance may take from it
            values = eligibility.element_values(len(chosen), found.direction)
            if value is None:  # a load's direction is not a unit one: no shift in its units
                values -= eligibility.element_shifts(len(chosen))
            values[~eligibility.model.usable] = -np.inf
            chosen.append(int(np.argmax(values)))
            found = source(chosen, found.direction, partial=True, certify=len(chosen) == m)
            history.append((len(history), found.rho_hat))
            if progress:
                progress("heuristic", len(history) - 1, found.rho_hat)
        if best is None or steering(eligibility, found, value) < steering(
            eligibility, best[0], value
        ):
            best = (found, history)
        if found.eligible:
            break
    found, history = best
    return _certified_result(source, found, history, evaluations0, t0, rounds=round_)


def _certified_result(eligibility, best, history, evaluations0, t0, **extra) -> SelectionResult:
    """The result of a selection run that ended on ``best``: certified (its history's last
    value too), with the run's evaluations and seconds; ``extra``: the algorithm's own fields.
    ``eligibility``: what valued the sets (the eligibility or a ``value``)."""
    best = eligibility.certify(best)
    history[-1] = (history[-1][0], best.rho_hat)
    return SelectionResult(
        best.elements,
        best.rho_hat,
        best.eligible,
        best.direction,
        tuple(history),
        eligibility.evaluations - evaluations0,
        time.perf_counter() - t0,
        bounds=best.bounds,
        marginal=best.marginal,
        converged=best.converged,
        **extra,
    )


def steering(eligibility: Eligibility, found, value=None) -> float:
    """The value selection steers by: rho_hat plus the set's support shift within the
    tolerance (rho_hat without one); a ``value``'s own (its ``rho_hat`` field) when given."""
    if value is not None:
        return found.rho_hat
    return robust_value(found.rho_hat, eligibility.shift(found.elements))


def light_rho_hat(eligibility: Eligibility, elements, warm, stop_below=None):
    """The light search's (:data:`SCREEN_SEARCH`) value of an element set, never above its full
    rho_hat, and its direction; with ``stop_below``, it stops once a direction shows ``p <=
    stop_below`` (see :meth:`~closure_nlp.criterion.support_minimum.SupportMinimizer.__call__`)."""
    light = eligibility.minimizer.with_search(SCREEN_SEARCH)
    slots = eligibility.slots(elements)
    found = light(slots, warm, stop_below)
    return signed_distance(found, slots, light.tolerances), found.direction


def iterative(
    eligibility: Eligibility,
    start,
    *,
    options: SelectionOptions = SelectionOptions(),
    progress: Progress | None = None,
    value=None,
) -> SelectionResult:
    """Steps 1-4 of the iterative algorithm from ``start`` (m element ids).

    Position ``i`` (cyclically) is replaced by the neighbour that lowers rho_hat most, if any
    does; the run ends after ``m`` consecutive positions without descent. Each candidate set's
    rho_hat is warm-started from the current ``u*`` and remembered, so no set is solved twice.
    Contact specs that can never give force closure raise ``ValueError`` before any search.
    ``value``: what ranks the sets instead of rho_hat (see :func:`heuristic`); its ``light``
    method is the screen's value.
    """
    require_closure_count(eligibility.all_specs)
    t0 = time.perf_counter()
    source = eligibility if value is None else value
    if value is None:

        def light_value(elements, warm, stop_below):
            return light_rho_hat(eligibility, elements, warm, stop_below=stop_below)

        shift_of = eligibility.shift
    else:
        light_value = value.light

        def shift_of(elements) -> float:
            return 0.0

    evaluations0 = source.evaluations
    current = list(eligibility.check_elements(start, "start"))
    m = eligibility.m
    seen: dict[tuple, EligibilityResult] = {}
    # value, direction, elements, and the start direction if the screen may have stopped at
    # the bar (else None)
    screened: dict[tuple, tuple[float, np.ndarray, tuple[int, ...], np.ndarray | None]] = {}

    # sets whose full search stopped once it showed they could not win: (value never above
    # their full rho_hat and at or above every later bar, elements, the search's start, the
    # value the search reached)
    unfinished: dict[tuple, tuple[float, tuple[int, ...], np.ndarray, float]] = {}

    def steered(found) -> float:
        return steering(eligibility, found, value)

    def evaluate(elements, warm, stop_above=None):
        """The full search's result, or None when ``stop_above`` (a steering value) is given
        and the search showed the set's value at or above it (the set cannot win: the step's
        choice is the same). The search stops early only below zero (rho_hat < 0)."""
        key = _multiset(eligibility, elements)
        if key not in seen:
            shift = shift_of(elements)
            stop = None if stop_above is None or stop_above - shift >= 0 else stop_above - shift
            found = source(elements, warm, certify=False, stop_above=stop)
            if stop is not None and found.rho_hat >= stop:
                unfinished[key] = (found.rho_hat + shift, tuple(elements), warm, found.rho_hat)
                return None
            seen[key] = found
        return seen[key]

    def screen(elements, warm, bar) -> tuple[float, np.ndarray]:
        """A steering value never above the full one (see :class:`SelectionOptions`); the
        search stops once it shows the value at or above ``bar`` (the set cannot win then, nor
        later, when the bar is lower)."""
        key = _multiset(eligibility, elements)
        if key in seen:
            return steered(seen[key]), seen[key].direction
        if key in unfinished:  # at or above every later bar: ranks past the break, as before
            return unfinished[key][0], screened[key][1]
        shift = shift_of(elements)
        if key not in screened:
            screen_value, direction = light_value(elements, warm, shift - bar)
            stopped = warm if screen_value >= bar - shift else None
            screened[key] = (screen_value, direction, tuple(elements), stopped)
        return screened[key][0] + shift, screened[key][1]

    best = evaluate(current, None)
    history = [(0, best.rho_hat)]
    count, i, step = 0, -1, 0
    while count < m:
        if step >= options.max_iterations:
            raise MethodError(
                f"iterative selection: no end after {step} steps (max_iterations); "
                f"rho_hat = {best.rho_hat:.6g}"
            )
        step += 1
        i = (i + 1) % m
        candidate = None
        margin = options.descent * max(1.0, abs(steered(best)))
        trials = []
        for neighbour in eligibility.model.neighbours(current[i]):
            trial = current.copy()
            trial[i] = neighbour
            trials.append(trial)
        if options.screen:
            bar = steered(best) - margin
            ranked = sorted(
                ((*screen(trial, best.direction, bar), trial) for trial in trials),
                key=lambda item: item[0],
            )
            for light, direction, trial in ranked:
                # values only rise along the ranking, and a full value is never below its own
                if light >= bar:
                    break
                if candidate is not None and light >= steered(candidate):
                    break
                # only a value below the bar and the candidate's can change the step's choice
                stop = bar if candidate is None else min(bar, steered(candidate))
                found = evaluate(trial, direction, stop)
                if found is not None and (candidate is None or steered(found) < steered(candidate)):
                    candidate = found
        else:
            for trial in trials:
                found = evaluate(trial, best.direction)
                if candidate is None or steered(found) < steered(candidate):
                    candidate = found
        if candidate is not None and steered(candidate) < steered(best) - margin:
            best, current, count = candidate, list(candidate.elements), 0
        else:
            count += 1
        history.append((step, best.rho_hat))
        if progress:
            progress("iterative", step, best.rho_hat)
    others = sorted(
        (steered(r), r.rho_hat, r.elements) for r in seen.values() if r.eligible and r is not best
    )
    unproven = sorted(
        (light, elements)
        for key, (light, _, elements, stopped) in screened.items()
        if key not in seen and key not in unfinished and light < 0 and stopped is None
    )
    # a stopped screen's value is below the light one (never above the full rho_hat): >= 0
    # proves the set is not eligible; below, it could be, and cannot be ranked by that value
    unranked = [
        (elements, stopped, light)
        for key, (light, _, elements, stopped) in screened.items()
        if key not in seen and key not in unfinished and light < 0 and stopped is not None
    ]
    floors = value is None  # the plan's pool searches by rho_hat
    return _certified_result(
        source,
        best,
        history,
        evaluations0,
        t0,
        eligible_sets=tuple((elements, rho_hat) for _, rho_hat, elements in others),
        candidate_sets=tuple((elements, light) for light, elements in unproven),
        screened=len(screened),
        unranked_sets=tuple((elements, stopped) for elements, stopped, _ in unranked),
        unfinished_sets=tuple((elements, warm) for _, elements, warm, _ in unfinished.values()),
        unranked_floors=tuple(light for _, _, light in unranked) if floors else (),
        unfinished_floors=tuple(v[3] for v in unfinished.values()) if floors else (),
    )


# Singular values below this share of the largest count as zero in lone_contact: the wrenches
# it tests are exactly orthogonal to a direction (surfaces of revolution, parallel planes), so
# only round-off separates them from it.
LONE_RANK_TOLERANCE = 1e-9

# The columns of an element's vertex grasp matrices (normal force, two friction forces, spin
# moment) whose wrenches a contact of each type can apply.
_COLUMNS = {ContactType.FPC: [0], ContactType.PCWF: [0, 1, 2]}


def lone_contact(eligibility: Eligibility, elements) -> int | None:
    """The position of a frictionless contact that alone gives the set a dimension of wrench
    space, or None.

    If the wrenches every other contact can apply, anywhere on its element, are orthogonal to a
    direction ``u`` (they span fewer than 6 dimensions), only contact ``i`` has a wrench along
    ``u``; a frictionless contact applies one wrench, ``u . w`` of one sign, so no placement on
    the set resists both ``u`` and ``-u``: none is force closure. rho_hat, which lets a contact
    use its whole element (both ends of a flat), may still call the set eligible. (E.g. a shaft
    whose other elements are on surfaces of revolution, with one contact on a wrench flat: no
    torque about the axis but from that contact.) The test is relative to the wrenches' scale.

    Parameters
    ----------
    eligibility : Eligibility
    elements : sequence of int
        One element id per contact, ``m`` of them.

    Returns
    -------
    int or None
        The first such position; None when there is none (the set may still not be placeable).
    """
    specs = eligibility.specs
    blocks = []
    for spec, e in zip(specs, elements):
        G = eligibility.model.elements[e].grasp_matrices(eligibility.torque_scale)
        columns = _COLUMNS.get(spec.type, [0, 1, 2, 3])
        blocks.append(G[:, :, columns].transpose(0, 2, 1).reshape(-1, 6))
    for spec, element in zip(eligibility.fixed.specs, eligibility.fixed.elements):
        G = element.grasp_matrices(eligibility.torque_scale)  # fixed contacts: never alone here
        columns = _COLUMNS.get(spec.type, [0, 1, 2, 3])
        blocks.append(G[:, :, columns].transpose(0, 2, 1).reshape(-1, 6))
    largest = max(np.linalg.norm(b, 2) for b in blocks)
    for i, spec in enumerate(specs):
        if spec.type is not ContactType.FPC:
            continue
        others = np.vstack([b for k, b in enumerate(blocks) if k != i])
        values = np.linalg.svd(others, compute_uv=False)
        if len(values) < 6 or values[5] <= LONE_RANK_TOLERANCE * largest:
            return i
    return None


def run_selection(
    eligibility: Eligibility,
    algorithm: str = "heuristic",
    *,
    start=None,
    seed: int | None = 0,
    options: SelectionOptions = SelectionOptions(),
    progress: Progress | None = None,
    value=None,
) -> SelectionResult:
    """``heuristic``, or ``iterative`` (from ``start`` if it names m elements, else from the
    heuristic's result; evaluations and seconds then include the heuristic's); ``value`` ranks
    the sets instead of rho_hat (see :func:`heuristic`)."""
    common = dict(options=options, progress=progress, value=value)
    if algorithm == "heuristic":
        return heuristic(eligibility, start=start, seed=seed, **common)
    if algorithm != "iterative":
        raise ValueError(f"algorithm: expected 'heuristic' or 'iterative', got {algorithm!r}")
    if start is not None and len(start) == eligibility.m:
        return iterative(eligibility, start, **common)
    first = heuristic(eligibility, start=start, seed=seed, **common)
    result = iterative(eligibility, first.elements, **common)
    return replace(
        result,
        evaluations=result.evaluations + first.evaluations,
        seconds=result.seconds + first.seconds,
    )


select = run_selection  # the command's name for it


def _multiset(eligibility: Eligibility, elements) -> tuple:
    """Key of an element set: contacts with equal specs are interchangeable."""
    kinds = [eligibility.specs.index(spec) for spec in eligibility.specs]
    return tuple(sorted(zip(kinds, elements)))


def _check_start(eligibility: Eligibility, start) -> tuple[int, ...]:
    start = as_id_list(start, "start")
    if not 1 <= len(start) <= eligibility.m:
        raise ValueError(f"start: expected 1 to {eligibility.m} element ids, got {len(start)}")
    ids = tuple(eligibility.model.check_id(e, f"start[{k}]") for k, e in enumerate(start))
    return check_usable(eligibility.model, ids, "start")


__all__ = [
    "Progress",
    "SelectionOptions",
    "SelectionResult",
    "heuristic",
    "iterative",
    "lone_contact",
    "run_selection",
    "select",
]
