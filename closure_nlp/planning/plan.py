"""The whole method in one call: heuristic, iterative selection and placement, from one seed
or the best of several (over processes)."""

from __future__ import annotations

from closure_nlp.base.progress import Progress
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.planning.seeds import DEFAULT_BUDGET, DEFAULT_SEEDS, plan_seeds
from closure_nlp.planning.single import PlanResult, check_plan_arguments, plan_one
from closure_nlp.selection.algorithms import SelectionOptions


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
    stop_seeds: bool = True,
) -> PlanResult:
    """Heuristic from ``seed`` (or ``start``), iterative from its result, then placement.

    The command line's defaults: the plans of ``seeds`` seeds ``seed, ..., seed + seeds - 1``
    (default 8; one when ``start`` is given or ``seed`` is None, which leave nothing to vary),
    over ``workers`` processes (default: one per core), no seed started after ``budget`` seconds
    (default 60): the best one, its ``seeds`` field every seed's result and the spread
    (:func:`closure_nlp.planning.seeds.plan_seeds`; the same answer for any ``workers``).
    ``seeds=1`` plans that one seed in this process. ``stop_seeds``: a seed whose selected set
    cannot beat the rho of the seeds placed before it stops after its selection (False: every
    seed is placed, e.g. when the placements are steered by something other than rho
    afterwards).

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
    alternatives = check_plan_arguments(alternatives, memo)
    if placer is not None and placer.eligibility is not eligibility:
        raise ValueError("placer: must be built on the same Eligibility as the plan")
    common = dict(
        start=start, selection=selection, progress=progress, alternatives=alternatives, memo=memo
    )
    if seeds is None:
        seeds = 1 if start is not None or seed is None else DEFAULT_SEEDS
    if isinstance(seeds, bool) or seeds != 1:  # plan_seeds checks the number
        return plan_seeds(
            eligibility,
            seed=seed,
            seeds=seeds,
            workers=workers,
            budget=DEFAULT_BUDGET if budget is None else budget,
            placement=placement,
            placer=placer,
            stop=stop_seeds,
            **common,
        )
    if workers is not None or budget is not None:
        raise ValueError("workers, budget: only with several seeds (seeds=1 plans one)")
    return plan_one(eligibility, placer or Placer(eligibility, placement), seed, **common)
