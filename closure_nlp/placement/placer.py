"""Contact placement: barycentric weights on the chosen elements for the best rho (paper sec. 5).

``max_c -rho(0, W_c^M) = max_c min_{|u|=1} p(u; c)`` is a max-min problem. We solve it by an
exchange method with a trust region: a restricted problem maximises ``r`` subject to
``p(u_k; c) >= r`` over a working set of directions ``u_k`` and weights within a radius of the
best ones; the rho solver then computes the true rho of the new contacts (accepted only if
better) and its worst direction joins the working set. It stops when the restricted problem
shows no gain. The method is local, so it runs from several starts (centroids first).

The restricted problem is a CasADi NLP solved by IPOPT, in which ``p(u_k; c)`` is replaced by a
smooth lower bound (one subset, one friction piece per contact, see :class:`ExchangeProblem`),
so whatever it achieves the true one achieves; a linear programme when every contact is
frictionless (:class:`ExchangeLP`). By default the runs that only explore (further starts,
neighbour-move trials) solve the same problem by sequential linear programming
(:class:`~closure_nlp.placement.sequential_lp.ModelSLP`, ``exchange_solver="mixed"``).
Each ``p(u_k; .)`` is convex in the weights, so its linearisation is a global under-estimator:
``exchange_solver="slp"`` solves the restricted problem by sequential linear programming on the
true support function instead (:class:`~closure_nlp.placement.sequential_lp.ExchangeSLP`),
``"slp-ipopt"`` by it until a round of it does not pay off and by IPOPT from there on.

Afterwards a contact whose optimum sits on its element's boundary may move into a neighbouring
element sharing that boundary, if that raises the optimum ("occupied and adjacent areas").
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from closure_nlp.base.interrupts import interruptible
from closure_nlp.base.progress import Progress
from closure_nlp.base.solver_cache import NLPSOL_OPTIONS, PerThread, cached
from closure_nlp.base.ties import lowest_first
from closure_nlp.base.validation import as_flag, is_whole
from closure_nlp.contact.contact_set import ContactSet, friction_pieces, is_frictionless
from closure_nlp.contact.count import require_closure_count
from closure_nlp.contact.wrenches import WrenchSlots, pad_rows, pushing_subsets
from closure_nlp.model.elements import nearest_weights, simplex_weights
from closure_nlp.placement.analytic_centre import analytic_centre
from closure_nlp.placement.max_min_lp import max_min_lp
from closure_nlp.placement.sequential_lp import ExchangeSLP, ModelSLP, restricted_model
from closure_nlp.rho.rho_hat import Eligibility
from closure_nlp.rho.sphere_search import sphere_samples
from closure_nlp.rho.support_minimum import SearchOptions, certificate_keys, rho, search_rho
from closure_nlp.selection.algorithms import SCREEN_SEARCH

# Working-set sizes the exchange NLP is built for (unused directions masked out). An IPOPT
# iteration costs about in proportion to the size (on the lamp's rounds, 40 directions 0.96 ms
# against 64's 1.62 ms, the same optimum within 2e-12), so the sizes are close together; a run
# grows its set by one direction a round, and one plan on the lamp builds 5 of them.
DIRECTION_BUCKETS = (16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256)
# Exchange NLPs kept per cache: 8-30 MB each (40-128 directions, 4-7 contacts). Unbounded, the
# fixture study's pistol 7-PCwF tasks run serially left 11 after the 7th, 275 MB of 440 MiB.
MAX_EXCHANGE_PROBLEMS = 6
# Weak directions of earlier exchange runs on the same elements that start a later run's working
# set: with the random ones and one run's rounds (max_rounds 40) it stays within 128.
SHARED_DIRECTIONS = 64
# Vertex rows above which a contact's position enters the exchange NLP through three variables
# (:class:`ExchangeProblem`): 7 PCwF on the pistol, 24- and 18-vertex facets, 9.5x per solve.
AFFINE_ROWS = 4
# The trust region's smallest radius (barycentric weights): below it the weights cannot move.
MIN_RADIUS = 1e-9
# The search that judges each exchange round's weights: they lie within the trust region of the
# best ones, whose weak directions the working set holds, so the WARM_DIRECTIONS of them weakest at
# the new weights start it, besides a quarter of the default's samples. Against the default
# search from the best direction alone, on 658 rounds of 12 placements (lamp, cup, pistol), each
# also judged by the other search: it found the weaker direction on 102 rounds, the default on 48.
# One smoothed descent: without it the exchange followed weaker directions less often and ended
# worse on 28 of 147 PCwF fixture-study tasks with unchanged elements (better on 9; mean 1.3%,
# up to 22%) for 1.2x less placement time.
ROUND_SEARCH = SearchOptions(samples=32, smoothing=(0.03,), ipopt_starts=2, ipopt_polish=False)
WARM_DIRECTIONS = 4
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
        certified (:func:`closure_nlp.rho.support_minimum.rho`); the exchange rounds compare the
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
        reported at the end is certified (:func:`closure_nlp.rho.support_minimum.rho`).
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
        answer on any machine. The default, 1, is the root cell alone: the ceiling over every
        placement with its cutting planes, a fraction of the exchange method's time. More cells
        tighten it by a few points and may find a better placement, at several times the
        exchange method's time for 40 cells (docs/placement.md).
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
    bound_cells: int = 1
    time_budget: float | None = None
    exchange_solver: str = "auto"
    lp_centre: bool = False

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
        flags = ("certify", "screen", "share_directions", "round_search", "validate", "bound")
        for name in (*flags, "lp_centre"):
            object.__setattr__(self, name, as_flag(getattr(self, name), name))


@dataclass(frozen=True)
class PlacedContact:
    """A contact on an element: barycentric ``weights`` (k,), its ``position`` and normal."""

    element: int
    weights: np.ndarray
    position: np.ndarray
    inward_normal: np.ndarray

    def to_dict(self) -> dict:
        return {
            "element": self.element,
            "weights": self.weights.tolist(),
            "position": self.position.tolist(),
            "inward_normal": self.inward_normal.tolist(),
        }


@dataclass(frozen=True)
class Move:
    """Contact ``contact`` moved from element ``source`` to its neighbour ``target``."""

    contact: int
    source: int
    target: int
    rho_before: float
    rho_after: float


@dataclass(frozen=True)
class PlacementResult:
    """Outcome of :func:`place`.

    Attributes
    ----------
    contacts : tuple of PlacedContact
    contact_set : ContactSet
        The placed contacts with their specs, ready for :func:`closure_nlp.rho.support_minimum.rho`.
    rho : float
        rho(0, W_c^M) of the placed contacts, recomputed by the rho solver from the final
        positions, and certified.
    force_closure : bool
    direction : (6,) float
        Their weakest direction ``u*``.
    start_rho : float
        rho of the start (centroids, or the given weights): the search's value, which is never
        above the certified one, unless the certified final rho was above it; then the start's
        certified rho (and the start is kept if it is better).
    model_value : float
        The trust-region model's last prediction of ``-rho`` (close to it when converged; the
        method is local, so this is not a bound on other placements).
    rounds : int
        Exchange rounds over all element sets tried.
    moves : tuple of Move
    seconds : float
    bounds : (float, float) or None
        Certified ``lo <= rho <= hi`` of the placed contacts.
    marginal, converged : bool
        As in :class:`~closure_nlp.rho.support_minimum.RhoResult`.
    capacity_bound : float or None
        Certified ceiling: no placement on the elements searched (``bound_elements``) has
        ``-rho`` above it (None without the bound).
    gap : float or None
        ``(capacity_bound - capacity) / capacity_bound`` with ``capacity = -hi`` (the certified
        capacity of these contacts), when they are force closure; None otherwise.
    gap_reached : bool or None
        The gap target was met (False: the time budget ended first).
    bound_elements : tuple of tuple of int
        The element ids each contact could sit on in the bound.
    bound_nodes : int
        Cells of the branch and bound.
    bound_seconds : float
        The bound's part of ``seconds``.
    exchange_rho : float or None
        The exchange method's own certified rho, before the bound's search (equal to ``rho``
        unless that search found better contacts).
    robust : bool or None
        Force closure for every contact set within the model's tolerance (None: no tolerance).
    shift : float
        How far the support function can move within that tolerance.
    exchange_solver : str
        The solver of the exchange method's restricted problems: ``"highs"`` (a linear
        programme: every contact frictionless), ``"mixed"`` (IPOPT, and IPOPT's problem by
        sequential linear programming on the exploring runs), ``"slp"`` (sequential linear
        programming), ``"slp-ipopt"`` (that, then IPOPT), ``"slp-model"`` or ``"ipopt"``.
    """

    contacts: tuple[PlacedContact, ...]
    contact_set: ContactSet
    rho: float
    force_closure: bool
    direction: np.ndarray
    start_rho: float
    model_value: float
    rounds: int
    moves: tuple[Move, ...]
    seconds: float
    bounds: tuple[float, float] | None = None
    marginal: bool = False
    converged: bool = True
    capacity_bound: float | None = None
    gap: float | None = None
    gap_reached: bool | None = None
    bound_elements: tuple[tuple[int, ...], ...] = ()
    bound_nodes: int = 0
    bound_seconds: float = 0.0
    exchange_rho: float | None = None
    robust: bool | None = None
    shift: float = 0.0
    exchange_solver: str = "ipopt"

    @property
    def elements(self) -> tuple[int, ...]:
        return tuple(c.element for c in self.contacts)

    def to_dict(self) -> dict:
        return {
            "contacts": [c.to_dict() for c in self.contacts],
            "rho": self.rho,
            "force_closure": self.force_closure,
            "direction": self.direction.tolist(),
            "start_rho": self.start_rho,
            "model_value": self.model_value,
            "rounds": self.rounds,
            "moves": [vars(m) for m in self.moves],
            "seconds": self.seconds,
            "exchange_solver": self.exchange_solver,
            **certificate_keys(self),
            **self.bound_keys(),
        }

    def bound_keys(self) -> dict:
        """The JSON keys of the certified ceiling (none when it was not computed)."""
        if self.capacity_bound is None:
            return {}
        return {
            "capacity_bound": self.capacity_bound,
            "gap": self.gap,
            "gap_reached": self.gap_reached,
            "bound_elements": [list(ids) for ids in self.bound_elements],
            "bound_nodes": self.bound_nodes,
            "exchange_rho": self.exchange_rho,
            "timing": {
                "exchange": self.seconds - self.bound_seconds,
                "bound": self.bound_seconds,
            },
        }

    def contact_file(self, name: str = "", units: str = "") -> dict:
        """The placed contacts as a contact-set file (docs/formats.md), each with its ``element``
        and ``weights``; :func:`closure_nlp.load_contact_set` reads it back to the same set."""
        data = {"torque_scale": self.contact_set.torque_scale}
        reference = getattr(self.contact_set, "reference_point", None)
        if reference is not None:  # models with a reference point
            data["reference_point"] = np.asarray(reference, float).tolist()
        if name:
            data["name"] = name
        if units:
            data["units"] = units
        verdict = "force closure" if self.force_closure else "not force closure"
        data["description"] = f"placed contacts: rho = {self.rho:.9g} ({verdict})"
        data["contacts"] = [
            {**c.to_dict(), "element": p.element, "weights": p.weights.tolist()}
            for c, p in zip(self.contact_set.contacts, self.contacts)
        ]
        return data


class ExchangeProblem:
    """``max r`` over weights ``c`` s.t. a smooth lower bound of ``p(u_k; c)`` is ``>= r``.

    For direction ``k`` the bound is ``sum_{i in S_k} f_i (d_n + sqrt(q_ik + eps^2) - eps)`` with
    ``d = G_i(x_i)^T u_k`` at the contact's position ``x_i``, ``S_k`` the contacts with
    ``P_ik > -margin * f_i`` at the current weights (the largest alone if none; a contact about
    to help must be seen) and ``q_ik`` the friction piece that is largest there. Every term is
    at most the true one (a sum over one subset, one piece, ``sqrt(q + eps^2) - eps <=
    sqrt(q)``), so a solution's ``r`` is met by the true support function: each solve is a
    restriction, and re-choosing ``S_k`` and the pieces at the new weights tightens it again.

    ``d`` is linear in the weights (``sum_j c_ij G_ij^T u_k``), and affine in the position. On an
    element with more than :data:`AFFINE_ROWS` vertex rows the position enters through three
    variables ``xi_i`` (offset from the centroid over the size, :class:`ElementFrame`) tied to
    the weights by the linear constraint ``xi_i = Xi_i^T c_i``: the curvature, most of a solve's
    time, then sits in a 3 x 3 block instead of a dense block over all the rows (a pistol set
    with 24- and 18-vertex facets, 7 PCwF: 482 -> 51 ms per solve). On smaller elements the
    extra variables cost more than they save (segments and triangles: 10-35% slower).

    Built once per shape; ``capacity`` directions, unused ones masked out by parameters and
    their rows left free.
    ``components`` (per contact; default all four) are the components of ``d`` its friction
    pieces weigh (PCwF: the two tangential ones). A contact with none (no friction piece: FPC,
    or mu = mu_s = 0) has the linear term ``f_i d_n`` alone: the same value, and no curvature
    at all. The other components are left out of ``q``, the same
    values to the bit with a smaller graph (its Hessian is most of a solve's time: on a pistol
    7-PCwF placement's 30 restricted problems, the same weights to the bit in 1.5x less time).
    """

    EPS = 1e-9
    solver = "ipopt"

    def __init__(
        self,
        rows,
        capacity: int,
        tol: float = 1e-10,
        margin: float = 0.0,
        components=(),
    ):
        self.margin = margin
        self.rows, self.capacity = tuple(rows), capacity
        self.affine = tuple(k > AFFINE_ROWS for k in self.rows)
        components = tuple(components) or ((0, 1, 2, 3),) * len(self.rows)
        import casadi as ca  # here: only a placement builds this NLP (casadi costs every start)

        m, K = len(self.rows), capacity
        c = [ca.SX.sym(f"c{i}", k) for i, k in enumerate(self.rows)]
        r = ca.SX.sym("r")
        W = [ca.SX.sym(f"W{i}", 4, K) for i in range(m)]  # chosen friction piece per direction
        mask = ca.SX.sym("mask", m, K)  # S_k
        f_max = ca.SX.sym("f_max", m)
        active = ca.SX.sym("active", K)
        total, xis, ties, data = 0, [], [], []
        for i, k in enumerate(self.rows):
            if self.affine[i]:
                xi = ca.SX.sym(f"xi{i}", 3)
                Xi = ca.SX.sym(f"Xi{i}", k, 3)  # the vertices' xi
                A, B = ca.SX.sym(f"A{i}", 4, K), ca.SX.sym(f"B{i}", 12, K)
                d = A + sum(xi[j] * B[4 * j : 4 * j + 4, :] for j in range(3))
                xis.append(xi)
                ties.append(xi - ca.mtimes(Xi.T, c[i]))
                data += [Xi, A, B]
            else:
                D = ca.SX.sym(f"D{i}", 4 * k, K)  # G_ij^T u_k
                d = sum(c[i][j] * D[4 * j : 4 * j + 4, :] for j in range(k))
                data.append(D)
            if not components[i]:  # its pieces are zero: sqrt(0 + eps^2) - eps = 0
                P = f_max[i] * d[0, :]
            else:  # the components its pieces weigh: fewer terms to differentiate
                q = sum(W[i][j, :] * d[j, :] ** 2 for j in components[i])
                P = f_max[i] * (d[0, :] + ca.sqrt(q + self.EPS**2) - self.EPS)
            total = total + mask[i, :] * P
        g = ca.vertcat(*[ca.sum1(ci) for ci in c], *ties, (total - active.T * r).T)
        n_tie = 3 * len(xis)
        self._lbg = np.concatenate([np.ones(m), np.zeros(n_tie), np.zeros(K)])
        self._ubg = np.concatenate([np.ones(m), np.zeros(n_tie), np.full(K, np.inf)])
        x = ca.vertcat(*c, *xis, r)
        p = ca.vertcat(*[ca.vec(a) for a in (*data, *W)], ca.vec(mask), f_max, active)
        self._solver = ca.nlpsol(
            "exchange",
            "ipopt",
            {"x": x, "p": p, "f": -r, "g": g},
            {
                **NLPSOL_OPTIONS,
                "ipopt": {
                    "print_level": 0,
                    "sb": "yes",
                    "tol": tol,
                    "constr_viol_tol": tol,
                    "max_iter": 500,
                },
            },
        )

    def solve(self, frames, slots_at_c, f_max, U, c0, radius):
        """One solve from weights ``c0`` (padded), each weight within ``radius`` of its start;
        ``frames`` holds each contact's :class:`ElementFrame`, ``slots_at_c`` the contacts at
        ``c0``.

        Returns the new padded weights (list) and ``r``.
        """
        m, K = len(self.rows), self.capacity
        n = len(U)
        P, subsets, chosen = restricted_model(slots_at_c, f_max, U, self.margin)
        mask = np.zeros((m, K))
        mask[:, :n] = subsets

        def padded(a):  # (rows, n) -> (rows, K), flattened column-major as CasADi reads it
            out = np.zeros((len(a), K))
            out[:, :n] = a
            return out.ravel(order="F")

        data, W_parts, xi0 = [], [], []
        for i, frame in enumerate(frames):
            if self.affine[i]:
                A, B = frame.affine(U)
                data += [frame.offsets.ravel(order="F"), padded(A), padded(B)]
                xi0.append(frame.offsets.T @ c0[i])
            else:
                data.append(padded(frame.local(U).reshape(-1, n)))
            W_parts.append(padded(chosen[:, i, :].T))
        active = np.zeros(K)
        active[:n] = 1.0
        params = np.concatenate([*data, *W_parts, mask.ravel(order="F"), f_max, active])
        r0 = float(np.min(np.where(mask[:, :n] > 0, P.T, 0.0).sum(axis=0))) - 1e-6
        x0 = np.concatenate([*c0, *xi0, [r0]])
        flat = np.concatenate(c0)
        free = np.full(3 * len(xi0), np.inf)
        lbx = np.concatenate([np.maximum(flat - radius, 0.0), -free, [-np.inf]])
        ubx = np.concatenate([np.minimum(flat + radius, 1.0), free, [np.inf]])
        # The unused directions' rows (0 >= 0) are left free: bounded, their slacks sit at the
        # relaxed bound inside IPOPT's barrier and complementarity measure, which took more
        # iterations to other weights than the NLP of exactly these directions; free, the same.
        lbg = self._lbg.copy()
        lbg[len(lbg) - K + n :] = -np.inf
        with interruptible():
            sol = self._solver(x0=x0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=self._ubg)
        x = np.asarray(sol["x"]).ravel()
        weights, at = [], 0
        for k in self.rows:
            weights.append(x[at : at + k])
            at += k
        return weights, float(x[-1])


class ExchangeLP:
    """The restricted problem of :class:`ExchangeProblem` when every contact is frictionless:
    each ``p_i(u_k; c)`` is then ``f_i d_n``, linear in the weights, and the problem is the
    linear programme ``max r`` s.t. ``sum_{i in S_k} f_i d_n(u_k; c_i) >= r``, weights in
    their simplices and the trust region; HiGHS solves it exactly (IPOPT's NLP is the same
    problem: on the pistol's 7 FPC about a tenth of its time per solve). With ``centre``, its
    weights are the analytic centre of the weights within
    :data:`~closure_nlp.placement.analytic_centre.SLAB` of the optimum
    (:func:`~closure_nlp.placement.analytic_centre.analytic_centre`): where the optimum is not
    unique, the
    solver's own point of the optimal face moves with round-off, the centre does not, so the same
    part in any unit takes the same path (:attr:`PlacementOptions.lp_centre`); so do the
    subsets' ties (:func:`~closure_nlp.contact.wrenches.pushing_subsets`).
    """

    solver = "highs"

    def __init__(self, margin: float = 0.0, centre: bool = False):
        self.margin, self.centre = margin, centre

    def solve(self, frames, slots_at_c, f_max, U, c0, radius):
        """As :meth:`ExchangeProblem.solve`: the new padded weights (list) and ``r``."""
        P, _ = slots_at_c.row_terms(U)  # (n, m)
        mask = pushing_subsets(P, f_max, self.margin, self.centre)  # (m, n)
        # A[k, (i, j)] = mask_ik f_i (G_ij^T u_k)_n: row k's value is linear in the weights
        A = np.hstack(
            [
                f_max[i] * mask[i][:, None] * frame.local(U)[:, 0, :].T
                for i, frame in enumerate(frames)
            ]
        )
        owner = np.repeat(np.arange(len(frames)), [len(frame.G) for frame in frames])
        flat = np.concatenate(c0)
        lower, upper = np.maximum(flat - radius, 0.0), np.minimum(flat + radius, 1.0)
        lam, r = max_min_lp(A, owner, lower, upper)
        # the LP solver's point of a non-unique optimum moves with round-off: its centre does not
        centre = analytic_centre(A, owner, lower, upper, r, lam) if self.centre else None
        if centre is not None:
            lam, r = centre, float(np.min(A @ centre))
        weights, at = [], 0
        for c in c0:
            weights.append(lam[at : at + len(c)])
            at += len(c)
        return weights, float(r)


class ElementFrame:
    """A contact's element in the exchange NLP: its (padded) vertices' grasp matrices ``G``, and
    ``d = G(x)^T u`` as an affine function of the scaled offset ``xi = (x - centre) / size`` of
    the position (``G`` is affine in ``x``).

    ``offsets`` (rows, 3) are the vertices' ``xi``; the affine map is fitted to the vertices' own
    ``d`` by least squares, exact on their affine hull, where every convex combination lies (the
    minimum-norm fit leaves out a facet's normal direction, which no weights reach).
    """

    @classmethod
    def padded(cls, element, torque_scale: float) -> ElementFrame:
        """The frame of ``element`` with its last vertex repeated up to
        :func:`~closure_nlp.contact.wrenches.padded_rows` rows (NLP shapes are shared by
        buckets)."""
        return cls(pad_rows(element.vertices), pad_rows(element.grasp_matrices(torque_scale)))

    def __init__(self, vertices: np.ndarray, G: np.ndarray):
        centre = vertices.mean(axis=0)
        size = float(np.max(np.linalg.norm(vertices - centre, axis=1)))
        self.offsets = (vertices - centre) / (size if size > 0 else 1.0)
        self.G = G  # (rows, 6, 4)
        self._fit = np.linalg.pinv(np.hstack([np.ones((len(vertices), 1)), self.offsets]))

    def local(self, U: np.ndarray) -> np.ndarray:
        """``G_j^T u_k`` of every vertex row: (rows, 4, n)."""
        return np.einsum("jrc,kr->jck", self.G, U)

    def affine(self, U: np.ndarray):
        """``A`` (4, n) and ``B`` (12, n), ``B[4 j : 4 j + 4]`` the derivative along ``xi_j``."""
        coef = np.tensordot(self._fit, self.local(U), axes=(1, 0))  # constant, then xi_1..3
        return coef[0], coef[1:].reshape(12, -1)


def _padded(weights: np.ndarray, size: int) -> np.ndarray:
    out = np.zeros(size)
    out[: len(weights)] = weights
    return out


def _unpadded(weights: np.ndarray, count: int) -> np.ndarray:
    """Fold the weights of repeated (padding) vertices back onto the last real vertex."""
    w = np.maximum(np.asarray(weights[:count], dtype=float), 0.0)
    w[-1] += max(float(np.sum(weights[count:])), 0.0)
    return w / w.sum()




class ExchangePlacer:
    """Contact placement on element sets of one model by the exchange method, solvers reused
    across calls (:class:`~closure_nlp.placement.place.Placer` adds the certified ceiling).

    ``problems`` (optional) is a cache of exchange NLPs to share between placers: they depend
    on the shape only (vertex rows per contact, working-set size, IPOPT tolerance and subset
    margin); the model, mu, f_max and torque scale are parameters, so a study worker builds
    them once for all of its tasks. It keeps one dict of NLPs per thread, as the placer does
    without it: a placer may be called from several threads at once.
    """

    def __init__(
        self,
        eligibility: Eligibility,
        options: PlacementOptions = PlacementOptions(),
        problems: PerThread[dict] | None = None,
    ):
        require_closure_count(eligibility.specs)
        if not (problems is None or isinstance(problems, PerThread)):
            raise TypeError(f"problems: expected a PerThread cache, got {type(problems).__name__}")
        self.eligibility = eligibility
        self.options = options
        self._caches: PerThread[dict] = PerThread(dict) if problems is None else problems

    @property
    def _problems(self) -> dict[tuple, ExchangeProblem]:
        """This thread's exchange NLPs by shape."""
        return self._caches.get()

    def _frictionless(self) -> tuple[bool, ...]:
        """Per contact: no friction piece (FPC, or mu = mu_s = 0)."""
        return tuple(is_frictionless(s.type, s.mu, s.mu_s) for s in self.eligibility.specs)

    def _components(self) -> tuple[tuple[int, ...], ...]:
        """Per contact: the components of ``d`` its friction pieces weigh (none: frictionless)."""
        return tuple(
            tuple(int(j) for j in np.flatnonzero(friction_pieces(s.type, s.mu, s.mu_s).any(axis=0)))
            for s in self.eligibility.specs
        )

    def exchange_solver(self) -> str:
        """The solver of the restricted problems: with ``exchange_solver="auto"``, ``"highs"``
        when they are linear programmes (every contact frictionless), else ``"mixed"``;
        otherwise the one asked for (``"slp"``:
        :class:`~closure_nlp.placement.sequential_lp.ExchangeSLP`,
        ``"slp-model"``: :class:`~closure_nlp.placement.sequential_lp.ModelSLP`)."""
        choice = self.options.exchange_solver
        if choice != "auto":
            return choice
        return "highs" if all(self._frictionless()) else "mixed"

    def _run_solver(self, explore: bool) -> str:
        """The solver of one exchange run's restricted problems: ``"mixed"`` is IPOPT on the
        runs whose result the placement keeps (the first start, a neighbour move's run once it
        beats the placement) and IPOPT's model by the sequential LP on the exploring ones."""
        solver = self.exchange_solver()
        if solver == "mixed":
            return "slp-model" if explore else "ipopt"
        return solver

    def _problem(
        self, rows, count, solver: str | None = None
    ) -> ExchangeProblem | ExchangeLP | ExchangeSLP:
        solver = solver or self.exchange_solver()
        if solver == "highs":
            # the same problem, linear
            return ExchangeLP(self.options.subset_margin, self.options.lp_centre)
        if solver == "slp":  # one per thread: it keeps its LP solver
            return cached(self._problems, "slp", ExchangeSLP, MAX_EXCHANGE_PROBLEMS)
        if solver == "slp-model":
            margin = self.options.subset_margin
            key = ("slp-model", margin)
            return cached(self._problems, key, lambda: ModelSLP(margin), MAX_EXCHANGE_PROBLEMS)
        capacity = next((b for b in DIRECTION_BUCKETS if count <= b), count)
        components = self._components()
        tol, margin = self.options.ipopt_tol, self.options.subset_margin
        key = (rows, capacity, tol, margin, components)
        return cached(
            self._problems,
            key,
            lambda: ExchangeProblem(rows, capacity, tol, margin, components),
            MAX_EXCHANGE_PROBLEMS,
        )

    def contact_set(self, elements, weights) -> ContactSet:
        model, specs = self.eligibility.model, self.eligibility.specs
        return ContactSet(
            tuple(
                specs[i].at(
                    model.elements[e].position(w),
                    model.elements[e].inward_normal,
                    f"contacts[{i}]",
                )
                for i, (e, w) in enumerate(zip(elements, weights))
            ),
            self.eligibility.torque_scale,
            model.reference_point,
            self.eligibility.tolerance,
        )

    def optimise(
        self,
        elements,
        weights,
        progress: Progress | None = None,
        initial=None,
        max_rounds=None,
        directions: list | None = None,
        bar: float = np.inf,
        explore: bool = False,
    ):
        """Trust-region exchange on fixed elements from ``weights`` (``initial``: their rho
        result, when already known), for at most ``max_rounds`` (default: the options') rounds.
        ``directions`` (optional, updated in place) holds the weak directions found by earlier
        calls on the same model: they start the working set (any direction gives a valid
        restriction), so a later start or neighbour trial need not find them again. A run that
        ends at or above ``bar`` (the value the caller needs it to beat) is not checked by
        the default search (``validate``): a check could only raise it. ``explore``: a run that
        only has to beat the best one so far (a further start, a neighbour-move trial), whose
        restricted problems the ``"mixed"`` solver gives to the sequential LP.

        Returns (weights, rho result, the model's last predicted ``-rho``, rounds).
        """
        model, specs = self.eligibility.model, self.eligibility.specs
        minimizer = self.eligibility.minimizer
        light = minimizer.with_search(SCREEN_SEARCH)
        judge = minimizer.with_search(ROUND_SEARCH) if self.options.round_search else minimizer
        ts = self.eligibility.torque_scale
        counts = [len(model.elements[e].vertices) for e in elements]
        frames = [ElementFrame.padded(model.elements[e], ts) for e in elements]
        rows = tuple(len(frame.G) for frame in frames)
        f_max = np.array([spec.f_max for spec in specs])
        best_w = [np.asarray(w, float) for w in weights]
        best = initial or search_rho(self.contact_set(elements, best_w), minimizer=minimizer)
        U = list(sphere_samples(self.options.random_directions, seed=1))
        if directions is not None:
            U += directions[-SHARED_DIRECTIONS:]
        U.append(best.direction)
        first_found = len(U) - 1
        # A trust region around the best weights: the restricted model is only good nearby, and
        # without it the solves jump between far corners (cutting planes oscillate).
        c_best, radius, predicted = [_padded(w, k) for w, k in zip(best_w, rows)], 0.5, np.inf
        rounds = 0
        at_best = WrenchSlots.from_contacts(self.contact_set(elements, best_w))
        limit = max_rounds or self.options.max_rounds
        checked = True  # best's value is the default search's (a start's, or validated)
        # "slp-ipopt": the sequential LP's rounds while they pay off; from the first one that
        # does not, IPOPT's, from a trust region of at least 0.5, so that a run ends where
        # IPOPT's rounds end it (a point of IPOPT's model, not a stall of the linearisation).
        solver = self._run_solver(explore)
        sequential = solver in ("slp", "slp-ipopt")
        tail = "ipopt" if solver == "slp-ipopt" else solver
        while True:
            while rounds < limit:
                rounds += 1
                problem = self._problem(rows, len(U), "slp" if sequential else tail)
                c, predicted = problem.solve(frames, at_best, f_max, np.array(U), c_best, radius)
                if predicted + best.rho <= self.options.gap * max(1.0, abs(best.rho)):
                    if sequential and solver == "slp-ipopt":
                        sequential, radius = False, max(radius, 0.5)
                        continue
                    break  # the model sees no better weights within the trust region
                w = [_unpadded(ci, k) for ci, k in zip(c, counts)]
                trial_slots = WrenchSlots.from_contacts(self.contact_set(elements, w))
                warm = best.direction
                if self.options.round_search:
                    values = trial_slots.support(np.array(U))
                    if self.options.lp_centre:  # ties in index order, in any unit
                        weakest = lowest_first(values, float(f_max.sum()), WARM_DIRECTIONS)
                    else:
                        weakest = np.argsort(values)[:WARM_DIRECTIONS]
                    warm = np.vstack([warm, np.array(U)[weakest]])
                if self.options.screen:
                    # the light search alone: a certificate per screened round cost more than
                    # the full search it was meant to spare (bench plan: fast mode 5-20x slower)
                    found = search_rho(trial_slots, minimizer=light, warm_start=warm)
                    warm = found.direction
                if not self.options.screen or found.rho < best.rho:
                    found = search_rho(trial_slots, minimizer=judge, warm_start=warm)
                U.append(found.direction)
                if found.rho < best.rho:
                    best, best_w, c_best, at_best = found, w, c, trial_slots
                    radius = min(1.0, 2.0 * radius)
                    checked = False
                elif sequential and solver == "slp-ipopt":
                    sequential, radius = False, max(radius, 0.5)
                else:
                    radius *= 0.25
                if progress:
                    progress("placement round", rounds, best.rho)
                if radius < MIN_RADIUS:
                    break
            # The exchange keeps the weights that the round search values lowest, so it seeks
            # out that search's misses: before the run ends, the default search checks the
            # best weights, and a weaker direction it finds resumes the run from the truer value.
            if checked or not self.options.validate or best.rho >= bar:
                break
            again, checked = self._validated(at_best, best), True
            if again is best:
                break
            best, radius = again, 0.5
            U.append(best.direction)
        if directions is not None:
            directions += U[first_found:]
        return best_w, best, predicted, rounds

    def __call__(self, elements, weights=None, progress: Progress | None = None) -> PlacementResult:
        """Place one contact on each of ``elements`` (from ``weights``, default the centroids);
        ``progress`` sees every exchange round, start, neighbour move and the certification."""
        t0 = time.perf_counter()
        model = self.eligibility.model
        elements = list(self.eligibility.check_elements(elements))
        counts = [len(model.elements[e].vertices) for e in elements]
        if weights is None:  # the element centroids
            weights = [np.full(k, 1.0 / k) for k in counts]
        if len(weights) != len(elements):
            raise ValueError(f"weights: expected {len(elements)} lists, got {len(weights)}")
        weights = [
            simplex_weights(w, k, f"weights[{i}]") for i, (w, k) in enumerate(zip(weights, counts))
        ]
        start_elements, start_set = tuple(elements), self.contact_set(elements, weights)
        # The start's search value is never above its certified rho (a found support value), so
        # the start is certified only when the final result does not beat that value (below).
        start = search_rho(start_set, minimizer=self.eligibility.minimizer)
        shared = [] if self.options.share_directions else None
        rng = np.random.default_rng(self.options.seed)
        probe = self.options.probe_rounds if self.options.starts > 1 else 0
        # With probe rounds, the first starts get that many rounds each and only the best of
        # them runs on to the full budget; otherwise each runs to the full budget.
        best_w, best, predicted, rounds = self.optimise(
            elements, weights, progress, start, probe, shared
        )
        if progress:
            progress("placement start", 1, best.rho)
        for k in range(1, self.options.starts + self.options.extra_starts):
            if k == self.options.starts and probe:
                best_w, best, predicted, n_rounds = self.optimise(
                    elements, best_w, progress, best, None, shared
                )
                rounds += n_rounds
            if k >= self.options.starts and best.force_closure:
                break  # extra starts only while no start has reached force closure
            trial = [rng.dirichlet(np.ones(k)) for k in counts]
            limit = probe if k < self.options.starts else None
            w, found, up, n_rounds = self.optimise(
                elements, trial, progress, None, limit, shared, bar=best.rho, explore=True
            )
            rounds += n_rounds
            if found.rho < best.rho:
                best_w, best, predicted = w, found, up
            if progress:
                progress("placement start", k + 1, best.rho)
        if probe and self.options.extra_starts == 0:  # the loop above never reached k == starts
            best_w, best, predicted, n_rounds = self.optimise(
                elements, best_w, progress, best, None, shared
            )
            rounds += n_rounds
        moves = []
        for _ in range(self.options.neighbour_moves):
            move, n_rounds = self._try_moves(elements, best_w, best, progress, shared)
            rounds += n_rounds
            if move is None:
                break
            (i, target, w_new, found, up) = move
            moves.append(Move(i, elements[i], target, best.rho, found.rho))
            if progress:
                progress("neighbour move", len(moves), found.rho)
            elements[i] = target
            best_w, best, predicted = w_new, found, up
        # The exchange kept the weights where the rho solver reported the lowest rho, so any
        # miss of its global search was selected for: the reported rho is certified (the branch
        # and bound is global, whatever its seed).
        contact_set = self.contact_set(elements, best_w)
        if progress:
            progress("certification", 0, best.rho)
        final = rho(contact_set, minimizer=self.eligibility.minimizer, warm_start=best.direction)
        if final.rho > start.rho:
            start = rho(start_set, minimizer=self.eligibility.minimizer)
        if final.rho > start.rho:
            # The exchange steered by the search's values, which can miss; certified, the start
            # is better: keep it, so that the result is never worse than the start it reports.
            elements, best_w, moves, contact_set, final = (
                list(start_elements),
                weights,
                [],
                start_set,
                start,
            )
        placed = tuple(
            PlacedContact(e, w, model.elements[e].position(w), model.elements[e].inward_normal)
            for e, w in zip(elements, best_w)
        )
        if progress:
            progress("certification", 1, final.rho)
        result = PlacementResult(
            placed,
            contact_set,
            final.rho,
            final.force_closure,
            final.direction,
            start.rho,
            predicted,
            rounds,
            tuple(moves),
            time.perf_counter() - t0,
            final.bounds,
            final.marginal,
            final.converged,
            robust=final.robust,
            shift=final.shift,
            exchange_solver=self.exchange_solver(),
        )
        return result

    def _validated(self, slots: WrenchSlots, found):
        """``found`` (a round search's result on ``slots``), or the weaker answer of the
        eligibility's own search (the starts' search: more samples and IPOPT runs)."""
        again = search_rho(slots, minimizer=self.eligibility.minimizer, warm_start=found.direction)
        return again if again.rho > found.rho else found

    def _try_moves(self, elements, weights, best, progress=None, directions=None):
        """The first neighbour move (contact on its element's boundary) that lowers rho, or
        None; and the exchange rounds spent on the trials."""
        model = self.eligibility.model
        tol = self.eligibility.minimizer.tolerances.geometry
        spent = 0
        for i, (e, w) in enumerate(zip(elements, weights)):
            element = model.elements[e]
            if len(w) > 1 and w.min() > 1e-6:
                continue  # strictly inside its element: not on a shared boundary
            here = element.position(w)
            for n in model.neighbours(e):
                target = model.elements[n]
                w_n = nearest_weights(target.vertices, here)
                gap = np.linalg.norm(target.position(w_n) - here)
                if gap > 1e3 * tol * max(element.size, target.size):  # relative: any unit
                    continue  # the neighbour does not touch this contact
                trial = list(elements)
                trial[i] = n
                margin = self.options.gap * max(1.0, abs(best.rho))
                if self._cannot_beat(trial, best, margin):
                    continue
                trial_w = list(weights)
                trial_w[i] = w_n
                probe = self.options.move_rounds or self.options.probe_rounds or None
                w_new, found, up, n_rounds = self.optimise(
                    trial,
                    trial_w,
                    progress,
                    None,
                    probe,
                    directions,
                    bar=best.rho - margin,
                    explore=True,
                )
                spent += n_rounds
                if found.rho < best.rho - margin:
                    if probe:  # a move that helps runs on to the full budget
                        w_new, found, up, more = self.optimise(
                            trial, w_new, progress, found, None, directions
                        )
                        spent += more
                    return (i, n, w_new, found, up), spent
        return None, spent

    def _cannot_beat(self, elements, best, margin: float) -> bool:
        """Whether no placement on ``elements`` can have rho below ``best.rho - margin``.

        Any placement's support function is at most the elements' (What_c^M holds every
        placement's W_c^M), so one direction ``u`` with ``-p_hat(u) >= best.rho - margin``
        proves it (rho >= -p(u) >= -p_hat(u)): a light search for a weak direction of the
        elements, from the placement's own, is enough, and it never rules out a trial wrongly.
        On the lamp it ruled out 12 of 20 neighbour-move trials, which had cost 4.2 of 11.3 s.
        """
        minimizer = self.eligibility.minimizer.with_search(SCREEN_SEARCH)
        bar = best.rho - margin  # the search may stop as soon as it shows rho >= bar
        found = minimizer(self.eligibility.slots(elements), best.direction, -bar)
        return -found.value >= bar



__all__ = [
    "ElementFrame",
    "ExchangeLP",
    "ExchangePlacer",
    "ExchangeProblem",
    "Move",
    "PlacedContact",
    "PlacementOptions",
    "PlacementResult",
]
