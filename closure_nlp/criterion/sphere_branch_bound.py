"""Certified ``min_{|u| = 1} p(u)`` by branch and bound over the sphere.

``p`` is the support function of a compact convex set ``W`` (:class:`WrenchSlots`): convex and
positively homogeneous, so every wrench ``w`` of ``W`` gives the linear lower bound
``p(x) >= w . x`` everywhere, and so does every convex combination ``wbar`` of such wrenches.

Cells. The sphere is the image of the 12 faces of the cube ``[-1, 1]^6`` (``x_k = +-1``); a cell
is a box of the other five coordinates. Its directions lie in the cap of centre ``c`` (the box
centre, normalised) and angular radius ``delta`` = the largest angle from ``c`` to a box corner
(``c . x / |x|`` is quasi-concave, so its minimum over a box is at a corner).

Bound of a cell. On a cap, ``min wbar . u = |wbar| cos(theta + delta)`` exactly, with ``theta`` the
angle between ``wbar`` and ``c``, that is ``cos(delta) wbar . c - sin(delta) |wbar_perp|``. The
support points of eleven directions of the cell (centre and the five axes' ends) are combined with
convex weights that maximise this concave expression (a few Frank-Wolfe steps with exact line
search; any weights give a valid bound). A single support point gives only a first-order bound
where ``p`` has a kink (a contact switching on, a cone's apex), and minima sit on such kinks; the
best combination of the support points from both sides of the kink is second-order accurate
there as on smooth minima, so few cells survive per level.

Support points. Besides the cell's own eleven, every cell may combine the point of ``W`` whose
bound its parent kept (a halved cell is first bounded by that point alone, and dropped before
its samples are taken when that suffices), the support points of a tiny cloud around the
incumbent (they hold every piece of ``p`` that meets at the minimum), and a cell that survives
near the minimum (any cell, in a set of few slots) gets those of a cloud around its lowest
sample, with a longer search of the weights (a matrix game over the cloud's points and those
the first weights hold). When these do not suffice, a set of few slots
gives each slot its own weights (:func:`closure_nlp.kernels.branch_bound.slot_bound`):
``p = sum_i max(P_i, 0)`` wherever some slot value is positive, so any slot-wise combination
of the slots' support points whose bound is positive over the cell bounds ``p`` there. A
contact seen nearly along its cone's axis has a sharply curved support over a cell; with
weights of its own, its points no longer share those of
the other slots. Larger sets add the support points of the cell's corners instead.

Incumbent. Every evaluated direction gives an upper bound ``p(u) >= min p``; the lowest is the
incumbent. When a cell's samples lower it, an optional local solver (``polish``) runs from there:
samples approach a minimum only to first order in the cell size, and with an incumbent that far
above the minimum whole neighbourhoods of it survive (an optimised lamp placement whose seed
search missed the global basin by 0.26%: 18.3 s and unconverged without, 0.9 s with). Cells
whose bound reaches the incumbent minus the allowed gap are dropped; the others are halved along
their widest coordinate, until none is left or the budget is spent, except a small cell holding
the incumbent: it is cut into nested shells round it, down to an inner box small enough that the
sphere's curvature costs it less than the gap (at a sharp minimum the shells drop at once, in
place of a chain of halvings). The minimum over the sphere
then lies in ``[min over dropped and live cells of their bounds, incumbent]``.

Symmetry. When turns about an axis map the set onto itself (:mod:`closure_nlp.criterion.symmetry`:
``n``
contacts equally spaced round a cylinder, coaxial round cones), ``p`` is constant on their
orbits and the search covers only boxes that meet every orbit, mapped onto that part of the
sphere by an invertible ``frame`` in place of the diagonal metric: ``n`` equal minima become
one, and a circle of equal minima (which no cell bound drops: its cells multiply at every
level) becomes a point. The detection's residuals give a ``slack``, subtracted from the lower
bound, so the bracket holds for inexact data too.

The rounds run compiled (:func:`closure_nlp.kernels.branch_bound.advance`), in one call until
the search ends or wants its incumbent polished; this module sets the budget and runs the
local solver. A long search's large rounds are dealt into two parts bounded apart, in two
threads when asked (:attr:`BranchBoundOptions.workers`): the same parts whatever the threads,
so the same answer.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from closure_nlp.base.validation import as_shaped, is_whole
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.cube_cells import face_cells
from closure_nlp.criterion.symmetry import find_symmetry
from closure_nlp.kernels import branch_bound as kernels

MAX_POLISH = 8  # local solves per branch and bound: each cheap; the first ones do the work
# Per unit of wrench scale: covers the float64 roundoff of support values and support points
# (a few ulps of sums of m terms), far below any tolerance of the package.
ROUNDOFF = 1e-13
CELLS_PER_ROUND = 128  # children per round while few cells live: fewer rounds
# Cells that hold the incumbent are cut into shells round it (the kernel's ``shells``) below
# this angular radius, each shell this many times smaller than the one outside it: against
# halving alone, larger factors sample fewer cells at sharp minima.
SHELLS_BELOW = 0.6
SHELLS_SHRINK = 8.0
# Sets of few slots (:data:`FEW_CONTACTS`) with friction, searched over the whole sphere, start
# from the 12 whole faces, cut the cell holding the incumbent into shells whatever its size,
# shells 3 times smaller each, in rounds of about 32 children. Their minima are sharp kinks (a
# contact carrying the load, others switching on there), whose shells drop at once where
# halving leaves the neighbours of the incumbent alive level after level: on 73 force-closure
# 4-PCwF sets sampled on a mesh, 141 cells against 300 at the median (1.35x less CPU), random
# mixed sets 1.2x. Not frictionless sets (7 FPC: 1.5x more CPU) nor symmetric domains (two
# opposite soft fingers: 1.4x more; round parts unchanged).
FEW_SLOTS_SHELLS = (0, 32, np.pi, 3.0)  # initial splits, cells per round, below, shrink
# Past ROUNDS_AFTER sampled cells, a round of at least ROUND_CELLS cells is dealt into two parts
# bounded apart (in two threads with BranchBoundOptions.workers >= 2). Only long searches get
# there (round parts, rings, many contacts: 4-6 SFCe round a cylinder 1.6x faster on two
# cores); a mesh-sampled 4-PCwF set takes 141 cells at the median, 1,100 at most.
ROUND_CELLS = 48
ROUNDS_AFTER = 500
# A symmetry is used when its slack (its detection's residuals) is at most this share of the gap.
SLACK_SHARE = 0.1
# Cells refined (:attr:`BranchBoundOptions.refine_below`) when smaller than this angular radius
# (0.05 -> 0.4: eligible lamp sets 2.3x faster, CPU; others 0.9-1.15x); in sets of at most
# FEW_CONTACTS slots, every cell: their games drop most coarse cells (13 force-closure 4-PCwF
# sets: 302 sampled cells against 701 at the median, 1.2x less CPU; the 9 eligible sets of 4
# lamp facets: 2.0x fewer cells, 1.2x less CPU). Not for many contacts, where a cloud costs m
# support values: 200 and 2,000 PCwF 0.88x and 0.81x.
REFINE_BELOW = 0.4
FEW_CONTACTS = kernels.SLOT_GAME_SLOTS


@dataclass(frozen=True)
class BranchBoundOptions:
    """Budget and shape of the search.

    Attributes
    ----------
    initial_splits : int, optional
        Halvings of every free coordinate of each cube face before the first bound (1: 32 cells
        per face, 384 in all). None: 0 for sets of at most :data:`FEW_CONTACTS` slots with
        friction searched over the whole sphere (:data:`FEW_SLOTS_SHELLS`), 1 otherwise.
    max_cells : int
        Cells bounded in all, beyond which the search stops with ``converged=False``, unless
        it may go on to ``extended_cells``.
    extended_cells, extension_alive : int
        Past ``max_cells``, the search goes on, up to ``extended_cells`` cells in all, while
        the cells alive after a round are at most ``extension_alive`` or twice as many as when
        it reached ``max_cells``. Measured: isolated but flat minima converge there (the round
        placements of the test suite, a pistol and a stepped-shaft placement: 100k-150k cells;
        a box's one-plane bound loses ``1 - cos(delta)`` of ``p``, so the cells alive are those
        within ``delta sqrt(p / curvature)`` of the minimum). Some keep 1,500-4,000 alive
        throughout; a shaft fixture's (7 PCwF, torque scale 1) rose from 1,900 at 40k cells to
        about 5,000, then fell to under 100 and converged at 84k. A continuum of minima (two
        opposite soft fingers, searched over the whole sphere) grows level after level and may
        need all of ``extended_cells``. ``max_cells`` or less: no extension.
    max_rounds : int
        Rounds of splitting (each halves every live cell once).
    fw_steps : int
        Frank-Wolfe steps that choose the convex weights of a cell's support points.
    refine_below : float, optional
        Angular radius under which a cell that survives its first bound gets more support
        points (a cloud around its lowest sample, then its corners) and a longer search of
        their weights: near the minimum, where the kinks of ``p`` meet. None: every cell of a
        set of few slots (:data:`FEW_CONTACTS`), :data:`REFINE_BELOW` otherwise.
        Not a cell whose lowest sample lies within ``|target| delta^2`` of the drop threshold
        (:data:`closure_nlp.kernels.branch_bound.HOPELESS`): linear bounds lose about that
        much there, and its children are cheaper.
    stop_below_zero : bool
        Stop, unconverged, at the first direction with ``p < 0``: the origin is then outside the
        set, where :mod:`closure_nlp.criterion.hull_distance` is exact and much faster.
    symmetry : bool
        Search only a fundamental domain of the turns that map the set onto itself
        (:mod:`closure_nlp.criterion.symmetry`), when there are: a circle of equal minima becomes a
        point, ``n`` equal minima one.
    workers : int
        Threads for the rounds of a long search: past :data:`ROUNDS_AFTER` sampled cells, a
        round of at least :data:`ROUND_CELLS` cells is dealt alternately into two parts, each
        bounded and split from its own copy of the search's state, whatever ``workers`` is (so
        every value gives the same bits); with ``workers >= 2`` the two parts run at once.
    """

    initial_splits: int | None = None
    max_cells: int = 40_000
    extended_cells: int = 400_000
    extension_alive: int = 20_000
    max_rounds: int = 200
    fw_steps: int = 12
    refine_below: float | None = None
    stop_below_zero: bool = True
    symmetry: bool = True
    workers: int = 1

    def __post_init__(self) -> None:
        names = ("initial_splits", "max_cells", "extended_cells", "extension_alive", "max_rounds")
        for name in (*names, "fw_steps", "workers"):
            value = getattr(self, name)
            if value is None and name == "initial_splits":
                continue
            least = 0 if name == "initial_splits" else 1
            if not is_whole(value) or value < least:
                raise ValueError(f"options.{name}: must be an integer >= {least}, got {value!r}")
            object.__setattr__(self, name, int(value))


@dataclass(frozen=True, eq=False)
class SphereBounds:
    """``lower <= min_{|u|=1} p(u) <= upper = p(direction)``.

    Attributes
    ----------
    lower, upper : float
    direction : (6,) float
        Unit direction of the incumbent.
    converged : bool
        Every cell was dropped: ``upper - lower`` is within the gap asked for.
    cells : int
        Cells sampled and bounded (not those a halved cell's inherited point dropped first).
    evaluations : int
        Directions at which ``p`` and a support point were evaluated.
    rounds : int
    seconds : float
    """

    lower: float
    upper: float
    direction: np.ndarray = field(repr=False)
    converged: bool
    cells: int
    evaluations: int
    rounds: int
    seconds: float


def sphere_minimum(
    slots: WrenchSlots,
    incumbent: np.ndarray | None = None,
    *,
    gap: float,
    metric=None,
    options: BranchBoundOptions = BranchBoundOptions(),
    polish=None,
) -> SphereBounds:
    """Certified bounds on ``min_{|u|=1} p(u)`` with ``upper - lower <= gap`` when converged.

    Parameters
    ----------
    slots : WrenchSlots
    incumbent : (6,) float, optional
        A good direction (e.g. a local solver's): its value starts the incumbent.
    gap : float
        Absolute gap to reach (callers make it relative to the wrench scale).
    metric : (6,) float, optional
        Positive diagonal ``D``: the cells are boxes of the cube's faces mapped by ``D``, so a
        set whose torque rows are ``k`` times its force rows is partitioned as evenly as an
        isotropic one with ``D = (1, 1, 1, 1/k, 1/k, 1/k)`` (``p_W(D v / |D v|) = p_{DW}(v) /
        |D v|``). Any positive ``D`` covers the sphere: only the work changes.
    options : BranchBoundOptions
        With ``symmetry``, the search covers a fundamental domain of the set's turns when it
        has any and their slack is at most :data:`SLACK_SHARE` of ``gap``; the whole sphere
        otherwise.
    polish : callable, optional
        ``polish(u) -> (6,)``: a local minimiser of ``p`` started at ``u``, run (at most
        :data:`MAX_POLISH` times) from the incumbent whenever samples lowered it by more than
        the gap. Its direction only enters as an evaluated sample, so any answer is safe.

    The search stops early, unconverged, when it finds ``p(u) < 0`` while ``stop_below_zero``:
    the origin is then outside the set, where :mod:`closure_nlp.criterion.hull_distance` is exact.
    """
    start = time.perf_counter()
    metric = np.ones(6) if metric is None else as_shaped(metric, "metric", (6,)).astype(float)
    if not np.all(metric > 0) or not np.all(np.isfinite(metric)):
        raise ValueError(f"metric: expected six positive finite numbers, got {metric.tolist()}")
    margin = ROUNDOFF * max(slots.row_scales()) * max(1, slots.m)
    symmetry = find_symmetry(slots) if options.symmetry else None
    symmetric = symmetry is not None and symmetry.slack <= SLACK_SHARE * gap
    splits, per_round, below, shrink = _shells(slots, options, symmetric)
    if symmetric:
        # min over the domain - slack <= min over the sphere <= min over the domain
        frame, *cells = symmetry.domain(metric, incumbent, splits)
        slack = symmetry.slack
        floor = np.linalg.svd(frame, compute_uv=False).min()
    else:
        frame, cells, slack = np.diag(metric), face_cells(splits), 0.0
        floor = metric.min()  # the least singular value of a positive diagonal, exactly
    packed = slots.packed
    search = _Search(packed, polish)
    if incumbent is not None:
        search.consider(incumbent, "incumbent")
    search.tally[kernels.POLISHED_AT] = search.best[0]  # a polish is due below the start
    settings = np.array(
        [
            gap - slack,
            margin,
            options.fw_steps,
            _refine_below(slots, options.refine_below),
            options.max_cells,
            options.extended_cells,
            options.extension_alive,
            options.max_rounds,
            options.stop_below_zero,
            per_round,
            0 if polish is None else MAX_POLISH,
            floor,
            below,
            shrink,
            ROUND_CELLS,
            ROUNDS_AFTER,
        ],
        dtype=float,
    )
    pool = None
    cells = (*cells, kernels.none_inherited(len(cells[0])))
    status, cells = search.run(cells, kernels.FRESH, frame, settings)
    try:
        while status == kernels.ROUND:
            if pool is None and options.workers > 1:
                pool = ThreadPoolExecutor(2)
            status, cells = _dealt_round(search, cells, frame, settings, pool)
            if status == kernels.ROUND and len(cells[0]) < ROUND_CELLS:
                status, cells = search.run(cells, kernels.CHILDREN, frame, settings)
    finally:
        if pool is not None:
            pool.shutdown()
    lower = search.tally[kernels.LOWER] - slack
    return SphereBounds(
        float(min(lower, search.best[0])),
        float(search.best[0]),
        search.best_u.copy(),
        status == kernels.CONVERGED,
        int(search.tally[kernels.CELLS]),
        int(search.best[1]),
        int(search.tally[kernels.ROUNDS]),
        time.perf_counter() - start,
    )


class _Search:
    """What :func:`kernels.advance` carries between calls: incumbent, anchor, tally."""

    STATE = ("best", "best_u", "anchor", "anchor_at", "tally")

    def __init__(self, packed, polish, copy_of=None):
        self.packed, self.polish = packed, polish
        if copy_of is not None:
            for name in self.STATE:
                setattr(self, name, getattr(copy_of, name).copy())
            return
        self.best, self.best_u = np.array([np.inf, 0.0]), np.zeros(6)
        self.anchor, self.anchor_at = np.empty((kernels.ANCHORS, 6)), np.zeros(7)
        self.tally = np.array([np.inf, 0, 0, -1, np.inf, 0, np.inf], dtype=float)

    def consider(self, u, name: str) -> None:
        u = np.asarray(as_shaped(u, name, (6,)), dtype=float)
        U = (u / np.linalg.norm(u))[None]
        kernels.consider(*self.packed, U, np.empty((1, 6)), self.best, self.best_u)

    def run(self, cells, stage, frame, settings) -> tuple:
        """Rounds from cells (axis, sign, lo, hi, lin) at ``stage`` (FRESH or CHILDREN) until
        the search ends or returns a round's children (``(status, cells)``), with the polishes
        it asks for."""
        cells = (*cells, *kernels.no_samples())
        while True:
            status, *cells = kernels.advance(
                *self.packed, *cells, stage, frame, self.best, self.best_u, self.anchor,
                self.anchor_at, self.tally, settings,
            )  # fmt: skip
            if status != kernels.POLISH:
                return status, tuple(cells[:5])
            self.consider(self.polish(self.best_u.copy()), "polish(u)")
            self.tally[kernels.POLISHES] += 1
            self.tally[kernels.POLISHED_AT] = self.best[0]
            stage = kernels.EVALUATED  # the same cells: on to their bounds


def _dealt_round(search: _Search, cells, frame, settings, pool) -> tuple:
    """One round of many cells dealt alternately into two parts, each bounded and split from a
    copy of the search's state (at once in ``pool``'s two threads, when given), then merged
    into ``search``: the same two parts with a pool or without, so the same bits. Returns
    (status, the live cells: CONVERGED, BUDGET and BELOW_ZERO leave none to go on with)."""
    parts = [tuple(np.ascontiguousarray(c[k::2]) for c in cells) for k in range(2)]
    copies = [_Search(search.packed, search.polish, copy_of=search) for _ in parts]
    one_round = settings.copy()
    one_round[kernels.ROUND_CELLS] = one_round[kernels.ROUNDS_AFTER] = 0
    one_round[kernels.CELLS_PER_ROUND] = settings[kernels.CELLS_PER_ROUND] / 2
    one_round[kernels.EXTENSION_ALIVE] = settings[kernels.EXTENSION_ALIVE] / 2

    def run(k):
        return copies[k].run(parts[k], kernels.CHILDREN, frame, one_round)

    ends = [run(k) for k in range(2)] if pool is None else list(pool.map(run, range(2)))
    _merge(search, copies)
    statuses = [status for status, _ in ends]
    if kernels.BELOW_ZERO in statuses:
        search.tally[kernels.LOWER] = -np.inf
        return kernels.BELOW_ZERO, ()
    if kernels.BUDGET in statuses:  # the other part's live cells count in the lower bound
        for status, copy in zip(statuses, copies):
            if status == kernels.ROUND:
                low = min(search.tally[kernels.LOWER], copy.tally[kernels.LIVE_LOWER])
                search.tally[kernels.LOWER] = low
        return kernels.BUDGET, ()
    live = [part for status, part in ends if status == kernels.ROUND]
    if not live:
        return kernels.CONVERGED, ()
    return kernels.ROUND, tuple(np.concatenate(arrays) for arrays in zip(*live))


def _merge(search: _Search, copies: list) -> None:
    """The parts' states into ``search``: the lower incumbent (the first part's on a tie), with
    its anchor; counts summed; the least bound of dropped cells."""
    base_tally, base_evaluations = search.tally.copy(), search.best[1]
    winner = min(copies, key=lambda c: c.best[0])  # min keeps the first of equals
    for name in _Search.STATE:
        setattr(search, name, getattr(winner, name).copy())
    t = search.tally
    t[kernels.LOWER] = min(c.tally[kernels.LOWER] for c in copies)
    for k in (kernels.CELLS, kernels.POLISHES):
        t[k] = base_tally[k] + sum(c.tally[k] - base_tally[k] for c in copies)
    t[kernels.ROUNDS] = base_tally[kernels.ROUNDS] + 1
    reached = [c.tally[kernels.ALIVE_AT_BUDGET] for c in copies]
    if base_tally[kernels.ALIVE_AT_BUDGET] < 0 and max(reached) >= 0:
        t[kernels.ALIVE_AT_BUDGET] = sum(max(r, 0) for r in reached)
    search.best[1] = base_evaluations + sum(c.best[1] - base_evaluations for c in copies)


def _shells(slots: WrenchSlots, options: BranchBoundOptions, symmetric: bool) -> tuple:
    """(initial splits, cells per round, shells below, shells' shrink) for this set, searched
    over a symmetry's domain or not (:data:`FEW_SLOTS_SHELLS`)."""
    if slots.m <= FEW_CONTACTS and any(slots.n_pieces) and not symmetric:
        splits, per_round, below, shrink = FEW_SLOTS_SHELLS
    else:
        splits, per_round, below, shrink = 1, CELLS_PER_ROUND, SHELLS_BELOW, SHELLS_SHRINK
    if options.initial_splits is not None:
        splits = options.initial_splits
    return splits, per_round, below, shrink


def _refine_below(slots: WrenchSlots, refine_below: float | None) -> float:
    """The angular radius under which cells are refined
    (:attr:`BranchBoundOptions.refine_below`)."""
    if refine_below is not None:
        return float(refine_below)
    return np.pi if slots.m <= FEW_CONTACTS else REFINE_BELOW


def _initial_cells(splits: int):
    """Every cube face cut into ``2^(5 splits)`` boxes: axis, sign, lo, hi."""
    return face_cells(splits)
