"""An independent reference for tests: bounds on rho from an inner polytope (qhull) and an SOCP.

This was the package's certificate before the branch and bound of
:mod:`closure_nlp.criterion.certificate`;
it is kept, for the tests only, because it reaches the same numbers by other mathematics (the
facets of a hull of support points instead of a partition of the sphere), so each checks the
other. It is slow at closure sets (hundreds of ms) and wide at symmetric minima.

Every unit direction ``u`` gives ``rho = -min_{|v| = 1} p(v) >= -p(u)``: the **lower bound** is
``lo = -min p`` over all directions evaluated. The **upper bound** comes from an inner polytope:
support points of ``W`` (wrenches of the set, :meth:`WrenchSlots.support_points`) span a polytope
``Q`` inside ``W``.

* Origin strictly inside ``Q``: the ball of radius ``d_in`` (distance to ``Q``'s nearest facet)
  lies in ``Q``, hence in ``W``, so ``-rho >= d_in`` and ``hi = -d_in < 0``. The support values
  along the normals of the facets nearer than ``-lo`` tighten ``lo``, and the support points
  there, when they lie beyond their facets, are added to ``Q``; repeat until ``hi - lo <= tol *
  max(1, |rho|)`` (DESIGN.md: "add that support point and repeat until the bounds meet"). The
  first polytope already holds cross-polytopes of support points around the hint direction
  (IPOPT's ``u*``) at angles down to 3e-4, which resolve the curved part of ``W`` there.
* Origin not inside ``Q``: ``rho <= dist(0, W) <= dist(0, Q) = |x|`` for any point ``x`` of
  ``Q``; the nearest one comes from a small QP over convex weights (any feasible weights give a
  valid bound, so the solver's accuracy does not matter). When the origin is outside ``W`` (the
  SOCP of :mod:`closure_nlp.criterion.crosscheck` says how far), the refinement walks like Gilbert's
  algorithm: support points at ``-x / |x|`` and around it.

The bounds are exact up to floating-point evaluation of ``p`` and qhull's roundoff, which
:data:`QHULL_MARGIN` (1e-10 relative) covers. The hulls of 6-D point sets grow fast (100-200
facets per point): :class:`PolytopeOptions` caps the work, and a set whose weakest directions form
a continuum (symmetric grasps of curved cones) then gets valid but wider bounds
(``converged=False``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import cvxpy as cp
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
from closure_nlp.base.validation import as_vector
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.crosscheck import SOLVER, as_slots, ball_minimum

# Taken off the nearest facet's distance (relative to the wrench scale): covers qhull's
# roundoff (its facets may be off by ~1e-11 relative after merges), far below any tolerance.
QHULL_MARGIN = 1e-10
# Relative pull towards the origin that puts degenerate support points in general position.
SHRINK = 1e-9
# A best direction farther than this from every cloud centre gets a cloud of its own.
RECENTRE = 0.05


@dataclass(frozen=True)
class PolytopeOptions:
    """How far the refinement goes.

    Attributes
    ----------
    samples : int
        Pseudo-random directions in the first polytope (besides ``+-e_k`` and the hints).
    scales : tuple of float
        Angles (radians, roughly) of the cross-polytopes of directions around the best direction
        found (and the hint): the finest sets the precision reachable without refinement.
    batch : int
        Facets examined (support points added) per refinement step.
    max_iter : int
        Refinement steps before the (then wider) bounds are returned as they are.
    max_points : int
        Vertices of the inner polytope beyond which no refinement step starts (a 6-D hull of
        ``n`` points has 100-200 ``n`` facets: 600 points take qhull about 0.3-0.5 s). Sets whose
        weakest directions form a continuum (symmetric grasps of curved cones) can need more;
        they get valid, wider bounds.
    max_facets : int
        Facets of the inner polytope beyond which no refinement step starts (the same budget
        for sets whose support points lie on many flat pieces, SFCl for instance).
    seed : int
        Seed of the pseudo-random directions: results are reproducible.
    """

    samples: int = 60
    scales: tuple = (0.3, 0.1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4)
    batch: int = 48
    max_iter: int = 40
    max_points: int = 600
    max_facets: int = 60_000
    seed: int = 0

    def __post_init__(self) -> None:
        scales = self.scales
        if not isinstance(scales, tuple) or not all(
            isinstance(e, (int, float)) and not isinstance(e, bool) and 0 < e < 1 for e in scales
        ):
            raise ValueError(f"options.scales: must be a tuple of numbers in (0, 1): {scales!r}")
        for name in ("samples", "batch", "max_iter", "max_points", "max_facets", "seed"):
            value = getattr(self, name)
            least = 0 if name in ("samples", "seed") else 1
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"options.{name}: must be an integer >= {least}, got {value!r}")


@dataclass(frozen=True)
class PolytopeBounds:
    """``lo <= rho <= hi``; unpacks as ``lo, hi = polytope_bounds(...)``.

    Attributes
    ----------
    lo, hi : float
    converged : bool
        ``hi - lo <= tol * max(1, |lo|, |hi|)``; otherwise the bounds are valid but wider.
    force_closure : bool or None
        ``True`` when ``hi < 0`` (certified), ``False`` when ``lo >= 0``, ``None`` when the
        bounds straddle 0 (a borderline set within the tolerance).
    iterations : int
        Refinement steps taken.
    points : int
        Support points evaluated.
    seconds : float
    direction : (6,) float
        The unit direction with the lowest support value found: ``p(direction) = -lo``.
    """

    lo: float
    hi: float
    converged: bool
    force_closure: bool | None
    iterations: int
    points: int
    seconds: float
    direction: np.ndarray = field(repr=False, compare=False, default=None)

    def __iter__(self):
        yield self.lo
        yield self.hi

    @property
    def gap(self) -> float:
        return self.hi - self.lo


def _unit_rows(U: np.ndarray) -> np.ndarray:
    U = np.atleast_2d(np.asarray(U, dtype=float))
    norms = np.linalg.norm(U, axis=1, keepdims=True)
    return U[norms[:, 0] > 1e-300] / norms[norms[:, 0] > 1e-300]


def _cloud(rng: np.random.Generator, u: np.ndarray, scales) -> np.ndarray:
    """Unit directions ``u +- eps e_j`` around unit ``u``: (10 len(scales), 6).

    ``e_1..e_5`` is a random orthonormal basis of the tangent space at ``u``, drawn anew for
    every scale ``eps``: a cross-polytope of support points around the minimiser at every scale
    resolves the curved part of ``W`` there (chord depth ~ eps^2) without any refinement step.
    """
    blocks = []
    for eps in scales:
        A = np.column_stack([u, rng.standard_normal((6, 5))])
        Q, _ = np.linalg.qr(A)
        E = Q[:, 1:].T  # (5, 6), orthonormal and orthogonal to u
        blocks += [u + eps * E, u - eps * E]
    return _unit_rows(np.vstack(blocks)) if blocks else np.zeros((0, 6))


def min_norm_point(points: np.ndarray) -> np.ndarray:
    """A point of ``conv(points)`` nearest the origin (QP over convex weights): (N, 6) -> (6,).

    The weights are clipped and renormalised, so the result lies in the hull whatever the
    solver's accuracy: its norm is always a valid upper bound on the distance.
    """
    P = np.asarray(points, dtype=float)
    norms = np.linalg.norm(P, axis=1)
    best = P[np.argmin(norms)]
    if len(P) == 1:
        return best
    lam = cp.Variable(len(P), nonneg=True)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(P.T @ lam)), [cp.sum(lam) == 1])
    try:
        problem.solve(solver=SOLVER)
    except cp.error.SolverError:
        return best
    if lam.value is None:
        return best
    w = np.maximum(np.asarray(lam.value, dtype=float), 0.0)
    if not w.sum() > 0:
        return best
    x = (w / w.sum()) @ P
    return x if np.linalg.norm(x) < norms.min() else best


class _Evaluated:
    """Directions evaluated so far: the running lower bound and the support points."""

    def __init__(self, slots: WrenchSlots):
        self.slots = slots
        self.best = np.inf
        self.best_u = None
        self.points: list[np.ndarray] = []

    def add(self, U: np.ndarray):
        U = _unit_rows(U)
        if not len(U):
            return np.zeros(0), np.zeros((0, 6))
        values, points = self.slots.evaluate(U)
        k = int(np.argmin(values))
        if values[k] < self.best:
            self.best, self.best_u = float(values[k]), U[k]
        self.points.append(points)
        return values, points

    def all_points(self) -> np.ndarray:
        return np.vstack(self.points)


def polytope_bounds(
    slots_or_contact_set,
    direction=None,
    *,
    tol: float | None = None,
    options: PolytopeOptions = PolytopeOptions(),
    tolerances: Tolerances = DEFAULT_TOLERANCES,
) -> PolytopeBounds:
    """Bounds ``lo <= rho <= hi`` on rho(0, W) with ``hi - lo <= tol * max(1, |rho|)``.

    Parameters
    ----------
    slots_or_contact_set : WrenchSlots or ContactSet
    direction : (6,) float, optional
        A direction near the minimiser (e.g. IPOPT's ``u*``): the refinement starts around it.
        The bounds hold whatever it is; it only saves work.
    tol : float, optional
        Relative gap to reach; ``tolerances.certify`` (1e-6) when omitted.
    options : PolytopeOptions
    tolerances : Tolerances

    Returns
    -------
    PolytopeBounds
        Valid bounds even when the refinement hits ``options.max_iter`` (then ``converged`` is
        ``False`` and the gap is wider). Sets without interior get bounds around 0.

    Raises
    ------
    TypeError, ValueError
        Bad ``slots_or_contact_set``, ``direction`` or ``tol``.
    MethodError
        When the SOCP solver fails.
    """
    start_time = time.perf_counter()
    slots = as_slots(slots_or_contact_set)
    if tol is None:
        tol = tolerances.certify
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not tol > 0:
        raise ValueError(f"tol: must be a positive number, got {tol!r}")
    hints = []
    if direction is not None:
        u = as_vector(direction, "direction", 6)
        if np.linalg.norm(u) > 0:
            hints.append(u / np.linalg.norm(u))
    rng = np.random.default_rng(options.seed)
    found = ball_minimum(slots, tolerances)
    evaluated = _Evaluated(slots)
    if found.distance > 0:
        lo, hi, iterations = _outside(slots, found.direction, hints, tol, options, rng, evaluated)
    else:
        lo, hi, iterations = _inside(slots, found.direction, hints, tol, options, rng, evaluated)
    if lo > hi:  # roundoff of two exact bounds of the same number
        hi = lo
    converged = _done(lo, hi, tol)
    verdict = True if hi < 0 else (False if lo >= 0 else None)
    return PolytopeBounds(
        float(lo),
        float(hi),
        bool(converged),
        verdict,
        iterations,
        sum(len(p) for p in evaluated.points),
        time.perf_counter() - start_time,
        evaluated.best_u,
    )


def _done(lo: float, hi: float, tol: float) -> bool:
    return hi - lo <= tol * max(1.0, abs(lo), abs(hi))


def _outside(slots, u0, hints, tol, options, rng, evaluated):
    """The origin outside ``W``: lower bound from directions, upper from nearest hull points."""
    for u in [u0, *hints]:
        evaluated.add(np.vstack([u, _cloud(rng, u, options.scales)]))
    lo = -evaluated.best
    x = min_norm_point(evaluated.all_points())
    hi = float(np.linalg.norm(x))
    iterations = 0
    while not _done(lo, hi, tol) and iterations < options.max_iter:
        iterations += 1
        norm = float(np.linalg.norm(x))
        if not norm > 0:  # cannot happen when the SOCP proved the origin outside; roundoff guard
            break
        u = -x / norm
        evaluated.add(np.vstack([u, _cloud(rng, u, options.scales)]))
        lo = -evaluated.best
        x = min_norm_point(evaluated.all_points())
        hi = min(hi, float(np.linalg.norm(x)))
    return lo, hi, iterations


def _inside(slots, u0, hints, tol, options, rng, evaluated):
    """The origin in ``W`` (or on its boundary): inner polytope by qhull, refined at facets."""
    U = [np.eye(6), -np.eye(6), rng.standard_normal((options.samples, 6))]
    if np.linalg.norm(u0) > 0.5:
        U.append(u0[None, :])
    evaluated.add(np.vstack(U))
    # Cross-polytope clouds around the hints and the best direction of the samples.
    centres: list[np.ndarray] = []
    for u in [*hints, evaluated.best_u]:
        if all(np.linalg.norm(u - c) > RECENTRE for c in centres):
            centres.append(u)
            evaluated.add(np.vstack([u, _cloud(rng, u, options.scales)]))
    points = evaluated.all_points()
    scale = max(1.0, float(np.abs(points).max()))
    # Affine dimension of the support points: below 6, the set has no interior.
    centred = points - points.mean(axis=0)
    _, sv, Vt = np.linalg.svd(centred, full_matrices=False)
    flat = sv <= 1e-10 * scale  # at least 12 points (+-e_k): sv has 6 entries
    if flat.any():
        normals = Vt[flat]
        evaluated.add(np.vstack([normals, -normals]))
        return _no_interior(evaluated)
    hull = _hull(points, rng)
    if hull is None:
        return _no_interior(evaluated)
    margin = QHULL_MARGIN * scale
    lo, hi, iterations = -evaluated.best, np.inf, 0
    while True:
        offsets = -hull.equations[:, -1]  # n . x <= b for x in Q, n unit
        normals = hull.equations[:, :-1]
        d_in = float(offsets.min()) - margin
        lo = -evaluated.best
        hi = -d_in if d_in > 0 else float(np.linalg.norm(min_norm_point(hull.points)))
        if (
            _done(lo, hi, tol)
            or iterations >= options.max_iter
            or len(hull.vertices) >= options.max_points
            or len(offsets) >= options.max_facets
        ):
            return lo, hi, iterations
        iterations += 1
        # Facets that may still hide a lower support value: b < min p - (what tol allows).
        slack = 0.5 * tol * max(1.0, abs(lo), abs(hi))
        candidates = np.flatnonzero(offsets < evaluated.best - slack)
        candidates = candidates[np.argsort(offsets[candidates], kind="stable")]
        picked = _spread(normals[candidates], options.batch)
        U = normals[candidates[picked]]
        values, new_points = evaluated.add(U)
        beyond = values > offsets[candidates[picked]] + 10 * margin
        if not beyond.any():
            # Every limiting facet touches W (within roundoff): nothing left to refine.
            return -evaluated.best, hi, iterations
        new_points = [new_points[beyond]]
        u = evaluated.best_u
        if all(np.linalg.norm(u - c) > RECENTRE for c in centres):
            # A lower support value far from every cloud: resolve the set around it too.
            centres.append(u)
            new_points.append(evaluated.add(_cloud(rng, u, options.scales))[1])
        hull = _hull(np.vstack([hull.points, *new_points]), rng)
        if hull is None:
            return lo, hi, iterations


def _hull(points: np.ndarray, rng: np.random.Generator) -> ConvexHull | None:
    """qhull of ``points`` (a subset of ``W``), or ``None`` when qhull gives up (flat input).

    Never qhull's incremental mode: a precision error there can end the process (scipy issue
    #4974); never ``Q12`` (its wide merges give wrong facets) nor ``QJ`` (joggled facets belong
    to other points). When qhull reports a precision error, every point is instead pulled
    towards the origin by its own random factor in ``[1 - 1e-9, 1]``: the points stay in ``W``
    (which contains the origin here), so the bound stays exact, and are in general position.
    """
    # Exact duplicates (support points at a kink of p repeat a vertex) only cost time.
    points = np.unique(points, axis=0)
    for attempt in range(2):
        if attempt:
            points = points * (1.0 - SHRINK * rng.random((len(points), 1)))
        try:
            return ConvexHull(points)
        except (QhullError, ValueError):
            continue
    return None


def _spread(normals: np.ndarray, count: int) -> np.ndarray:
    """Indices of up to ``count`` rows spread over the sphere, the first row first.

    Greedy farthest-point selection: the nearest facet (row 0) and then the facets whose normals
    are farthest from every pick, so that one step refines every region with deep facets
    instead of crowding the one near the minimum. Duplicates (qhull repeats merged facets) are
    never picked twice.
    """
    if not len(normals):
        return np.zeros(0, dtype=int)
    picked = [0]
    gap = np.linalg.norm(normals - normals[0], axis=1)
    while len(picked) < count:
        i = int(np.argmax(gap))
        if gap[i] < 1e-9:
            break
        picked.append(i)
        gap = np.minimum(gap, np.linalg.norm(normals - normals[i], axis=1))
    return np.asarray(picked, dtype=int)


def _no_interior(evaluated: _Evaluated):
    """The set lies in a hyperplane through (about) the origin: rho >= 0 and near 0."""
    lo = -evaluated.best
    x = min_norm_point(evaluated.all_points())
    hi = float(np.linalg.norm(x))
    return lo, hi, 0
