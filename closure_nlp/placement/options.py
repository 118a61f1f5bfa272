"""What a placement run may do: its options, validated on creation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from closure_nlp.base.validation import as_flag, is_whole

EXCHANGE_SOLVERS = ("auto", "mixed", "ipopt", "slp", "slp-ipopt", "slp-model")


@dataclass(frozen=True)
class PlacementOptions:
    """Options of the exchange method.

    Attributes
    ----------
    gap : float
        Stop when ``r - (-rho) <= gap * max(1, |rho|)``.
    max_rounds : int
        Exchange rounds per element set.
    random_directions : int
        Pseudo-random directions in the first working set, besides ``+-e_k``.
    neighbour_moves : int
        Moves of contacts into neighbouring elements tried at most (0: stay on the elements).
    starts : int
        Start weights: the given ones (or the centroids), then random ones from ``seed``; the
        trust-region method is local and symmetric starts are often stationary.
    extra_starts : int
        Further random starts tried, one at a time, while none has reached force closure.
    seed : int
    subset_margin : float
        Contacts with ``P_ik > -subset_margin * f_max`` count in the model of direction ``k``, so
        a contact about to start helping is seen (any subset gives a valid lower bound).
    ipopt_tol : float
    certify : bool
        Accepted for compatibility and ignored: the start's and the final rho are always
        certified (:func:`closure_nlp.criterion.support_minimum.rho`); the exchange rounds compare
        the
        search's
        values.
        At optimised placements many directions are equally weak, and the bounds often stop
        at their budget wider than 1e-6: they are valid, and the README says how wide.
    probe_rounds : int
        Rounds each of the ``starts`` starts gets before only the best of them runs on to
        ``max_rounds`` (0, the default: every start runs to ``max_rounds``); a neighbour-move
        trial gets this many rounds when ``move_rounds`` is 0.
        Measured with ``screen`` on 3 seeds of the paper's examples (``bench plan``, mode
        ``fast``, probe 6, and on the lamp and the cup): placement 1.3-1.7x
        faster, median rho 6-8% less negative (less load capacity), so it is not the default.
    screen : bool
        Judge each exchange round's new weights by a light search first
        (:data:`~closure_nlp.selection.algorithms.SCREEN_SEARCH`): when it already finds a
        direction at
        least as weak as the best weights' rho, the round is rejected as the full search would
        reject it; only promising weights get the full search. ``False`` (default): the full
        search every round.
    round_search : bool
        Judge each round's new weights by :data:`ROUND_SEARCH`, started also from the working
        set's directions weakest there (default); ``False``: by the eligibility's own search
        from the best weights' direction alone. Measured against it in
        one process on 24 placements (lamp, cup, pistol; torque scale 1 and automatic):
        placement 1.2-2.1x faster (median of the six groups 1.37x); the final rho is better on
        9, worse on 12 (the path of a local method changes), by -0.097 to +0.052. Every value
        reported at the end is certified (:func:`closure_nlp.criterion.support_minimum.rho`).
    move_rounds : int
        Rounds a neighbour-move trial gets; it runs on to ``max_rounds`` only if it already
        beats the current placement (0: every trial runs to ``max_rounds``, or
        ``probe_rounds`` when that is set). A trial starts from the
        placement's weights with one contact moved, often far worse; the trials that never
        paid off cost most of the placement's rounds on the pistol and the lamp. Measured with
        the start's deferred certification, against every trial run in full, in one process, on
        9 sets of the three examples (automatic torque scale): the same rho on all 9, placement
        0.97-1.8x faster (median 1.33x).
    share_directions : bool
        Start each exchange run (every start and neighbour trial of one placement) with the
        weak directions the earlier runs found, besides the random ones. Off by default:
        measured on 7 sets of the examples it gave a better rho on some (lamp at torque scale
        1: median -0.68 against -0.48) and a worse one on others (a lamp set at the automatic
        scale: -0.31 against -0.55), and slower rounds (a larger NLP).
    validate : bool
        When an exchange run would end, the eligibility's own search checks its best weights,
        and a weaker direction it finds resumes the run from that truer value (default). The
        exchange keeps whatever weights the round search values lowest, so it seeks out that
        search's misses. Measured in one process on the three examples, 5 seeds each: the final
        certified rho better on 13 of 15 and equal on 2 (pistol median -0.393 -> -0.445),
        placement 1.2-1.5x slower (README, "Selecting elements and placing contacts").
    bound : bool
        After the exchange method, compute the certified ceiling on every placement on the
        elements searched (:func:`closure_nlp.placement.ceiling.capacity_bound`) and search for
        better placements until ``target_gap`` or ``time_budget`` (default on; the result is
        never worse than the exchange method's).
    target_gap : float
        Relative gap ``(ceiling - capacity) / ceiling`` at which that search stops (0.02).
    bound_cells : int
        Cells the branch and bound of that search may bound: a budget that gives the same
        answer on any machine. The default, 500, costs about as much as the exchange method
        (a cell a few milliseconds, and most searches reach the gap target sooner) on the placed
        contacts' own elements: on 19 default placements of 3-4 contacts of every type and 7 FPC
        on the examples, 4 contacts reach 2% within 100 cells, 3 contacts 2-5% (the pistol's
        about 23%) (docs/placement.md). 1: the root cell alone.
    bound_neighbours : bool
        The ceiling covers each contact's element and its neighbours (the elements the
        exchange method may move it to), not only the element it sits on. Off by default: over
        several elements per contact the bound mixes them and is far looser (the same 19
        placements: median gap 70% at the root, 66% after 30 cells).
    time_budget : float or None
        Seconds that search may take besides (None, the default: no limit in seconds). When a
        budget ends first, the gap reached is reported as such.
    exchange_solver : {"auto", "mixed", "ipopt", "slp", "slp-ipopt", "slp-model"}
        The solver of the restricted problems: ``"auto"`` (default), HiGHS when every contact
        is frictionless (the problem is then a linear programme, :class:`ExchangeLP`),
        ``"mixed"`` otherwise: IPOPT's NLP (:class:`ExchangeProblem`) on the first start's
        run and on a neighbour move's run once it beats the placement, the same problem by
        sequential linear programming (:class:`~closure_nlp.placement.sequential_lp.ModelSLP`) on
        the
        runs that explore (further starts, neighbour-move trials). Against IPOPT everywhere,
        on seeds 1-8 of the lamp, the cup and the pistol with 7 PCwF (docs/placement.md):
        placement 1.2-2x faster; the median rho equal on the lamp, better on the cup, and on
        the pistol better in one measurement and 0.45% lower in another (one seed).
        ``"slp-model"``: that sequential LP on every run (the lamp's median 0.04% lower).
        ``"ipopt"``: IPOPT always; ``"slp"``:
        sequential linear programming by HiGHS
        (:class:`~closure_nlp.placement.sequential_lp.ExchangeSLP`), any contact type. Measured on 8
        seeds of the lamp's default plan (4 PCwF, docs/placement.md), each in its own
        process: ``"slp"`` places 1.9x faster, and its rho is better on 2 seeds, worse on 3
        and equal on 3, the median 0.03% lower; on the cup (4 SFCe) it is no faster.
        ``"slp-ipopt"``: the sequential LP's rounds until one of them gains nothing or is
        rejected, IPOPT's rounds from there on (its trust region reopened to 0.5), so a run
        ends where IPOPT's model stops: on the same 8 seeds the lamp's median rho is IPOPT's
        (placement 1.24x and 0.94x as fast in two runs), the cup's 1.1% lower (1.17x), the
        pistol's with 7 PCwF 0.5% lower (1.02x). So neither is the default.
    lp_centre : bool
        Take each linear restricted problem's weights at the analytic centre of its near-optimal
        set (:class:`ExchangeLP`), not where the LP solver stops inside a non-unique optimum,
        and resolve ties between contacts and between working-set directions at the scale of
        the data, in index order (:mod:`closure_nlp.base.ties`), not by round-off:
        frictionless contacts then get the same placement in metres and in millimetres (a box
        x1000: the same positions to 3e-10 of the part's size; off: 11% apart in rho). Off by
        default: on the pistol's plans (7 FPC, seeds 1-9, one process, load 6-8) it ended worse
        on 4 seeds (by 20-55%), better on 4 (by 1-3%), the median rho -0.121 against -0.145,
        and 1.1-1.6x slower.
    min_spacing : float
        No two contacts (new or fixed) closer than this (model units; 0, the default: no
        limit). A run whose contacts end closer goes on with a constraint on every pair that
        can come closer in IPOPT's restricted problems; ``MethodError`` when no placement found
        keeps it.
    """

    gap: float = 1e-6
    max_rounds: int = 40
    starts: int = 4
    extra_starts: int = 8
    seed: int = 0
    subset_margin: float = 0.01
    random_directions: int = 20
    neighbour_moves: int = 20
    ipopt_tol: float = 1e-10
    certify: bool = True
    screen: bool = False
    probe_rounds: int = 0
    share_directions: bool = False
    move_rounds: int = 8
    round_search: bool = True
    validate: bool = True
    bound: bool = True
    target_gap: float = 0.02
    bound_cells: int = 500
    bound_neighbours: bool = False
    time_budget: float | None = None
    exchange_solver: str = "auto"
    lp_centre: bool = False
    min_spacing: float = 0.0

    def __post_init__(self) -> None:
        if self.exchange_solver not in EXCHANGE_SOLVERS:
            raise ValueError(
                f"exchange_solver: must be one of {', '.join(EXCHANGE_SOLVERS)}, "
                f"got {self.exchange_solver!r}"
            )
        for name in (
            "max_rounds",
            "random_directions",
            "neighbour_moves",
            "starts",
            "extra_starts",
            "seed",
            "probe_rounds",
            "move_rounds",
            "bound_cells",
        ):
            value = getattr(self, name)
            least = 1 if name in ("max_rounds", "starts", "bound_cells") else 0
            if not is_whole(value) or value < least:
                raise ValueError(f"{name}: expected an integer >= {least}, got {value!r}")
            object.__setattr__(self, name, int(value))  # a numpy integer stored as an int
        if not (isinstance(self.subset_margin, (int, float)) and self.subset_margin >= 0):
            raise ValueError(f"subset_margin: expected a number >= 0, got {self.subset_margin!r}")
        for name in ("gap", "ipopt_tol"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name}: expected a positive number, got {value!r}")
        if isinstance(self.target_gap, bool) or not (
            isinstance(self.target_gap, (int, float)) and 0 <= self.target_gap < 1
        ):
            raise ValueError(f"target_gap: expected a number in [0, 1), got {self.target_gap!r}")
        budget = self.time_budget
        if budget is not None and (
            isinstance(budget, bool)
            or not isinstance(budget, (int, float))
            or not 0 <= budget < np.inf
        ):
            raise ValueError(f"time_budget: expected seconds >= 0 or None, got {budget!r}")
        spacing = self.min_spacing
        if isinstance(spacing, bool) or not (
            isinstance(spacing, (int, float)) and 0 <= spacing < np.inf
        ):
            raise ValueError(f"min_spacing: expected a distance >= 0, got {spacing!r}")
        flags = ("certify", "screen", "share_directions", "round_search", "validate", "bound")
        flags += ("bound_neighbours",)
        for name in (*flags, "lp_centre"):
            object.__setattr__(self, name, as_flag(getattr(self, name), name))
