"""A certified ceiling on the best placement: no contacts on the given elements hold more.

For contacts ``c`` (contact ``i`` at a point ``c_i`` of its element) the load capacity is
``-rho(c) = min_{|u|=1} p(u; c)``. This module bounds ``max_c -rho(c)`` from above over every
placement in a *domain*: for each contact, a list of convex pieces (facets, sub-triangles,
segments, sub-segments, points), each with one inward normal.

The bound (proof)
-----------------
Let ``P_i(u; c_i)`` be contact ``i``'s support value and ``p = sum_i max(P_i, 0) +
min(max_i P_i, 0)`` (eq 26: the sum of the positive ``P_i`` if any is positive, otherwise the
largest). Since ``min(max_i P_i, 0) <= 0``, in every case

    (1)  p(u; c) <= s(u; c) := sum_i max(0, P_i(u; c_i)).

On a piece the normal is fixed and the grasp matrix ``G(c_i)`` is affine in the position
(force rows constant, torque rows ``torque_scale * r x frame`` linear in ``r``, spin column
constant), so ``d = G(c_i)^T u`` is affine in ``c_i`` and ``P_i = f_max (d_n + phi(d))`` with
``phi`` a norm or a max of norms (PCwF, SFCl, SFCe; ``phi = 0`` for FPC) is convex in ``c_i``;
so is ``max(0, P_i)``. For ``c_i = sum_r lam_ir v_r`` (barycentric weights over the vertices
``v_r`` of the piece holding ``c_i``) Jensen's inequality gives

    (2)  max(0, P_i(u; c_i)) <= sum_r lam_ir a_ir(u),   a_ir(u) := max(0, P_i(u; v_r)).

A point is a piece of one vertex (``lam = 1``, (2) an equality). Let ``lam_i`` range over the
simplex of *all* vertex rows of contact ``i``'s pieces (a placement puts its weight on one piece;
the others' weights zero): a relaxation, so still an upper bound. For any finite set ``U`` of
unit directions, with ``g(u; lam) = sum_ir lam_ir a_ir(u)``,

    -rho(c) = min_{|u|=1} p(u; c) <= min_{u in U} p(u; c) <= min_{u in U} g(u; lam(c))
            <= T(U) := max_lam min_{u in U} g(u; lam),

a linear programme (``max t`` s.t. ``t <= sum_ir lam_ir a_ir(u_k)``, ``lam_i`` in simplices).
The value reported is not HiGHS's but its weak dual, recomputed here: for any ``y >= 0`` on
``U`` with ``sum_k y_k = 1`` and any feasible ``lam``,
``min_k g(u_k; lam) <= sum_k y_k g(u_k; lam) = sum_ir lam_ir (y^T A)_ir
<= sum_i max_r (y^T A)_ir =: D(y)``. So ``D(y)`` of the solver's (clipped, normalised) dual bounds
every placement whatever the solver's accuracy; a relative margin covers the round-off of the
``a_ir`` (a few ulps). ``T(U) >= 0`` always: ``0`` proves that no placement in the domain is
force closure.

Tightening
----------
*Cuts*: at the LP's ``lam*`` the directions that minimise ``g(u; lam*)`` over the sphere (a
convex, positively homogeneous function: the support function of ``sum_ir lam_ir conv(W_ir, 0)``,
found by the batched descent of :mod:`closure_nlp.criterion.sphere_search` on slots with ``f_max``
scaled
by
``lam_ir``) are added to ``U`` while they lie below the LP value. *Branching*: a contact with
several pieces is split into its heaviest piece and the rest; a contact on one piece has it
halved (longest edge of a triangle, across the longest extent of a polygon, midpoint of a
segment); the
interpolation error of (2) shrinks with the piece's size. The contact split is the one whose
piece has the largest moment ``size * f_max``: the torque its force can make across the piece,
which (2) lets the vertices' weights make as if several contacts pushed there. The bound depends
on the whole piece, not on the LP's point in it (lamp, 2000 cells: ceiling 0.5404 against 0.5443
when splitting the contact of largest dual-weighted Jensen gap at the LP's point); measured
against the piece's size relative to its element, the moment narrows the gap on elements of
unequal sizes (the pistol's 3 contacts, 300 cells: ceiling 0.123 against 0.212). Cells whose
bound is at most the certified capacity of the best placement known are closed; the ceiling is
the largest bound of all leaves (open or closed).

Why cells, not a tighter LP: the points ``(a_ir(u_k))_k`` of a contact's vertices are values
of the contact at those points, and (2) puts every other point of the piece below their convex
hull, so the rows of ``lam_i`` describe exactly the convex hull of the contact's values
``(max(0, P_i(u_k; c_i)))_k`` over its piece. No relaxation of one contact at a time (exact
friction cones, McCormick envelopes of its force-position products, a Lagrangian bound, whose
value ``min_y sum_i max_r (y^T A)_ir`` is the LP's) can be tighter. What the LP loses is
only the minimum over directions taken on that hull, a coupling of the contacts that only a
partition of the placements (cells) narrows.

*Facets*: with frictionless contacts only, a cell whose pieces are all small (at most
:data:`FACET_SIZE` of their elements) is also bounded by the facets of its zonotope
(:func:`closure_nlp.criterion.frictionless.facet_rows`, proved there): affine rows in the same
weights
whose
error is of second order in the pieces' sizes, with no kink at the contacts on a facet; the
cell's bound is the least of the two LPs' weak duals (both certified).

*Probes*: a split cell's LP placement (each contact at the weights' point on its heaviest
piece) gets a light rho search. Its weakest direction joins the working set: the cut descent
starts on the LP's weights and can miss it, and without it cells shrunk to points kept bounds
above every placement in them (the cup's 3 SFCe: the ceiling stayed 4% above for hundreds of
cells). When the light search's value beats the incumbent, the full search judges it (adding
its direction too), and the placement, certified, becomes the incumbent when it holds more: as
the cells shrink round the best placement, their LP placements approach it.

Incumbents also come from the exchange method (:class:`~closure_nlp.placement.placer.Placer`)
started at the LP's placement in the best cell (``polish_every``; an exchange run costs as much
as hundreds of cells), every value certified by
:func:`closure_nlp.criterion.support_minimum.rho`. With frictionless contacts only, a climb on the
closed-form capacity of their zonotope (:mod:`closure_nlp.criterion.frictionless`) first searches
the
root (random starts) and each such cell (the LP's placement and random starts), and the exchange
method starts from its best placements: thousands of capacities cost less than one exchange run,
and the climb reaches placements the exchange method, a local method, stops short of
(docs/placement.md, the pistol).
"""

from __future__ import annotations

import heapq
import time
from collections import OrderedDict
from dataclasses import dataclass, field, replace

import numpy as np

from closure_nlp.contact.contact_set import grasp_matrices, is_frictionless
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import tolerance_unit
from closure_nlp.criterion.frictionless import MAX_CONTACTS, climb, facet_rows
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.sphere_search import descend, sphere_samples
from closure_nlp.criterion.support_minimum import search_rho
from closure_nlp.model.elements import nearest_weights
from closure_nlp.placement import max_min_lp as lp_solvers  # tests swap its solvers
from closure_nlp.placement.max_min_lp import INF, OPTIMAL, dual_bound, max_min_model, thread_solver
from closure_nlp.placement.placer import ExchangePlacer, PlacementOptions
from closure_nlp.placement.spacing import SpacingError
from closure_nlp.selection.algorithms import SCREEN_SEARCH

# Directions kept in the shared working set of the cutting planes (the most recent ones).
MAX_DIRECTIONS = 600
# Pieces whose vertices' grasp matrices a CellLP keeps (the most recently used).
KEPT_GRASPS = 4096
# Row generation adds at most this many rows per solve, while the LP's weights fall below
# (1 - ROW_TOLERANCE) times its value on them.
ADDED_ROWS = 24
ROW_TOLERANCE = 1e-6
# The cut descent starts from the working set's directions lowest at the LP's weights, and at
# the root from this many quasi-random directions besides (+-e_k always).
CUT_LOWEST = 12
ROOT_CUT_SAMPLES = 24
CUT_ITERATIONS = 60
# A probed placement that may beat the incumbent is certified at once when its search value
# beats it by more than this share, else only the best such one, when the search ends (a
# certificate costs as much as several cells).
PROBE_STEP = 0.01
# Exchange runs from cells under a budget of cells alone (polish_every apart): they find
# better placements than the probes (the lamp's 3 and 4 SFCe, 0.3-1.2%), and more of them
# cost more than the cells.
CELL_BUDGET_POLISHES = 2
# Frictionless contacts: the climb on their zonotope's closed-form capacity (members,
# iterations) at the root and at a cell, and the root's placements polished by the exchange
# method. The root's (200, 100) gets most of what three times the members and twice the steps
# reach, at a sixth of their time, which every frictionless placement with a ceiling pays.
CLIMB_ROOT = (200, 100)
CLIMB_CELL = (100, 60)
CLIMB_POLISHES = 2
# The zonotope's facet bound is computed on cells whose pieces are all at most this size
# against their elements: above it the signs it needs are seldom fixed (pistol 7 FPC around its
# best placement: bound at pieces of 0.1 of their elements, none at 0.25), and it costs about
# as much as a cell's LP.
FACET_SIZE = 0.2


@dataclass(frozen=True)
class BoundOptions:
    """Options of :func:`capacity_bound`.

    Attributes
    ----------
    gap : float
        Stop when ``(ceiling - capacity) / ceiling <= gap`` (relative, >= 0).
    time_budget : float
        Seconds the branch and bound may run (``inf``: no limit; the root LP is always solved);
        when it ends first, the gap reached is reported as such.
    root_cuts : int
        Cutting-plane rounds at the root cell.
    cell_cuts : int
        Cutting-plane rounds at every other cell.
    cut_tolerance : float
        A round adds directions only while the descent finds ``g(u; lam*)`` below the LP value by
        more than this fraction of it.
    max_nodes : int
        Cells bounded at most (a budget independent of the machine's speed).
    polish_every : int
        Every that many cells, the exchange method is started at the best open cell's LP
        placement (0: never)...
    polish_share : float
        ... and, under a finite ``time_budget``, only while the exchange runs have taken at
        most this share of the time spent (1: always). Without a time budget the cells alone
        decide when they run: the same answer on any machine.
    polish_runs : int or None
        Those exchange runs at most (None: no limit).
    cut_samples : int
        Quasi-random starts (besides ``+-e_k`` and the working set's lowest directions) of a
        cell's cut descent; the root's always has 24. Fewer make cells cheaper and looser
        (without any, the cup's ceiling after 800 cells is 2-3% higher).
    lp_rows : int
        Rows (directions) a cell's LP starts with, the parent's active ones besides; the
        working set's others join where the LP's weights fall below its value on them (row
        generation, same bound). 0: every row from the start.
    probe_every : int
        Every that many splits, a light rho search at the split cell's LP placement: its
        weakest direction joins the working set (a cut the descent on the LP's weights can
        miss: without it, cells shrunk to points kept bounds 4% above any placement in them,
        cup, 3 SFCe), and with ``probe_incumbents`` the placement, judged by the full search
        and certified, becomes the incumbent when it holds more (0: never). A probe costs about
        a cell; an exchange run (``polish_every``) hundreds.
    probe_incumbents : bool
        Whether probed placements may replace the incumbent (the part's ceiling keeps the
        plan's).
    """

    gap: float = 0.02
    time_budget: float = 30.0
    root_cuts: int = 30
    cell_cuts: int = 1
    cut_tolerance: float = 1e-3
    max_nodes: int = 100_000
    polish_every: int = 20
    polish_share: float = 0.3
    polish_runs: int | None = None
    cut_samples: int = 24
    lp_rows: int = 24
    probe_every: int = 2
    probe_incumbents: bool = True

    def __post_init__(self) -> None:
        for name in ("gap", "time_budget", "cut_tolerance", "polish_share"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise ValueError(f"{name}: expected a number >= 0, got {value!r}")
            if not np.isfinite(value) and name != "time_budget":
                raise ValueError(f"{name}: expected a finite number, got {value!r}")
        names = ("root_cuts", "cell_cuts", "max_nodes", "polish_every", "cut_samples", "lp_rows")
        names += ("probe_every",) + (() if self.polish_runs is None else ("polish_runs",))
        for name in names:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{name}: expected an integer >= 0, got {value!r}")


@dataclass(frozen=True, eq=False)
class Piece:
    """A convex part of one element: ``vertices`` (k, 3) (k = 1 point, 2 segment, >= 3 polygon,
    in order around it), the element's ``inward_normal`` (3,) and its id ``element``."""

    element: int
    vertices: np.ndarray
    inward_normal: np.ndarray

    @property
    def size(self) -> float:
        v = self.vertices
        return float(np.max(np.linalg.norm(v[:, None] - v[None], axis=2))) if len(v) > 1 else 0.0

    def halves(self) -> tuple[Piece, Piece] | None:
        """Two pieces covering this one (None for a point)."""
        v, k = self.vertices, len(self.vertices)
        if k == 1:
            return None
        if k == 2:
            mid = v.mean(axis=0)
            return self._with(np.array([v[0], mid])), self._with(np.array([mid, v[1]]))
        if k == 3:  # bisect the longest edge
            edges = [np.linalg.norm(v[(j + 1) % 3] - v[j]) for j in range(3)]
            j = int(np.argmax(edges))
            a, b, c = v[j], v[(j + 1) % 3], v[(j + 2) % 3]
            mid = 0.5 * (a + b)
            return self._with(np.array([a, mid, c])), self._with(np.array([mid, b, c]))
        # a polygon: cut across its longest extent (the line through the midpoint of its two
        # farthest vertices, square to them): cuts along diagonals leave slivers as long as the
        # polygon (a rectangle's two triangles, a round facet's halves keep its diameter), so
        # the bound would hardly narrow (the pistol's 3 PCwF, 300 cells: gap 44% -> 29%)
        d = np.linalg.norm(v[:, None] - v[None], axis=2)
        a, b = np.unravel_index(int(np.argmax(d)), d.shape)
        side = (v - 0.5 * (v[a] + v[b])) @ (v[b] - v[a])
        return self._with(_clipped(v, -side)), self._with(_clipped(v, side))

    def _with(self, vertices: np.ndarray) -> Piece:
        return Piece(self.element, vertices, self.inward_normal)


def _clipped(v: np.ndarray, side: np.ndarray) -> np.ndarray:
    """The part of the convex polygon ``v`` (vertices in order) where the affine function
    with values ``side`` at its vertices is <= 0, in the same order."""
    out = []
    for j in range(len(v)):
        k = (j + 1) % len(v)
        if side[j] <= 0.0:
            out.append(v[j])
        if (side[j] < 0.0 < side[k]) or (side[k] < 0.0 < side[j]):
            t = side[j] / (side[j] - side[k])
            out.append(v[j] + t * (v[k] - v[j]))
    return np.array(out)


@dataclass(frozen=True, eq=False)
class CellBound:
    """The LP bound of one cell (one list of pieces per contact).

    Attributes
    ----------
    value : float
        Certified: no placement in the cell has ``-rho`` above it.
    lam : (R,) float
        The LP's weights over the cell's vertex rows (contact by contact).
    y : (N,) float
        The dual weights over ``directions``.
    directions : (N, 6) float
    lp_value : float
        HiGHS's optimum (for information; ``value`` is its recomputed dual).
    """

    value: float
    lam: np.ndarray
    y: np.ndarray
    directions: np.ndarray
    lp_value: float


@dataclass(frozen=True, eq=False)
class CapacityBound:
    """Outcome of :func:`capacity_bound`.

    Attributes
    ----------
    value : float
        Certified ceiling: every placement in the domain has ``-rho <= value`` (``>= 0``; within
        the certificate's accuracy of 0 (``1e-6`` of the set's wrench scale) it shows that none
        is force closure, and the search ends there).
    capacity : float
        Certified capacity of the best placement known: ``-hi`` of its rho bracket (``-rho``
        when it has no bracket), ``<= -rho`` of that placement.
    gap : float or None
        ``(value - capacity) / value`` when ``capacity > 0`` (the best placement is force
        closure), else None: a relative gap to a ceiling means nothing below zero capacity.
    placement : object or None
        The best placement found (a :class:`~closure_nlp.placement.placer.PlacementResult`), or None
        when none beat the one given.
    nodes : int
        Cells bounded (the root included).
    open_cells : int
        Cells left open when the search ended.
    reached : bool
        The gap target was reached (else the time budget or node limit ended the search).
    domain : tuple of tuple of int
        The element ids each contact may sit on.
    seconds : float
    """

    value: float
    capacity: float
    gap: float | None
    placement: object
    nodes: int
    open_cells: int
    reached: bool
    domain: tuple[tuple[int, ...], ...]
    seconds: float
    root_value: float = np.nan
    cuts: int = 0
    polishes: int = 0
    history: tuple = field(default=(), repr=False)

    def trend(self) -> tuple[float | None, float | None, float | None]:
        """``(root_gap, gap_per_second, gap_per_cell)``: the gap after the root cell, and how
        fast the gap fell over the last quarter of the search's time and of its cells (relative
        gap per second and per cell; None without a force-closure placement, or when the
        search did not go past its root cell)."""
        gaps = [(t, n, relative_gap(c, b)) for t, c, b, n in self.history]
        root = gaps[0][2] if gaps else None
        if self.nodes <= 1 or len(gaps) < 2 or gaps[-1][2] is None:
            return root, None, None
        return root, _fall(gaps, 0), _fall(gaps, 1)

    def to_dict(self) -> dict:
        root_gap, per_second, per_cell = self.trend()
        return {
            "root_gap": root_gap,
            "gap_per_second": per_second,
            "gap_per_cell": per_cell,
            "capacity_bound": self.value,
            "gap": self.gap,
            "gap_reached": self.reached,
            "nodes": self.nodes,
            "open_cells": self.open_cells,
            "root_bound": self.root_value,
            "bound_elements": [list(d) for d in self.domain],
            "bound_seconds": self.seconds,
        }


def _fall(gaps, at: int) -> float | None:
    """How fast the gap fell over the last quarter of ``gaps`` ((seconds, cells, gap) rows) in
    their column ``at`` (seconds or cells): gap per unit, ``>= 0``; None over no span."""
    end, last = gaps[-1][at], gaps[-1][2]
    recent = [(row[at], row[2]) for row in gaps if row[at] >= 0.75 * end and row[2] is not None]
    start, first = recent[0]
    if end - start <= 0:  # one step in the last quarter: the rate over the whole search
        start, first = next((row[at], row[2]) for row in gaps if row[2] is not None)
    if end - start <= 0:
        return None
    return max(0.0, (first - last) / (end - start))


def relative_gap(ceiling: float, capacity: float) -> float | None:
    """``(ceiling - capacity) / ceiling`` for a force-closure placement (``capacity > 0``), else
    None."""
    if not capacity > 0.0 or not ceiling > 0.0:
        return None
    return max(0.0, (ceiling - capacity) / ceiling)


class CellLP:
    """The LP bound and its cutting planes for cells of one eligibility (model and specs)."""

    def __init__(self, eligibility: Eligibility):
        self.eligibility = eligibility
        model = eligibility.model
        self.reference = model.reference_point
        self.directions = np.asarray(sphere_samples(40, seed=3), float).copy()
        self.cuts = 0
        self.frictionless = _frictionless(eligibility)
        self._grasp: OrderedDict[Piece, np.ndarray] = OrderedDict()

    def grasp(self, piece: Piece) -> np.ndarray:
        """The grasp matrices of a piece's vertices: a cell shares all but one contact's
        pieces with its parent, so the most recent pieces' are kept."""
        G = self._grasp.get(piece)
        if G is None:
            ts = self.eligibility.torque_scale
            G = grasp_matrices(piece.vertices - self.reference, piece.inward_normal, ts)
            self._grasp[piece] = G
            if len(self._grasp) > KEPT_GRASPS:
                self._grasp.popitem(last=False)
        else:
            self._grasp.move_to_end(piece)
        return G

    def rows(self, cell) -> tuple[WrenchSlots, list[np.ndarray], list[int]]:
        """The cell's vertex rows: slots (one per contact, one row per piece vertex), each
        contact's vertex positions (R_i, 3) and its rows' count."""
        slots, positions, counts = [], [], []
        for spec, pieces in zip(self.eligibility.all_specs, cell):
            G = np.concatenate([self.grasp(p) for p in pieces])
            slots.append((G, spec.type, spec.mu, spec.mu_s, spec.f_max))
            positions.append(np.concatenate([p.vertices for p in pieces]))
            counts.append(len(G))
        return WrenchSlots.build(slots), positions, counts

    def bound(
        self,
        cell,
        rounds: int,
        tolerance: float,
        deadline: float = np.inf,
        hint=None,
        rows: int = 0,
        samples: int = ROOT_CUT_SAMPLES,
        floor: float = -np.inf,
        warm: bool | None = None,
    ) -> CellBound:
        """The cell's certified LP bound after at most ``rounds`` cutting-plane rounds (none
        begun after ``deadline``, a :func:`time.perf_counter` value). With ``rows`` > 0 the LP
        starts on ``hint`` (optional (K, 6) directions, a parent cell's active ones) and the
        ``rows`` directions of the working set lowest at uniform weights; the others join only
        where the LP's weights fall below its value on them (:meth:`_solve_rows`). ``samples``:
        quasi-random starts of the cut descent. For frictionless contacts each on one piece the
        bound is the least of this LP's and the zonotope's facet bound (:meth:`facet_bound`),
        and the LP is skipped when the facet bound is at most ``floor`` (the cell closes).
        ``warm``: whether the LP's re-solves start from its last basis (default: unless every
        contact is frictionless, see below)."""
        facet = self.facet_bound(cell)
        if facet <= floor:
            lam = np.concatenate([np.full(len(p.vertices), 1.0 / len(p.vertices)) for (p,) in cell])
            return CellBound(facet, lam, np.zeros(0), np.zeros((0, 6)), facet)
        slots, _, counts = self.rows(cell)
        owner = np.repeat(np.arange(len(counts)), counts)
        pool = self.directions if hint is None else np.vstack([hint, self.directions])
        A = np.maximum(slots.row_values(pool), 0.0)
        work = self._first_rows(A, owner, len(hint) if hint is not None else 0, rows)
        # Frictionless contacts: the LP's weights start the climb to placements, and an LP kept
        # warm ends at another point of its optimal face, from which the climbs ended worse (96
        # fixture-study FPC tasks: 35 worse, 19 better, rho summed 1-3% weaker): solved afresh
        # where a climb starts from them.
        lp = _GrowingLP(owner, keep_basis=not self.frictionless if warm is None else warm)
        for k in range(rounds + 1):
            result = self._solve_rows(A, owner, pool, work, lp)
            work = lp.rows
            if k == rounds or time.perf_counter() > deadline:
                break
            new = self._cuts(slots, result, owner, samples)
            lowest = g_values(slots, result.lam, new)
            keep = new[lowest < result.lp_value * (1.0 - tolerance)]
            if not len(keep):
                break
            self.cuts += len(keep)
            work = np.concatenate([work, len(pool) + np.arange(len(keep))])
            pool = np.vstack([pool, keep])
            A = np.vstack([A, np.maximum(slots.row_values(keep), 0.0)])
            self.directions = np.vstack([self.directions, keep])[-MAX_DIRECTIONS:]
        if facet < result.value:
            result = replace(result, value=facet)
        return result

    def facet_bound(self, cell) -> float:
        """Frictionless contacts each on one piece: the certified bound of the zonotope's facets
        (:func:`~closure_nlp.criterion.frictionless.facet_rows`, second order in the pieces'
        sizes), the
        weak
        dual of its LP as in :func:`dual_bound` (``>= 0``); ``inf`` otherwise."""
        if not self.frictionless or any(len(pieces) != 1 for pieces in cell):
            return np.inf
        elements = self.eligibility.model.elements
        if max(p.size / elements[p.element].size for (p,) in cell) > FACET_SIZE:
            return np.inf
        ts = self.eligibility.torque_scale
        vertex_wrenches = [
            spec.f_max * grasp_matrices(p.vertices - self.reference, p.inward_normal, ts)[:, :, 0]
            for spec, (p,) in zip(self.eligibility.all_specs, cell)
        ]
        A = facet_rows(vertex_wrenches)
        if not len(A):
            return np.inf
        owner = np.repeat(np.arange(len(cell)), [len(w) for w in vertex_wrenches])
        return max(0.0, _solve_lp(A, owner, np.zeros((len(A), 6))).value)

    @staticmethod
    def _first_rows(A: np.ndarray, owner: np.ndarray, hinted: int, rows: int) -> np.ndarray:
        """The LP's first rows: the hinted ones and the ``rows`` lowest at uniform weights
        (every row when ``rows`` is 0)."""
        if rows <= 0:
            return np.arange(len(A))
        m = int(owner.max()) + 1
        uniform = 1.0 / np.bincount(owner, minlength=m)[owner]
        lowest = np.argsort(A @ uniform)[:rows]
        return np.union1d(np.arange(hinted), lowest)

    @staticmethod
    def _solve_rows(A, owner, pool, work, lp: _GrowingLP | None = None) -> CellBound:
        """The LP on the rows ``work`` of ``A``, rows of the rest added while the LP's weights
        fall below its value on them (row generation). The dual bound of any subset of rows is
        valid; the loop only makes it as tight as the LP over all of them, within
        :data:`ROW_TOLERANCE`. ``lp`` (optional): the :class:`_GrowingLP` of earlier solves on
        a prefix of ``work``, which keeps the rows added here (its ``rows``)."""
        lp = _GrowingLP(owner) if lp is None else lp
        while True:
            result = lp.solve(A, pool, work)
            values = A @ result.lam
            below = values < result.lp_value * (1.0 - ROW_TOLERANCE)
            below[work] = False
            missing = np.flatnonzero(below)
            if not len(missing):
                return result
            missing = missing[np.argsort(values[missing])[:ADDED_ROWS]]
            work = np.concatenate([work, missing])

    @staticmethod
    def _cuts(slots: WrenchSlots, result: CellBound, owner: np.ndarray, samples: int) -> np.ndarray:
        """Directions of low ``g(u; lam*)``: a descent from the working set's lowest ones."""
        lam = result.lam
        used = lam > 1e-12
        g = WrenchSlots(
            slots.G[used][:, None].reshape(-1, 6, 4),
            np.arange(int(used.sum())),
            slots.f_max[used] * lam[used],
            slots.pieces[used],
            tuple(slots.types[i] for i in owner[used]),
            tuple(slots.n_pieces[i] for i in owner[used]),
        )
        U = result.directions
        values = g.support(U)
        lowest = U[np.argsort(values)[:CUT_LOWEST]]
        starts = np.vstack([lowest, sphere_samples(samples, seed=len(U))])
        ends, found = descend(g, starts, iterations=CUT_ITERATIONS)
        order = np.argsort(found)
        chosen: list[np.ndarray] = []
        for j in order:
            if all(np.linalg.norm(ends[j] - c) > 1e-3 for c in chosen):
                chosen.append(ends[j])
            if len(chosen) == 6:
                break
        out = np.array(chosen)
        return out / np.linalg.norm(out, axis=1, keepdims=True)


def g_values(slots: WrenchSlots, lam: np.ndarray, U: np.ndarray) -> np.ndarray:
    """``g(u; lam) = sum_r lam_r max(0, P_r(u))`` over the rows of ``slots``: (N, 6) -> (N,)."""
    return np.maximum(slots.row_values(U), 0.0) @ lam


def _solve_lp(A: np.ndarray, owner: np.ndarray, U: np.ndarray) -> CellBound:
    """``max_lam min_k (A lam)_k`` over one simplex per contact, and its certified dual bound."""
    N, R = A.shape
    m = int(owner.max()) + 1
    # solved on A over its largest entry: the solver's absolute tolerances then mean the same
    # for any wrench scale (the weights and duals do not change; the value scales back)
    unit = float(A.max(initial=0.0))
    unit = unit if unit > 0.0 else 1.0
    try:
        solvers = lp_solvers
        solve = solvers.highs_solve if solvers.Highs is not None else solvers.linprog_solve
        x, duals, value = solve(A / unit, owner, m)
        value *= unit
    except RuntimeError:
        # every solver failed on it: uniform weights and duals, still a certified bound
        x, duals, value = np.r_[np.ones(R), 0.0], -np.full(N, 1.0 / N), np.nan
    return _cell_bound(A, owner, U, x, duals, value)


def _cell_bound(A, owner, U, x, duals, value) -> CellBound:
    """The LP's weights (from its primal ``x``) and the certified bound of its duals (their
    weak dual, :func:`dual_bound`, whatever the solver's accuracy)."""
    N, R = A.shape
    m = int(owner.max()) + 1
    lam = np.maximum(x[:R], 0.0)
    totals = np.bincount(owner, lam, minlength=m)
    lam /= totals[owner]
    y = np.maximum(-duals, 0.0)
    y = y / y.sum() if y.sum() > 0 else np.full(N, 1.0 / N)
    bound = dual_bound(A, owner, y)
    return CellBound(bound, lam, y, U, value if np.isfinite(value) else bound)


class _GrowingLP:
    """The LP of :func:`_solve_lp` on rows of ``A`` that only grow (cutting planes, row
    generation): HiGHS keeps its basis between the solves, so each one after the first is a few
    dual simplex iterations from the last optimum, not a solve from scratch. The bound is the
    weak dual of its duals (:func:`_cell_bound`), as for a fresh solve; a solve that does not
    end optimal is done afresh by :func:`_solve_lp` (and its fallbacks). ``keep_basis=False``:
    every solve afresh (see :meth:`CellLP.bound`)."""

    def __init__(self, owner: np.ndarray, keep_basis: bool = True):
        self.owner, self.m, self.keep_basis = owner, int(owner.max()) + 1, keep_basis
        self.rows = np.zeros(0, dtype=int)  # rows of A of the last solve
        self._held = self.rows  # the rows the solver holds, in its order
        self.unit, self.first = 0.0, 0  # A's scale, and the rows passed with the model

    def solve(self, A: np.ndarray, pool: np.ndarray, rows: np.ndarray) -> CellBound:
        """The LP on rows ``rows`` of ``A`` (directions ``pool``), from the last basis when
        ``rows`` starts with the last call's."""
        self.rows = rows = np.asarray(rows, dtype=int)
        if lp_solvers.Highs is None or not self.keep_basis:
            return _solve_lp(A[rows], self.owner, pool[rows])
        solver = thread_solver("growing")
        old = len(self._held)
        if not np.array_equal(rows[:old], self._held):
            old = 0
        added = A[rows[old:]]
        if not old:
            unit = float(added.max(initial=0.0))  # as in _solve_lp: tolerances at unit scale
            self.unit, self.first = (unit if unit > 0.0 else 1.0), len(added)
            solver.passModel(max_min_model(added / self.unit, self.owner, self.m))
        elif len(added):
            n, width = added.shape[0], added.shape[1] + 1
            values = np.hstack([-added / self.unit, np.ones((n, 1))]).ravel()
            index = np.tile(np.arange(width, dtype=np.int32), n)
            starts = np.arange(n, dtype=np.int32) * width
            solver.addRows(n, np.full(n, -INF), np.zeros(n), n * width, starts, index, values)
        self._held = rows
        solver.run()
        if solver.getModelStatus() != OPTIMAL:
            self._held = np.zeros(0, dtype=int)  # the next solve starts afresh
            return _solve_lp(A[rows], self.owner, pool[rows])
        solution = solver.getSolution()
        first = self.first  # the simplex rows follow them, the added ones come after
        at = np.r_[np.arange(first), first + self.m + np.arange(len(rows) - first)]
        duals = np.asarray(solution.row_dual, float)[at]
        value = -solver.getInfo().objective_function_value * self.unit
        x = np.asarray(solution.col_value, float)
        return _cell_bound(A[rows], self.owner, pool[rows], x, duals, value)


def element_pieces(eligibility: Eligibility, element: int) -> list[Piece]:
    """An element as one piece (a facet as its polygon)."""
    e = eligibility.model.elements[element]
    return [Piece(element, np.array(e.vertices, float), np.array(e.inward_normal, float))]


def domain_of(eligibility: Eligibility, elements, neighbours: bool, extra=()) -> tuple:
    """Each contact's element ids: its own, its neighbours (``neighbours``) and ``extra[i]``."""
    model = eligibility.model
    out = []
    for i, e in enumerate(elements):
        ids = [e]
        if neighbours:
            ids += [n for n in model.neighbours(e) if n not in ids]
        if i < len(extra) and extra[i] not in ids:
            ids.append(extra[i])
        out.append(tuple(ids))
    return tuple(out)


class _Cell:
    __slots__ = ("pieces", "bound", "depth")

    def __init__(self, pieces, bound: CellBound, depth: int):
        self.pieces, self.bound, self.depth = pieces, bound, depth

    def __lt__(self, other: _Cell) -> bool:  # a max-heap on the bound
        return self.bound.value > other.bound.value


def capacity_bound(
    placer,
    elements,
    incumbent=None,
    options: BoundOptions = BoundOptions(),
    domain=None,
    progress=None,
) -> CapacityBound:
    """Certified ceiling on ``-rho`` of every placement on ``elements`` (one per contact).

    Parameters
    ----------
    placer : closure_nlp.placement.placer.Placer
        Its eligibility gives the model, specs and torque scale; its exchange method polishes the
        LP's placements into incumbents.
    elements : sequence of int
        The chosen elements, one per contact.
    incumbent : PlacementResult, optional
        A placement already found (certified): the search starts from its value.
    options : BoundOptions
    domain : sequence of sequence of int, optional
        Each contact's element ids (default: its element, plus its neighbours when the placer
        moves contacts to neighbours, plus the incumbent's element).
    progress : callable, optional
        Called as ``progress("capacity bound", nodes, ceiling)``.

    Returns
    -------
    CapacityBound
    """

    if not isinstance(options, BoundOptions):
        raise TypeError(f"options: expected BoundOptions, got {type(options).__name__}")
    t0 = time.perf_counter()
    eligibility = placer.eligibility
    model = eligibility.model
    elements = eligibility.check_elements(elements)
    if domain is None:
        extra = incumbent.elements if incumbent is not None else ()
        domain = domain_of(eligibility, elements, placer.options.neighbour_moves > 0, extra)
    domain = tuple(
        tuple(model.check_id(e, f"domain[{i}]") for e in ids) for i, ids in enumerate(domain)
    )
    if len(domain) != eligibility.m or not all(domain):
        raise ValueError(f"domain: expected {eligibility.m} non-empty lists of element ids")
    lp = CellLP(eligibility)
    # A ceiling this close to zero (the certificate's relative accuracy) shows that no
    # placement in the domain is force closure beyond numerical accuracy.
    zero = eligibility.minimizer.tolerances.certify * tolerance_unit(eligibility.slots(elements))
    if incumbent is not None and getattr(incumbent, "direction", None) is not None:
        lp.directions = np.vstack([lp.directions, incumbent.direction[None]])

    best = incumbent
    best_value = _capacity(incumbent)
    # the fixed contacts first, each one point (never split), as in a placement's contact set
    fixed = eligibility.fixed
    k0 = len(fixed)
    root_cell = tuple(
        [Piece(e, c.position[None], c.inward_normal)] for c, e in zip(fixed.contacts, fixed.on)
    )
    root_cell += tuple(sum((element_pieces(eligibility, e) for e in ids), []) for ids in domain)
    spacing = placer.options.min_spacing
    if spacing and not _room(root_cell, spacing, k0):
        raise SpacingError(f"min_spacing: no placement on these elements keeps {spacing:g}")
    deadline = t0 + options.time_budget
    root = lp.bound(root_cell, options.root_cuts, options.cut_tolerance, deadline)
    heap = [_Cell(root_cell, root, 0)]
    closed = -np.inf  # the largest bound of a closed cell
    nodes, polishes, history = 1, 0, [(0.0, root.value, best_value, 1)]
    probes, splits = 0, 0
    pending = (-np.inf, None, None, None)  # the best probed placement not yet certified
    polish_seconds, polished_at, cell_polishes = 0.0, -np.inf, 0
    polisher = ExchangePlacer(
        eligibility,
        PlacementOptions(
            starts=1,
            extra_starts=0,
            neighbour_moves=0,
            max_rounds=placer.options.max_rounds,
            bound=False,
            min_spacing=spacing,
        ),
        placer._caches,
    )

    frictionless = _frictionless(eligibility)
    light = eligibility.minimizer.with_search(SCREEN_SEARCH)

    def ceiling() -> float:
        top = heap[0].bound.value if heap else -np.inf
        return max(top, closed, 0.0)

    def done() -> bool:
        gap = relative_gap(ceiling(), best_value)
        return ceiling() <= zero or (gap is not None and gap <= options.gap)

    def movable(ids, positions):  # the placement's contacts but the fixed ones, as weights
        ids = ids[k0:]
        vertices = [model.elements[e].vertices for e in ids]
        return ids, [nearest_weights(v, x) for v, x in zip(vertices, positions[k0:])]

    def polish(ids, positions):
        nonlocal best, best_value, polishes
        ids, weights = movable(ids, positions)
        polishes += 1
        try:
            found = polisher(list(ids), weights)
        except SpacingError:  # no placement found there that keeps the spacing
            return
        if _capacity(found) > best_value:
            best, best_value = found, _capacity(found)

    def probe(cell: _Cell):
        nonlocal probes, pending
        probes += 1
        ids, weights = movable(*_lp_placement(lp, cell))
        warm = cell.bound.directions[np.argmax(cell.bound.y)] if len(cell.bound.y) else None
        contacts = polisher.contact_set(ids, weights)
        found = search_rho(contacts, minimizer=light, warm_start=warm)
        add_cut(found.direction)
        # -found.rho bounds its capacity from above: certified only when it may beat the best,
        # at once when by more than PROBE_STEP of it, else the best such one at the end
        if not options.probe_incumbents or not -found.rho > max(best_value, pending[0]):
            return
        # the light search often misses the weakest direction: the full one judges it first
        found = search_rho(contacts, minimizer=eligibility.minimizer, warm_start=found.direction)
        add_cut(found.direction)
        value = -found.rho
        if not value > max(best_value, pending[0]):
            return
        pending = (value, ids, weights, found.direction)
        if not np.isfinite(best_value) or value > best_value + PROBE_STEP * abs(best_value):
            certify_pending()

    def add_cut(u):  # any unit direction is a valid cut
        if u is not None and np.all(np.isfinite(u)) and np.linalg.norm(u) > 0.0:
            u = np.asarray(u, float) / np.linalg.norm(u)
            lp.directions = np.vstack([lp.directions, u[None]])[-MAX_DIRECTIONS:]

    def certify_pending():
        nonlocal best, best_value, pending
        value, ids, weights, direction = pending
        pending = (-np.inf, None, None, None)
        if not value > best_value:
            return
        placed = polisher.certified_at(ids, weights, direction)
        if placed is not None and _capacity(placed) > best_value:
            best, best_value = placed, _capacity(placed)

    def polishing() -> bool:  # exchange runs from cells still to come
        runs = options.polish_runs
        return bool(options.polish_every) and (runs is None or cell_polishes < runs)

    def try_placement(cell: _Cell):
        nonlocal polish_seconds, polished_at, cell_polishes
        started, polished_at = time.perf_counter(), nodes
        cell_polishes += 1
        starts = []
        if frictionless:  # the climb's best from the LP's placement and random ones
            starts = _climbed(lp, cell, CLIMB_CELL, seed=nodes)[:1]
        if not starts:  # (none of them force closure: the LP's placement, as for other types)
            starts = [_lp_placement(lp, cell)]
        for ids, positions in starts:
            polish(ids, positions)
        polish_seconds += time.perf_counter() - started

    if frictionless:  # the root's climb: placements far from the exchange method's
        started = time.perf_counter()
        for ids, positions in _climbed(lp, heap[0], CLIMB_ROOT, seed=0)[:CLIMB_POLISHES]:
            polish(ids, positions)
        polish_seconds += time.perf_counter() - started

    while heap and not done():
        if time.perf_counter() - t0 > options.time_budget or nodes >= options.max_nodes:
            break
        # an exchange run takes seconds: none started in the last quarter of the budget
        late = time.perf_counter() - t0 > 0.75 * options.time_budget
        late |= nodes > 0.75 * options.max_nodes
        # an exchange run every polish_every cells; under a time budget only while they take
        # at most polish_share of the time (one costs seconds, as much as hundreds of cells).
        # A budget of cells alone keeps its answer independent of the machine's speed.
        due = polishing() and nodes - polished_at >= options.polish_every
        if np.isfinite(options.time_budget):
            due = due and polish_seconds <= options.polish_share * (time.perf_counter() - t0)
        if due and not late:
            try_placement(heap[0])
            if done():
                break
        cell = heapq.heappop(heap)
        if cell.bound.value <= best_value:
            closed = max(closed, cell.bound.value)
            continue
        split = _split(lp, cell)
        if split is None:  # every contact on one point: the bound is its placement's own
            closed = max(closed, cell.bound.value)
            continue
        splits += 1
        if options.probe_every and splits % options.probe_every == 0:
            probe(cell)
        hint = cell.bound.directions[cell.bound.y > 0.0]
        for pieces in split:
            if spacing and not _room(pieces, spacing, k0):
                continue  # two contacts wholly closer than the spacing: no placement here
            bound = lp.bound(
                pieces,
                options.cell_cuts,
                options.cut_tolerance,
                deadline,
                hint,
                options.lp_rows,
                options.cut_samples,
                best_value,
                # warm unless a climb may start from the cell's LP weights
                None if polishing() else True,
            )
            if bound.value > cell.bound.value:  # the parent's bound holds for its parts too
                bound = replace(bound, value=cell.bound.value)
            nodes += 1
            child = _Cell(pieces, bound, cell.depth + 1)
            if bound.value <= best_value:
                closed = max(closed, bound.value)
            else:
                heapq.heappush(heap, child)
        history.append((time.perf_counter() - t0, ceiling(), best_value, nodes))
        if progress:
            progress("capacity bound", nodes, ceiling())
    certify_pending()
    value = ceiling()
    gap = relative_gap(value, best_value)
    reached = value <= zero or (gap is not None and gap <= options.gap)
    improved = best if best is not incumbent else None
    return CapacityBound(
        value,
        best_value,
        gap,
        improved,
        nodes,
        len(heap),
        reached,
        domain,
        time.perf_counter() - t0,
        root.value,
        lp.cuts,
        polishes,
        tuple(history),
    )


def bounded(placer, elements, result, t0: float, progress=None):
    """``result`` (the exchange method's placement on ``elements``, started at ``t0``) with the
    certified ceiling of :func:`capacity_bound` under the placer's options, and replaced by a
    better placement the bound's search found (certified, and by the capacity left within the
    tolerance when there is one; never a worse one). The ceiling covers the elements the
    contacts sit on, or with ``bound_neighbours`` ``elements``, their neighbours (when the
    placer moves contacts to neighbours) and the contacts' elements."""
    options = placer.options
    budget = np.inf if options.time_budget is None else float(options.time_budget)
    domain = None
    if not options.bound_neighbours:  # the elements the contacts sit on
        elements = result.elements
        domain = tuple((e,) for e in elements)
    # A budget of cells alone: two exchange runs (at the first cell and the 21st), each costing
    # as much as hundreds of cells; the probes' placements are the other incumbents.
    bound = BoundOptions(
        gap=options.target_gap,
        time_budget=budget,
        max_nodes=options.bound_cells,
        polish_runs=None if np.isfinite(budget) else CELL_BUDGET_POLISHES,
    )
    found = capacity_bound(placer, elements, result, bound, domain, progress)
    chosen = result
    if found.placement is not None and _kept_by(found.placement) > _kept_by(result):
        better = found.placement
        chosen = replace(
            better,
            start_rho=result.start_rho,
            rounds=result.rounds + better.rounds,
            moves=(),
        )
    root_gap, _, per_cell = found.trend()
    return replace(
        chosen,
        capacity_bound=found.value,
        gap=found.gap,
        gap_reached=found.reached,
        root_gap=root_gap,
        gap_per_cell=per_cell,
        bound_elements=found.domain,
        bound_nodes=found.nodes,
        bound_seconds=found.seconds,
        exchange_rho=result.rho,
        seconds=time.perf_counter() - t0,
    )


def part_ceiling(placer, incumbent=None, options: BoundOptions = BoundOptions()) -> CapacityBound:
    """Certified ceiling on ``-rho`` of every placement of the placer's contacts anywhere on the
    part: each contact's domain is every usable element, so the bound covers every element set
    (a set's placements are a part of that domain; several contacts may share an element).
    ``incumbent`` (a placement, e.g. a plan's) closes the cells it beats and gives the gap;
    no exchange runs (``polish_every`` 0): the ceiling alone."""
    eligibility = placer.eligibility
    usable = tuple(int(e) for e in np.flatnonzero(eligibility.model.usable))
    if not usable:
        raise ValueError("model: no usable element to place contacts on")
    m = eligibility.m
    elements = incumbent.elements if incumbent is not None else usable[:m]
    elements = tuple(elements) + tuple(usable[i % len(usable)] for i in range(len(elements), m))
    options = replace(options, polish_every=0, probe_incumbents=False)
    return capacity_bound(placer, elements, incumbent, options, (usable,) * m)


def part_text(found: CapacityBound, m: int) -> str:
    """The part's ceiling in words: what it proves and where the plan stands."""
    cells = f"{found.nodes} cell" + ("s" if found.nodes != 1 else "")
    text = (
        f"certified: no placement of {m} contacts anywhere on the part holds more than "
        f"{_digits(found.value)} ({cells})"
    )
    if found.gap is None:
        return text
    return f"{text}; this plan holds {_digits(found.capacity)}, within {_percent(found.gap)}"


def gap_text(result) -> str:
    """The ceiling in words: what it proves and where the placement stands, e.g. ``certified:
    no placement on these elements holds more than 0.7928; this one holds 0.5160, within 2.1%``;
    when a budget ended first, how fast the gap was still falling (what more time would buy)."""
    if result.capacity_bound is None:
        return ""
    where = "these elements"
    if any(len(ids) > 1 for ids in result.bound_elements):
        where += " and their neighbours"
    nodes = result.bound_nodes
    cells = f"{nodes} cell" + ("s" if nodes != 1 else "")
    ceiling = _digits(result.capacity_bound)
    if result.gap is None:
        if result.gap_reached:
            return f"certified: no placement on {where} is force closure ({cells})"
        return (
            f"certified: no placement on {where} holds more than {ceiling}; "
            f"this one is not force closure ({cells})"
        )
    held = _digits(_capacity(result))
    text = (
        f"certified: no placement on {where} holds more than {ceiling}; "
        f"this one holds {held}, within {_percent(result.gap)}"
    )
    if result.gap_reached:
        return f"{text} ({cells})"
    rate = getattr(result, "gap_per_cell", None)
    if nodes <= 1 or rate is None:
        return f"{text} (the root cell; more cells narrow it: --bound-cells, --time-budget)"
    root = getattr(result, "root_gap", None)
    since = f" from {_percent(root)}" if root is not None else ""
    seconds = getattr(result, "bound_seconds", 0.0)
    pace = f"{100 * rate:.2g} points a cell lately" if rate > 0 else "flat lately"
    return f"{text} (narrowed{since} over {cells} in {seconds:.3g} s; {pace})"


def _digits(value: float) -> str:
    """Four significant digits, trailing zeros kept (0.5160)."""
    text = f"{value:#.4g}"
    return text[:-1] if text.endswith(".") else text


def _percent(gap: float) -> str:
    return f"{100 * gap:.3g}%"


def _capacity(result) -> float:
    """Certified capacity of a placement result: ``-hi`` of its bracket (-inf for None)."""
    if result is None:
        return -np.inf
    if result.bounds is not None:
        return -float(result.bounds[1])
    return -float(result.rho)


def _kept_by(result) -> float:
    """What decides between two placements: the certified capacity left within the tolerance
    (``-robust_rho``), which placement steers by; ``-hi`` without a tolerance."""
    robust = result.robust_rho
    return _capacity(result) if robust is None else -float(robust)


def _heaviest(cell: _Cell) -> tuple[list[Piece], list[np.ndarray]]:
    """Each contact's piece of largest LP weight and the weights' barycentric point there."""
    chosen, points = [], []
    lam, at = cell.bound.lam, 0
    for pieces in cell.pieces:
        weights = []
        for p in pieces:
            weights.append(lam[at : at + len(p.vertices)])
            at += len(p.vertices)
        j = int(np.argmax([w.sum() for w in weights]))
        k = len(pieces[j].vertices)
        total = weights[j].sum()
        chosen.append(pieces[j])
        points.append(weights[j] / total if total > 0 else np.full(k, 1.0 / k))
    return chosen, points


def _lp_placement(lp: CellLP, cell: _Cell):
    """The placement the cell's LP weights describe: each contact on its heaviest piece at the
    weights' point there; (element ids, positions (m, 3))."""
    pieces, points = _heaviest(cell)
    return [p.element for p in pieces], np.array([w @ p.vertices for w, p in zip(points, pieces)])


def _frictionless(eligibility: Eligibility) -> bool:
    """Every contact frictionless, and few enough for
    :func:`~closure_nlp.criterion.frictionless.climb`."""
    specs = eligibility.all_specs
    frictionless = all(is_frictionless(s.type, s.mu, s.mu_s) for s in specs)
    return frictionless and 7 <= len(specs) <= MAX_CONTACTS


def _climbed(lp: CellLP, cell: _Cell, size: tuple[int, int], seed: int) -> list:
    """Placements in ``cell`` (each contact on its heaviest piece) from a climb of
    :func:`~closure_nlp.criterion.frictionless.climb` with ``size = (members, iterations)``: the
    LP's
    placement
    and random ones (Dirichlet(1/2) weights) start it. Distinct placements, best first, as
    (element ids, positions (m, 3)); not certified (the exchange method certifies them)."""
    pieces, points = _heaviest(cell)
    members, iterations = size
    rng = np.random.default_rng(seed)
    ts, ref = lp.eligibility.torque_scale, lp.reference
    rows, starts = [], []
    for spec, piece, point in zip(lp.eligibility.all_specs, pieces, points):
        G = grasp_matrices(piece.vertices - ref, piece.inward_normal, ts)
        rows.append(spec.f_max * G[:, :, 0])
        k = len(piece.vertices)
        starts.append(np.vstack([point, rng.dirichlet(np.full(k, 0.5), members - 1)]))
    found, values = climb([p.vertices for p in pieces], rows, starts, iterations, seed=seed)
    sizes = np.array([max(p.size, np.finfo(float).tiny) for p in pieces])
    out, kept = [], []
    for b in np.argsort(-values):
        if not values[b] > 0.0:
            break
        positions = np.array([x[b] for x in found])
        # distinct: some contact more than 1e-3 of its piece's size from the kept ones'
        if any(np.all(np.linalg.norm(positions - k, axis=1) <= 1e-3 * sizes) for k in kept):
            continue
        kept.append(positions)
        out.append(([p.element for p in pieces], positions))
        if len(out) == CLIMB_POLISHES:
            break
    return out


def _room(cell, spacing: float, fixed: int) -> bool:
    """Whether every pair of contacts of ``cell`` (pieces per contact, the first ``fixed``
    ones fixed) can lie ``spacing`` apart: some of their pieces' vertices are that far apart
    (the farthest points of two convex sets are vertices)."""
    points = [np.vstack([p.vertices for p in pieces]) for pieces in cell]
    for j in range(fixed, len(points)):
        for i in range(j):
            a, b = points[i], points[j]
            if np.max(np.linalg.norm(a[:, None] - b[None], axis=2)) < spacing:
                return False
    return True


def _split(lp: CellLP, cell: _Cell):
    """Two cells covering ``cell``: a contact on pieces of several elements has its heaviest
    piece (by the LP's weights) split from the rest; otherwise the contact whose piece has the
    largest moment (size times f_max) is halved. None when every contact is on a point."""
    sizes = []
    for spec, pieces in zip(lp.eligibility.all_specs, cell.pieces):
        if len(pieces) > 1:
            sizes.append(np.inf)  # pieces of several elements: separate them first
        elif len(pieces[0].vertices) == 1:
            sizes.append(-1.0)  # a point: nothing to split
        else:  # the moment its force can make across the piece, what (2) mixes
            sizes.append(pieces[0].size * spec.f_max)
    i = int(np.argmax(sizes))
    if sizes[i] < 0.0:
        return None
    pieces = cell.pieces[i]
    if len(pieces) > 1:
        counts = [sum(len(p.vertices) for p in ps) for ps in cell.pieces]
        at, mass = sum(counts[:i]), []
        for p in pieces:
            mass.append(cell.bound.lam[at : at + len(p.vertices)].sum())
            at += len(p.vertices)
        j = int(np.argmax(mass))
        parts = ([pieces[j]], [p for k, p in enumerate(pieces) if k != j])
    else:
        parts = tuple([half] for half in pieces[0].halves())
    return tuple(cell.pieces[:i] + (part,) + cell.pieces[i + 1 :] for part in parts)


__all__ = [
    "BoundOptions",
    "CapacityBound",
    "CellLP",
    "Piece",
    "bounded",
    "capacity_bound",
    "domain_of",
    "dual_bound",
    "gap_text",
    "part_ceiling",
    "part_text",
    "relative_gap",
]
