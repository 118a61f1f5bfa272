"""A plan steered by load factors (``objective="loads"``): its element sets re-placed for the
largest least load factor.

The plan selects element sets by rho_hat and places contacts by rho (every seed alike). One more
element set is selected by the least load factor itself (the iterative algorithm ranking sets by
:class:`~closure_nlp.selection.load_value.LoadValue`, from the plan's seed) and placed by rho.
Each distinct element set of these is then placed again with the load objective
(:mod:`~closure_nlp.placement.load_objective`), started from that set's rho placement, and the
set whose placement holds the loads most times is kept; the sets go in the order of their
elements' own load factor (an upper bound on any placement's on them), and a set that cannot beat
the best placement so far is left out. A placement never ends below its start (certified
factors), and the plan's own set is re-placed or bounded below the best, so steering by loads
never ends below steering by rho on the same seeds. The plan's ``seconds`` include this step.
"""

from __future__ import annotations

import dataclasses
import time

from closure_nlp.base.progress import Progress
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from closure_nlp.placement.spacing import SpacingError
from closure_nlp.planning.single import PlanResult
from closure_nlp.selection.algorithms import SelectionOptions, run_selection
from closure_nlp.selection.load_value import LoadValue


def steer_by_loads(
    eligibility: Eligibility,
    result: PlanResult,
    loads,
    options: PlacementOptions = PlacementOptions(),
    progress: Progress | None = None,
    seed: int | None = 0,
    selection: SelectionOptions = SelectionOptions(),
) -> PlanResult:
    """``result`` with its placement replaced by the best load-steered placement over the
    element sets of its seeds (force-closure placements first, the plan's own when none is);
    its ``seconds`` count this step too. ``seed`` and ``selection``: the loads' own selection's."""
    t0 = time.perf_counter()
    runs = [run.result for run in result.seeds.runs if run.ok] if result.seeds else [result]
    placements = [r.placement for r in runs if r.placement.force_closure] or [result.placement]
    starts: dict[tuple, object] = {}
    for placement in [result.placement, *placements]:  # the plan's own first
        starts.setdefault(placement.elements, placement)
    placer = Placer(eligibility, options, loads=loads)
    objective = placer.objective
    chosen = run_selection(
        eligibility,
        "iterative",
        seed=seed,
        options=selection,
        value=LoadValue(eligibility, objective),
    )
    if chosen.eligible and chosen.elements not in starts:  # holds every case: placed by rho
        try:
            # the same NLPs, built once; no rho ceiling: this placement is a start, not reported
            start_options = dataclasses.replace(options, bound=False)
            by_rho = Placer(eligibility, start_options, placer._caches)
            placed = by_rho(list(chosen.elements))
            starts.setdefault(placed.elements, placed)  # it may end on neighbours
        except SpacingError:
            pass  # no placement on it keeps the spacing
    # most promising first: no placement on a set holds more than the set's elements do, so a
    # set whose elements cannot beat the best placement so far is not placed again
    ceilings = {e: -objective.upper_bound(eligibility.slots(e)) for e in starts}
    best = None
    for elements in sorted(starts, key=ceilings.get):
        if best is not None and ceilings[elements] >= best[0]:
            break
        weights = [c.weights for c in starts[elements].contacts]
        found = placer(list(elements), weights, progress=progress)
        value = objective(WrenchSlots.from_contacts(found.contact_set)).rho  # -factor * unit
        if best is None or value < best[0]:
            best = (value, found)
    seconds = result.seconds + time.perf_counter() - t0
    return dataclasses.replace(result, placement=best[1], seconds=seconds)
