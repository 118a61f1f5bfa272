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

With a tolerance, every comparison (a round's weights, a start, a neighbour move, the start
kept) is by rho plus the contacts' support shift within it (:meth:`ExchangePlacer.steering`):
a contact moved onto a coarse element must gain more than its tolerance costs.
"""

from __future__ import annotations

import time

import numpy as np

from closure_nlp.base.progress import Progress
from closure_nlp.base.solver_cache import PerThread, cached
from closure_nlp.base.ties import lowest_first
from closure_nlp.contact.contact_set import ContactSet, friction_pieces, is_frictionless
from closure_nlp.contact.count import require_closure_count
from closure_nlp.contact.wrenches import WrenchSlots, pad_rows
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.robustness import has_tolerance, robust_value, support_shift
from closure_nlp.criterion.sphere_search import sphere_samples
from closure_nlp.criterion.support_minimum import SearchOptions, rho, search_rho
from closure_nlp.model.elements import nearest_weights, simplex_weights
from closure_nlp.placement.load_objective import LoadObjective
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.restricted import ExchangeLP, ExchangeProblem
from closure_nlp.placement.result import Move, PlacedContact, PlacementResult
from closure_nlp.placement.sequential_lp import ExchangeSLP, ModelSLP
from closure_nlp.placement.spacing import Spacing, SpacingError, check_fixed_spacing
from closure_nlp.selection.algorithms import SCREEN_SEARCH

# Working-set sizes the exchange NLP is built for (unused directions masked out). An IPOPT
# iteration costs about in proportion to the size (the same optimum at any size), so the sizes
# are close together; a run grows its set by one direction a round.
DIRECTION_BUCKETS = (16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256)
# Exchange NLPs kept per cache: each holds tens of MB at most; unbounded, a worker running
# task after task would keep every shape it ever built.
MAX_EXCHANGE_PROBLEMS = 6
# Weak directions of earlier exchange runs on the same elements that start a later run's working
# set: with the random ones and one run's rounds (max_rounds 40) it stays within 128.
SHARED_DIRECTIONS = 64
# The trust region's smallest radius (barycentric weights): below it the weights cannot move.
MIN_RADIUS = 1e-9
# The search that judges each exchange round's weights: they lie within the trust region of the
# best ones, whose weak directions the working set holds, so the WARM_DIRECTIONS of them weakest at
# the new weights start it, besides a quarter of the default's samples: it finds the weaker
# direction more often than the default search from the best direction alone. One smoothed
# descent: without it the exchange follows weaker directions less often and ends worse on more
# fixture tasks than it saves in time.
ROUND_SEARCH = SearchOptions(samples=32, smoothing=(0.03,), ipopt_starts=2, ipopt_polish=False)
WARM_DIRECTIONS = 4


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
        self.vertices = vertices  # (rows, 3)
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

    ``loads`` (optional, as :func:`~closure_nlp.contact.loads.as_loads` takes them): the exchange
    maximises the least certified load factor of these cases instead of ``-rho``
    (:mod:`~closure_nlp.placement.load_objective`); the result still reports the placement's rho.

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
        loads=None,
    ):
        require_closure_count(eligibility.all_specs)
        if options.min_spacing:
            check_fixed_spacing(eligibility, options.min_spacing)
        if not (problems is None or isinstance(problems, PerThread)):
            raise TypeError(f"problems: expected a PerThread cache, got {type(problems).__name__}")
        self.eligibility = eligibility
        self.options = options
        self._caches: PerThread[dict] = PerThread(dict) if problems is None else problems
        self.objective = None
        if loads is not None:
            self.objective = LoadObjective.of(eligibility, loads)

    def _search(self, contacts, minimizer, warm_start=None):
        """The exchange's value of contacts (a ContactSet or its slots): the rho search's
        answer, or the load objective's (``rho`` = minus the least load factor)."""
        if self.objective is not None:
            return self.objective(
                WrenchSlots.from_contacts(contacts)
                if isinstance(contacts, ContactSet)
                else contacts
            )
        return search_rho(contacts, minimizer=minimizer, warm_start=warm_start)

    @property
    def _problems(self) -> dict[tuple, ExchangeProblem]:
        """This thread's exchange NLPs by shape."""
        return self._caches.get()

    def _frictionless(self) -> tuple[bool, ...]:
        """Per contact: no friction piece (FPC, or mu = mu_s = 0)."""
        return tuple(is_frictionless(s.type, s.mu, s.mu_s) for s in self.eligibility.all_specs)

    def _components(self) -> tuple[tuple[int, ...], ...]:
        """Per contact: the components of ``d`` its friction pieces weigh (none: frictionless)."""
        return tuple(
            tuple(int(j) for j in np.flatnonzero(friction_pieces(s.type, s.mu, s.mu_s).any(axis=0)))
            for s in self.eligibility.all_specs
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
        self, rows, count, solver: str | None = None, pairs=()
    ) -> ExchangeProblem | ExchangeLP | ExchangeSLP:
        solver = "ipopt" if pairs else solver or self.exchange_solver()
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
        key = (rows, capacity, tol, margin, pairs, components)
        return cached(
            self._problems,
            key,
            lambda: ExchangeProblem(rows, capacity, tol, margin, components, pairs),
            MAX_EXCHANGE_PROBLEMS,
        )

    def contact_set(self, elements, weights) -> ContactSet:
        """The fixed contacts, then one on each of ``elements`` at ``weights``."""
        model, specs = self.eligibility.model, self.eligibility.specs
        return ContactSet(
            self.eligibility.fixed.contacts
            + tuple(
                specs[i].at(
                    model.elements[e].position(w),
                    model.elements[e].inward_normal,
                    f"contacts[{i}]",
                )
                for i, (e, w) in enumerate(zip(elements, weights))
            ),
            self.eligibility.torque_scale,
            model.reference_point,
            self.eligibility.contact_tolerance(elements),
        )

    def steering(self, contacts: ContactSet | WrenchSlots, found, tolerance=None) -> float:
        """What placement steers by: ``found.rho`` plus the support shift of ``contacts``
        within their tolerance (``tolerance``, default the contact set's own); rho itself
        without one; the objective's value (minus the least load factor) when steering by loads."""
        if self.objective is not None:
            return found.rho
        if tolerance is None:
            tolerance = contacts.tolerance
        if not has_tolerance(tolerance):
            return found.rho
        return robust_value(found.rho, support_shift(contacts, tolerance))

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
        """:meth:`run`; with a minimum spacing that some pair of contacts can break, the run
        without its constraints first (their own solvers, faster), and only when its weights
        break the spacing a run with them, from those weights: a local optimum that keeps the
        spacing without its constraints is one with them."""
        args = (progress, initial, max_rounds, directions, bar, explore)
        spacing = self._spacing(elements)
        found = self.run(elements, weights, *args)
        if spacing is None or self._kept(elements, found[0], spacing):
            return found
        w, best, predicted, rounds = found
        again = self.run(elements, w, progress, best, max_rounds, directions, bar, explore, True)
        return (*again[:3], rounds + again[3])

    def run(
        self,
        elements,
        weights,
        progress: Progress | None = None,
        initial=None,
        max_rounds=None,
        directions: list | None = None,
        bar: float = np.inf,
        explore: bool = False,
        spaced: bool = False,
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

        ``spaced``: keep the minimum spacing by constraints of the restricted problems.

        Returns (weights, rho result, the model's last predicted ``-rho``, rounds).
        """
        model, fixed = self.eligibility.model, self.eligibility.fixed
        minimizer = self.eligibility.minimizer
        light = minimizer.with_search(SCREEN_SEARCH)
        judge = minimizer.with_search(ROUND_SEARCH) if self.options.round_search else minimizer
        ts = self.eligibility.torque_scale
        counts = [len(model.elements[e].vertices) for e in elements]
        # the fixed contacts first, each a point: its one weight cannot move
        frames = [ElementFrame.padded(e, ts) for e in fixed.elements]
        frames += [ElementFrame.padded(model.elements[e], ts) for e in elements]
        rows = tuple(len(frame.G) for frame in frames)
        k0 = len(fixed)
        f_max = np.array([spec.f_max for spec in self.eligibility.all_specs])
        spacing = self._spacing(elements) if spaced else None
        pairs = spacing.pairs if spacing else ()
        kept_apart = (spacing.length, spacing.distance) if spacing else None
        best_w = [np.asarray(w, float) for w in weights]
        best_ok = self._kept(elements, best_w, spacing)
        start_w = best_w
        if not best_ok:  # coincident contacts have no gradient apart: start from nearby weights
            rng = np.random.default_rng(len(best_w))
            start_w = [0.8 * w + 0.2 * rng.dirichlet(np.ones(len(w))) for w in best_w]
        best = initial or self._search(self.contact_set(elements, best_w), minimizer)
        tolerance = self.eligibility.contact_tolerance(elements)
        if self.objective is not None:  # each case's directions u / u.w
            U, directions = self.objective.directions(self.options.random_directions), None
        else:
            U = list(sphere_samples(self.options.random_directions, seed=1))
        if directions is not None:
            U += directions[-SHARED_DIRECTIONS:]
        U.append(best.direction)
        first_found = len(U) - 1
        # A trust region around the best weights: the restricted model is only good nearby, and
        # without it the solves jump between far corners (cutting planes oscillate).
        c_best = [_padded(np.ones(1), k) for k in rows[:k0]]
        c_best += [_padded(w, k) for w, k in zip(start_w, rows[k0:])]
        radius, predicted = (0.5 if best_ok else 1.0), np.inf
        rounds = 0
        at_best = WrenchSlots.from_contacts(self.contact_set(elements, start_w))
        best_value = self.steering(at_best, best, tolerance)
        limit = max_rounds or self.options.max_rounds
        checked = True  # best's value is the default search's (a start's, or validated)
        # "slp-ipopt": the sequential LP's rounds while they pay off; from the first one that
        # does not, IPOPT's, from a trust region of at least 0.5, so that a run ends where
        # IPOPT's rounds end it (a point of IPOPT's model, not a stall of the linearisation).
        solver = "ipopt" if pairs else self._run_solver(explore)  # spacing: IPOPT's NLP
        sequential = solver in ("slp", "slp-ipopt")
        tail = "ipopt" if solver == "slp-ipopt" else solver
        while True:
            while rounds < limit:
                rounds += 1
                problem = self._problem(rows, len(U), "slp" if sequential else tail, pairs)
                args = (frames, at_best, f_max, np.array(U), c_best, radius)
                c, predicted = problem.solve(*args, kept_apart) if pairs else problem.solve(*args)
                no_gain = predicted + best.rho <= self.options.gap * max(1.0, abs(best.rho))
                if no_gain and best_ok:
                    if sequential and solver == "slp-ipopt":
                        sequential, radius = False, max(radius, 0.5)
                        continue
                    break  # the model sees no better weights within the trust region
                w = [_unpadded(ci, k) for ci, k in zip(c[k0:], counts)]
                trial_ok = self._kept(elements, w, spacing)
                if not (trial_ok or best_ok):
                    break  # no placement found that keeps the spacing
                trial_slots = WrenchSlots.from_contacts(self.contact_set(elements, w))
                warm = best.direction
                if self.objective is not None:
                    found = self.objective(trial_slots)
                elif self.options.round_search:
                    values = trial_slots.support(np.array(U))
                    if self.options.lp_centre:  # ties in index order, in any unit
                        weakest = lowest_first(values, float(f_max.sum()), WARM_DIRECTIONS)
                    else:
                        weakest = np.argsort(values)[:WARM_DIRECTIONS]
                    warm = np.vstack([warm, np.array(U)[weakest]])
                if self.options.screen:
                    # the light search alone: a certificate per screened round cost more than
                    # the full search it was meant to spare
                    found = search_rho(trial_slots, minimizer=light, warm_start=warm)
                    warm = found.direction
                if self.objective is None and (
                    not self.options.screen
                    or not best_ok
                    or self.steering(trial_slots, found, tolerance) < best_value
                ):
                    found = search_rho(trial_slots, minimizer=judge, warm_start=warm)
                U.append(found.direction)
                value = self.steering(trial_slots, found, tolerance)
                if trial_ok and (value < best_value or not best_ok):
                    best, best_w, c_best, at_best, best_value = found, w, c, trial_slots, value
                    radius = min(1.0, 2.0 * radius) if best_ok else 0.5
                    best_ok = True
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
            if checked or not self.options.validate or best_value >= bar or self.objective:
                break
            again, checked = self._validated(at_best, best), True
            if again is best:
                break
            best, radius = again, 0.5
            best_value = self.steering(at_best, best, tolerance)
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
        spacing = self._spacing(elements)
        reason = spacing.impossible() if spacing else None
        if reason:
            raise SpacingError(f"min_spacing: cannot be kept: {reason}")
        start_elements, start_set = tuple(elements), self.contact_set(elements, weights)
        # The start's search value is never above its certified rho (a found support value), so
        # the start is certified only when the final result does not beat that value (below).
        start = self._search(start_set, self.eligibility.minimizer)
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
        best_value = self._value(elements, best_w, best)
        for k in range(1, self.options.starts + self.options.extra_starts):
            if k == self.options.starts and probe:
                best_w, best, predicted, n_rounds = self.optimise(
                    elements, best_w, progress, best, None, shared
                )
                rounds += n_rounds
                best_value = self._value(elements, best_w, best)
            if k >= self.options.starts and best.force_closure:
                break  # extra starts only while no start has reached force closure
            trial = [rng.dirichlet(np.ones(k)) for k in counts]
            limit = probe if k < self.options.starts else None
            w, found, up, n_rounds = self.optimise(
                elements, trial, progress, None, limit, shared, bar=best_value, explore=True
            )
            rounds += n_rounds
            value = self._value(elements, w, found)
            if self._better(elements, w, value, best_w, best_value):
                best_w, best, predicted, best_value = w, found, up, value
            if progress:
                progress("placement start", k + 1, best.rho)
        if probe and self.options.extra_starts == 0:  # the loop above never reached k == starts
            best_w, best, predicted, n_rounds = self.optimise(
                elements, best_w, progress, best, None, shared
            )
            rounds += n_rounds
        moves = []
        for _ in range(self.options.neighbour_moves):
            best_value = self._value(elements, best_w, best)
            move, n_rounds = self._try_moves(elements, best_w, best, best_value, progress, shared)
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
        start_ok = self._kept(start_elements, weights, spacing)
        if self.objective is not None:  # certified load factors: keep the start if better
            if best.rho > start.rho and start_ok:
                elements, best_w, moves, contact_set = list(start_elements), weights, [], start_set
            start = rho(start_set, minimizer=self.eligibility.minimizer)  # its rho, reported
        warm = None if self.objective is not None else best.direction  # a load's is not unit
        final = rho(contact_set, minimizer=self.eligibility.minimizer, warm_start=warm)
        steered = self.objective is None and start_ok
        if steered and self.steering(contact_set, final) > self.steering(start_set, start):
            start = rho(start_set, minimizer=self.eligibility.minimizer)
        if steered and self.steering(contact_set, final) > self.steering(start_set, start):
            # The exchange steered by the search's values, which can miss; certified, the start
            # is better: keep it, so that the result is never worse than the start it reports.
            elements, best_w, moves, contact_set, final = (
                list(start_elements),
                weights,
                [],
                start_set,
                start,
            )
        if self.options.min_spacing:
            final_spacing = self._spacing(elements)
            if final_spacing:
                final_spacing.check(self._positions(elements, best_w))
        if progress:
            progress("certification", 1, final.rho)
        return self._result(elements, best_w, contact_set, final, start.rho, predicted, rounds,
                            moves, t0)  # fmt: skip

    def certified_at(self, elements, weights, warm_start=None) -> PlacementResult | None:
        """The placement of one contact on each of ``elements`` at ``weights`` as it is (no
        exchange round), its rho certified; None when it breaks the minimum spacing."""
        t0 = time.perf_counter()
        if not self._kept(elements, weights):
            return None
        contact_set = self.contact_set(elements, weights)
        final = rho(contact_set, minimizer=self.eligibility.minimizer, warm_start=warm_start)
        return self._result(elements, weights, contact_set, final, final.rho, final.rho, 0, (), t0)

    def _result(self, elements, weights, contact_set, final, start_rho, predicted, rounds, moves,
                t0) -> PlacementResult:  # fmt: skip
        """The result of the contacts at ``weights`` on ``elements`` whose certified rho is
        ``final``, started at ``start_rho`` (timed from ``t0``)."""
        return PlacementResult(
            self._placed(elements, weights),
            contact_set,
            final.rho,
            final.force_closure,
            final.direction,
            start_rho,
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

    def _placed(self, elements, weights) -> tuple:
        """The contacts at ``weights`` on ``elements``, as a result lists them."""
        model = self.eligibility.model
        return tuple(
            PlacedContact(e, w, model.elements[e].position(w), model.elements[e].inward_normal)
            for e, w in zip(elements, weights)
        )

    def _value(self, elements, weights, found) -> float:
        """:meth:`steering` of the contacts at ``weights`` on ``elements``."""
        return self.steering(self.contact_set(elements, weights), found)

    def _spacing(self, elements) -> Spacing | None:
        """The spacing of contacts on ``elements`` (None: no minimum, or no pair that can
        come closer than it)."""
        if not self.options.min_spacing:
            return None
        spacing = Spacing(self.eligibility, elements, self.options.min_spacing)
        return spacing if spacing.pairs else None

    def _positions(self, elements, weights) -> np.ndarray:
        """(k + m, 3): the fixed contacts' positions, then those on ``elements``."""
        model = self.eligibility.model
        new = [model.elements[e].position(w) for e, w in zip(elements, weights)]
        return np.vstack([self.eligibility.fixed.positions, *new])

    def _kept(self, elements, weights, spacing: Spacing | None | bool = True) -> bool:
        """Whether the contacts on ``elements`` at ``weights`` keep the minimum spacing
        (``spacing``: theirs when known)."""
        if spacing is True:
            spacing = self._spacing(elements)
        return not spacing or spacing.kept(self._positions(elements, weights))

    def _better(self, elements, w, value: float, best_w, best_value: float) -> bool:
        """Whether a run's result at ``w`` (steering ``value``) replaces the best (at
        ``best_w``), both on ``elements``: a lower value keeping the spacing, or keeping it
        where the best does not."""
        if not self.options.min_spacing:
            return value < best_value
        if not self._kept(elements, w):
            return False
        return value < best_value or not self._kept(elements, best_w)

    def _validated(self, slots: WrenchSlots, found):
        """``found`` (a round search's result on ``slots``), or the weaker answer of the
        eligibility's own search (the starts' search: more samples and IPOPT runs)."""
        again = search_rho(slots, minimizer=self.eligibility.minimizer, warm_start=found.direction)
        return again if again.rho > found.rho else found

    def _try_moves(self, elements, weights, best, best_value, progress=None, directions=None):
        """The first neighbour move (contact on its element's boundary) that lowers the
        steering value (:meth:`steering`, ``best_value`` now), or None; and the exchange rounds
        spent on the trials."""
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
                margin = self.options.gap * max(1.0, abs(best_value))
                if self._cannot_beat(trial, best_value - margin, best.direction):
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
                    bar=best_value - margin,
                    explore=True,
                )
                spent += n_rounds
                if not self._kept(trial, w_new):
                    continue
                if self._value(trial, w_new, found) < best_value - margin or not self._kept(
                    elements, weights
                ):
                    if probe:  # a move that helps runs on to the full budget
                        w_new, found, up, more = self.optimise(
                            trial, w_new, progress, found, None, directions
                        )
                        spent += more
                    return (i, n, w_new, found, up), spent
        return None, spent

    def _cannot_beat(self, elements, bar: float, direction) -> bool:
        """Whether no placement on ``elements`` can have a steering value below ``bar``.

        Any placement's support function is at most the elements' (What_c^M holds every
        placement's W_c^M), so one direction ``u`` with ``-p_hat(u) >= bar`` proves it (rho +
        shift >= rho >= -p(u) >= -p_hat(u), the shift never negative): a light search for a
        weak direction of the elements, from the placement's own (``direction``), is enough,
        and it never rules out a trial wrongly. A trial ruled out skips its exchange run, most
        of a neighbour move's cost.
        """
        if self.objective is not None:  # no placement holds more than the elements do
            return -self.objective.upper_bound(self.eligibility.slots(elements)) >= bar
        minimizer = self.eligibility.minimizer.with_search(SCREEN_SEARCH)
        # the search may stop as soon as it shows rho >= bar
        found = minimizer(self.eligibility.slots(elements), direction, -bar)
        return -found.value >= bar


__all__ = ["ElementFrame", "ExchangePlacer"]
