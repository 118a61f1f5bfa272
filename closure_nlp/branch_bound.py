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

Support points. Besides the cell's own eleven, every cell may combine the support points of a
tiny cloud around the incumbent (they hold every piece of ``p`` that meets at the minimum), and a
cell that survives near the minimum gets those of its corners and of a cloud around its lowest
sample, with a longer search of the weights.

Incumbent. Every evaluated direction gives an upper bound ``p(u) >= min p``; the lowest is the
incumbent. When a cell's samples lower it, an optional local solver (``polish``) runs from there:
samples approach a minimum only to first order in the cell size, and with an incumbent that far
above the minimum whole neighbourhoods of it survive (an optimised lamp placement whose seed
search missed the global basin by 0.26%: 18.3 s and unconverged without, 0.9 s with). Cells
whose bound reaches the incumbent minus the allowed gap are dropped; the others are halved along
their widest coordinate, all at once in numpy, until none is left or the budget is spent. The
minimum over the sphere then lies in ``[min over dropped and live cells of their bounds,
incumbent]``.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .validation import is_whole
from .wrenches import WrenchSlots

MAX_POLISH = 8  # local solves per branch and bound: each a few ms; the first ones do the work
# Per unit of wrench scale: covers the float64 roundoff of support values and support points
# (a few ulps of sums of m terms), far below any tolerance of the package.
ROUNDOFF = 1e-13
_FREE = np.array([[j for j in range(6) if j != k] for k in range(6)])  # (6, 5)
_CORNERS = np.array(np.meshgrid(*[[-1.0, 1.0]] * 5, indexing="ij")).reshape(5, -1).T  # (32, 5)
# Directions x rows per support evaluation: ~6 MB per temporary. 2**20 held 50 MB per temporary:
# a stepped-shaft placement certificate (152k cells) peaked 60 MB higher and ran 1.3x slower.
EVALUATION_CHUNK = 2**17
EXACT_CHUNK = 512  # cells per batch of exact bounds: a few tens of MB of tableaux
CELL_CHUNK = 2048  # cells bounded at once: ~40 MB of corners, bounds and their temporaries
CELLS_PER_ROUND = 128  # 1.1-1.7x faster than one halving per round (bench certify, process time)
_AXES = np.vstack([np.zeros(5), np.eye(5), -np.eye(5)])  # (11, 5): centre and the axes' ends


@dataclass(frozen=True)
class BranchBoundOptions:
    """Budget and shape of the search.

    Attributes
    ----------
    initial_splits : int
        Halvings of every free coordinate of each cube face before the first bound (1: 32 cells
        per face, 384 in all).
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
        throughout; the shaft's were 9,000 at 40k cells, then fell. A continuum of minima (two
        opposite soft fingers) grows past both limits at 70k-90k cells and would never
        converge. ``max_cells`` or less: no extension.
    max_rounds : int
        Rounds of splitting (each halves every live cell once).
    fw_steps : int
        Frank-Wolfe steps that choose the convex weights of a cell's support points.
    refine_below : float
        Angular radius under which a cell that survives its first bound gets more support
        points (its corners and a small cloud around its lowest sample) and a longer search of
        their weights: near the minimum, where the kinks of ``p`` meet.
    stop_below_zero : bool
        Stop, unconverged, at the first direction with ``p < 0``: the origin is then outside the
        set, where :mod:`closure_nlp.nearest_point` is exact and much faster.
    """

    initial_splits: int = 1
    max_cells: int = 40_000
    extended_cells: int = 400_000
    extension_alive: int = 5_000
    max_rounds: int = 200
    fw_steps: int = 12
    refine_below: float = 0.4  # 0.05 -> 0.4: eligible lamp sets 2.3x faster (CPU), others 0.9-1.15x
    stop_below_zero: bool = True

    def __post_init__(self) -> None:
        names = ("initial_splits", "max_cells", "extended_cells", "extension_alive", "max_rounds")
        for name in (*names, "fw_steps"):
            value = getattr(self, name)
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
        Cells bounded.
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


def _face_points(axis, sign, y):
    """Points of the cube faces: axis (N,), sign (N,), y (N, ..., 5) -> (N, ..., 6)."""
    shape = y.shape[:-1]
    expand = (-1,) + (1,) * (len(shape) - 1)
    idx = np.broadcast_to(axis.reshape(expand), shape)
    x = np.empty((*shape, 6))
    np.put_along_axis(x, _FREE[idx], y, axis=-1)
    s = np.broadcast_to(sign.reshape(expand), shape)[..., None].astype(float)
    np.put_along_axis(x, idx[..., None], s, axis=-1)
    return x


def _directions(axis, sign, y, metric):
    """Unit directions of cube-face points mapped by the diagonal ``metric``:
    axis (N,), sign (N,), y (N, ..., 5) -> (N, ..., 6)."""
    x = _face_points(axis, sign, y) * metric
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _cells(axis, sign, lo, hi, metric):
    """What the bounds need of each cell: the cone of ``metric * x`` over the box's points ``x``.

    Returns the cap's centre (N, 6) and angular radius (N,), the cell's 32 corners (N, 32, 6)
    and their unit directions, and a lower bound on ``|x|`` over the cell's cross-section (N,).
    A linear map keeps the cross-section a convex polytope with the mapped corners as vertices,
    so every bound of :func:`_box_bound` holds as on the cube's faces.
    """
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    c = _directions(axis, sign, mid, metric)
    corners = _face_points(axis, sign, mid[:, None, :] + half[:, None, :] * _CORNERS[None])
    corners = corners * metric
    unit = corners / np.linalg.norm(corners, axis=2, keepdims=True)
    cos = np.einsum("nkr,nr->nk", unit, c).min(axis=1)
    nearest = np.sqrt(1.0 + np.sum(np.maximum(np.maximum(lo, -hi), 0.0) ** 2, axis=1))
    return c, np.arccos(np.clip(cos, -1.0, 1.0)), corners, unit, nearest * metric.min()


def _box_bound(W, corners, corners_unit, nearest):
    """Lower bounds of ``w . u`` over each cell, for wrenches W (N, K, 6) -> (N, K).

    Where ``w . x >= 0`` at every corner ``x`` of the box (on the cube face), ``w . x / |x|`` is
    quasi-concave on the box, so its minimum is at a corner: exact. Otherwise the most negative
    ``w . x`` over the corners divided by the smallest ``|x|`` on the box.
    """
    Wt = W.transpose(0, 2, 1)  # batched matmul: 9x faster than the einsum of these shapes
    raw = (corners @ Wt).min(axis=1)
    unit = (corners_unit @ Wt).min(axis=1)
    return np.where(raw >= 0, unit, raw / nearest[:, None])


def _frank_wolfe(points, c, delta, steps):
    """Convex weights of ``points`` (N, K, 6) for a high cap bound, and that bound: (N, K), (N,).

    On a cap of centre ``c`` and radius ``delta``, ``min wbar . u = cos(delta) wbar . c -
    sin(delta) |wbar_perp|`` (``|wbar| cos(theta + delta)``), concave in the weights: a few
    Frank-Wolfe steps with exact line search raise it; every iterate is a valid bound. Weights
    that cancel the tangential parts make it second-order accurate at a kink of ``p``.
    """
    cd, sd = np.cos(delta), np.sin(delta)
    a = np.einsum("nkr,nr->nk", points, c)
    B = points - a[..., None] * c[:, None, :]
    single = cd[:, None] * a - sd[:, None] * np.linalg.norm(B, axis=2)
    j = np.argmax(single, axis=1)
    rows = np.arange(len(points))
    lam = np.zeros(points.shape[:2])
    lam[rows, j] = 1.0
    lam_a = a[rows, j]
    v = B[rows, j].copy()
    for _ in range(steps):
        nv = np.linalg.norm(v, axis=1)
        unit = v / np.where(nv > 0, nv, 1.0)[:, None]
        grad = cd[:, None] * a - sd[:, None] * np.einsum("nkr,nr->nk", B, unit)
        j = np.argmax(grad, axis=1)
        beta = cd * (a[rows, j] - lam_a)
        dv = B[rows, j] - v
        A = np.einsum("nr,nr->n", dv, dv)
        b = np.einsum("nr,nr->n", v, dv)
        gamma = _line_search(beta, sd, A, b, nv**2)
        lam *= (1.0 - gamma)[:, None]
        lam[rows, j] += gamma
        lam_a = lam_a + gamma * (a[rows, j] - lam_a)
        v = v + gamma[:, None] * dv
    a_bar, b_bar = lam_a, np.linalg.norm(v, axis=1)
    theta = np.arctan2(b_bar, a_bar)
    # Past the antipode the cap's farthest point is -wbar itself.
    cap = np.where(theta + delta > np.pi, -np.hypot(a_bar, b_bar), cd * a_bar - sd * b_bar)
    return lam, cap


def _anchor_cloud(u, scales=(1e-3, 1e-5, 1e-7)):
    """``u`` and ``u +- eps e_j`` along an orthonormal basis of its tangent space: (1 + 10 k, 6).

    Their support points hold every piece of ``p`` that meets at ``u`` (a kink's subgradients),
    so convex combinations of them reach the subgradient parallel to ``u`` at a minimum.
    """
    return _anchor_clouds(np.asarray(u)[None], np.asarray(scales, dtype=float)[None])[0]


def _anchor_clouds(U: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """:func:`_anchor_cloud` of each row of ``U`` (N, 6), with its own scales (N, k)."""
    N = len(U)
    Q, _ = np.linalg.qr(
        np.concatenate([U[:, :, None], np.broadcast_to(np.eye(6), (N, 6, 6))], axis=2)
    )
    E = np.swapaxes(Q[:, :, 1:6], 1, 2)  # (N, 5, 6): the tangent basis
    steps = scales[:, :, None, None] * np.array([1.0, -1.0])[None, None, :, None]  # (N, k, 2, 1)
    moved = U[:, None, None, None, :] + steps[..., None] * E[:, None, None, :, :]
    cloud = np.concatenate([U[:, None, :], moved.reshape(N, -1, 6)], axis=1)
    return cloud / np.linalg.norm(cloud, axis=2, keepdims=True)


def _game_weights(M: np.ndarray, max_pivots: int = 300) -> np.ndarray:
    """Convex weights ``lam`` maximising ``min_c (M lam)_c``: (N, C, K) -> (N, K).

    The value of a small matrix game, as ``N`` linear programs solved at once by a dense
    primal simplex (Dantzig's rule): ``max t`` s.t. ``t <= (M lam)_c``, ``sum lam = 1``,
    ``lam >= 0``. Every iterate is feasible, so weights from a capped run still give a valid
    (if looser) bound; callers recompute the bound from the weights, in float64. So the
    tableau is float32 (half the memory traffic: 1.5x faster certificates of optimised
    placements), on each game scaled to [0, 1]: the weights reach the value within about 1e-6
    of the spread of the game's entries, which is tiny in the small cells near a minimum.
    """
    N, C, K = M.shape
    Mp = M - M.min(axis=(1, 2), keepdims=True)  # >= 0, so t >= 0 at the optimum
    span = Mp.max(axis=(1, 2), keepdims=True)
    Mp = Mp / np.where(span > 0, span, 1.0)  # in [0, 1]: the weights are those of M
    j0 = np.argmax(Mp.min(axis=1), axis=1)  # the best single column
    rows = np.arange(N)
    V = K + 1 + C  # columns: lam, t, slacks
    T = np.zeros((N, C + 2, V + 1), dtype=np.float32)
    # Row c: -M' lam + t + s_c = 0, with lam_j0 eliminated through the sum row.
    pivot_col = Mp[rows, :, j0]  # (N, C)
    T[:, :C, :K] = -Mp + pivot_col[:, :, None]
    T[:, :C, K] = 1.0
    T[:, :C, K + 1 : K + 1 + C] = np.eye(C)
    T[:, :C, -1] = pivot_col
    T[:, C, :K] = 1.0  # sum row
    T[:, C, -1] = 1.0
    T[:, C + 1, K] = -1.0  # objective row: maximise t
    basis = np.empty((N, C + 1), dtype=int)
    basis[:, :C] = K + 1 + np.arange(C)
    basis[:, C] = j0
    eps = 1e-6
    # Rows at their optimum leave the working arrays: a finished program never pivots again.
    work = rows
    done_T, done_basis = np.empty_like(T), np.empty_like(basis)
    for _ in range(max_pivots):
        obj = T[:, C + 1, :V]
        j = np.argmin(obj, axis=1)
        here = np.arange(len(work))
        col = T[here, : C + 1, j]  # (n, C + 1)
        rhs = T[:, : C + 1, -1]
        ratio = np.where(col > eps, rhs / np.where(col > eps, col, 1.0), np.inf)
        i = np.argmin(ratio, axis=1)
        active = (obj[here, j] < -eps) & np.isfinite(ratio[here, i])
        if not active.all():
            done_T[work[~active]], done_basis[work[~active]] = T[~active], basis[~active]
            work, T, basis = work[active], T[active], basis[active]
            i, j = i[active], j[active]
            if not len(work):
                break
        here = np.arange(len(work))
        prow = T[here, i, :] / T[here, i, j][:, None]
        T -= T[here, :, j][:, :, None] * prow[:, None, :]
        T[here, i, :] = prow
        basis[here, i] = j
    done_T[work], done_basis[work] = T, basis
    T, basis = done_T, done_basis
    lam = np.zeros((N, K))
    values = T[:, : C + 1, -1]
    is_lam = basis < K
    r, k = np.nonzero(is_lam)
    lam[r, basis[r, k]] = np.maximum(values[r, k], 0.0)
    total = lam.sum(axis=1, keepdims=True)
    lam = np.where(total > 0, lam / np.where(total > 0, total, 1.0), 0.0)
    lam[total[:, 0] <= 0, 0] = 1.0
    return lam


def _exact_bound(points, corners, corners_unit, nearest):
    """The corner bound of the best convex combination of each cell's points: (N,).

    In chunks of :data:`EXACT_CHUNK` cells: each cell's game is solved on its own, so the
    bounds are the same, and the simplex's tableaux (about 60 KB per cell with their
    temporaries) stay small; all cells at once took a fixture-study task from 142 to 450 MiB.
    """
    out = np.empty(len(points))
    for part in _chunks(len(points), EXACT_CHUNK):
        lam = _game_weights(corners_unit[part] @ points[part].transpose(0, 2, 1))
        wbar = lam[:, None, :] @ points[part]  # (n, 1, 6)
        out[part] = _box_bound(wbar, corners[part], corners_unit[part], nearest[part])[:, 0]
    return out


def _line_search(beta, s, A, b, C):
    """argmax over [0, 1] of ``beta g - s sqrt(A g^2 + 2 b g + C)`` (concave), batched.

    Stationary point: with ``t = A g + b`` and ``D = A C - b^2 >= 0``, ``t sqrt(A) / sqrt(t^2 +
    D) = r = beta / s``, solvable when ``r^2 < A``; otherwise the function is monotone.
    """
    D = np.maximum(A * C - b * b, 0.0)
    safe_A = np.where(A > 0, A, 1.0)
    r = beta / np.where(s > 0, s, 1e-300)
    room = safe_A - r * r
    t = np.sign(r) * np.sqrt(r * r * D / np.where(room > 0, room, 1.0))
    g = np.where(room > 0, (t - b) / safe_A, np.where(beta > 0, 1.0, 0.0))
    g = np.where(A > 0, g, 0.0)
    return np.clip(np.nan_to_num(g, nan=0.0), 0.0, 1.0)


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
    polish : callable, optional
        ``polish(u) -> (6,)``: a local minimiser of ``p`` started at ``u``, run (at most
        :data:`MAX_POLISH` times) from the incumbent whenever samples lowered it by more than
        the gap. Its direction only enters as an evaluated sample, so any answer is safe.

    The search stops early, unconverged, when it finds ``p(u) < 0`` while ``stop_below_zero``:
    the origin is then outside the set, where :mod:`closure_nlp.nearest_point` is exact.
    """
    start = time.perf_counter()
    metric = np.ones(6) if metric is None else np.asarray(metric, dtype=float)
    margin = ROUNDOFF * max(slots.row_scales()) * max(1, slots.m)
    state = _Incumbent(slots)
    if incumbent is not None:
        state.consider(np.asarray(incumbent, dtype=float)[None])
    axis, sign, lo, hi = _initial_cells(options.initial_splits)
    lower_dropped = np.inf
    cells = rounds = polished = 0
    polished_at = state.value
    converged = False
    alive_at_budget = None  # cells alive after the round that reached max_cells
    while True:
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        U = _directions(axis, sign, mid[:, None, :] + half[:, None, :] * _AXES[None], metric)
        values, points = state.consider(U.reshape(-1, 6), with_values=True)
        values, points = values.reshape(len(lo), -1), points.reshape(len(lo), -1, 6)
        cells += len(lo)
        rounds += 1
        if polish is not None and polished < MAX_POLISH and state.value < polished_at - gap:
            state.consider(np.asarray(polish(state.u), dtype=float)[None])
            polished, polished_at = polished + 1, state.value
        if options.stop_below_zero and state.value < -margin:
            lower = -np.inf
            break
        target = state.value - gap
        anchors = functools.cache(state.anchors)  # taken once per round, when first needed
        # In chunks of cells: a round's corners and bounds hold ~20 KB per cell, and rounds of
        # 20k cells took a study worker's peak up by hundreds of MB. Every cell is bounded on
        # its own against the round's target, so the bounds do not depend on the chunking.
        here = _Round(state, anchors, target, margin, metric, options)
        bound = np.concatenate(
            [
                here.bounds(*(a[s] for a in (axis, sign, lo, hi, U, values, points)))
                for s in _chunks(len(lo), CELL_CHUNK)
            ]
        )
        live = bound < target
        if (~live).any():
            lower_dropped = min(lower_dropped, float(bound[~live].min()))
        if not live.any():
            converged = True
            lower = lower_dropped
            break
        alive = int(live.sum())
        if cells >= options.max_cells and alive_at_budget is None:
            alive_at_budget = alive
        extending = alive_at_budget is not None and alive <= max(
            options.extension_alive, 2 * alive_at_budget
        )
        if (
            rounds >= options.max_rounds
            or cells >= max(options.max_cells, options.extended_cells)
            or (cells >= options.max_cells and not extending)
        ):
            lower = min(lower_dropped, float(bound[live].min()))
            break
        axis, sign, lo, hi = _halve(axis[live], sign[live], lo[live], hi[live])
    return SphereBounds(
        min(lower, state.value),
        state.value,
        state.u,
        converged,
        cells,
        state.evaluations,
        rounds,
        time.perf_counter() - start,
    )


def _chunks(n: int, size: int):
    """Slices of ``range(n)`` of at most ``size`` items."""
    return [slice(at, at + size) for at in range(0, n, size)]


class _Round(NamedTuple):
    """What bounds the cells of one round: the incumbent, its anchors (taken when first
    needed), the target a cell must beat to be dropped, the roundoff margin, the metric and
    the options."""

    state: _Incumbent
    anchors: Callable[[], np.ndarray]
    target: float
    margin: float
    metric: np.ndarray
    options: BranchBoundOptions

    def bounds(self, axis, sign, lo, hi, U, values, points) -> np.ndarray:
        """Lower bounds of ``p`` over cells, from their samples ``U`` (N, 11, 6), ``values``
        and support ``points``: three bounds, each for the cells the cheaper one left below
        the target. Single support points (exact on a linear piece of p), Frank-Wolfe
        combinations with the anchors (second order at a kink, approximately), the exact best
        combination of more points (small cells)."""
        state, target, margin, options = self.state, self.target, self.margin, self.options
        c, delta, corners, corners_unit, nearest = _cells(axis, sign, lo, hi, self.metric)
        bound = _box_bound(points, corners, corners_unit, nearest).max(axis=1) - margin
        k = np.flatnonzero(bound < target)
        if len(k):
            anchor_points = self.anchors()
            pool = np.concatenate(
                [points[k], np.broadcast_to(anchor_points, (len(k), *anchor_points.shape))], axis=1
            )
            lam, cap = _frank_wolfe(pool, c[k], delta[k], options.fw_steps)
            wbar = lam[:, None, :] @ pool
            box = _box_bound(wbar, corners[k], corners_unit[k], nearest[k])[:, 0]
            bound[k] = np.maximum(bound[k], np.maximum(cap, box) - margin)
            still = bound[k] < target
            k, pool = k[still], pool[still]
        if len(k):
            k_small = delta[k] < options.refine_below
            k, pool = k[k_small], pool[k_small]
        if len(k):
            # More support points of each small surviving cell: at its corners (both sides of
            # any kink crossing it) and a small cloud around its lowest sample (the pieces of p
            # meeting there), and their best combination, exactly.
            lowest = U[k, np.argmin(values[k], axis=1)]
            clouds = _anchor_clouds(lowest, np.outer(delta[k], [0.25, 0.01]))
            more = np.concatenate([corners_unit[k], clouds], axis=1)
            local = state.consider(more.reshape(-1, 6)).reshape(len(k), -1, 6)
            exact = _exact_bound(
                np.concatenate([pool, local], axis=1), corners[k], corners_unit[k], nearest[k]
            )
            bound[k] = np.maximum(bound[k], exact - margin)
        return bound


class _Incumbent:
    """The lowest support value evaluated so far, and support points near its direction."""

    def __init__(self, slots: WrenchSlots):
        self.slots = slots
        self.value, self.u = np.inf, None
        self.evaluations = 0
        self._anchored_at, self._anchors = None, None

    def consider(self, U: np.ndarray, with_values: bool = False):
        """Evaluate directions (N, 6) (normalised here); returns their support points."""
        U = U / np.linalg.norm(U, axis=1, keepdims=True)
        # In chunks: support evaluation holds (directions x rows x 6) temporaries, which for all
        # live cells of an element set at once took a study worker's RSS past 1.5 GB.
        chunk = max(1, EVALUATION_CHUNK // max(1, len(self.slots.G)))
        parts = [self.slots.evaluate(U[part]) for part in _chunks(len(U), chunk)]
        values = np.concatenate([v for v, _ in parts])
        points = np.concatenate([p for _, p in parts])
        self.evaluations += len(U)
        k = int(np.argmin(values))
        if values[k] < self.value:
            self.value, self.u = float(values[k]), U[k].copy()
        return (values, points) if with_values else points

    def anchors(self) -> np.ndarray:
        """Support points of a tiny cloud around the incumbent (renewed when it moves)."""
        if self._anchored_at is None or not np.array_equal(self._anchored_at, self.u):
            self._anchored_at = self.u
            self._anchors = self.consider(_anchor_cloud(self.u))
        return self._anchors


def _initial_cells(splits: int):
    """Every cube face cut into ``2^(5 splits)`` boxes: axis, sign, lo, hi."""
    n = 2**splits
    edges = np.linspace(-1.0, 1.0, n + 1)
    grid = np.array(np.meshgrid(*[np.arange(n)] * 5, indexing="ij")).reshape(5, -1).T
    axis = np.repeat(np.arange(6), 2 * len(grid))
    sign = np.tile(np.repeat([1.0, -1.0], len(grid)), 6)
    return axis, sign, np.tile(edges[grid], (12, 1)), np.tile(edges[grid + 1], (12, 1))


def _halve(axis, sign, lo, hi, cells_per_round: int = CELLS_PER_ROUND):
    """Every cell cut in two across its widest coordinate; while few cells live, each is cut
    across several coordinates at once (``2^k`` children, ``k <= 5``), so that a round holds
    about ``cells_per_round``: fewer rounds, whose numpy overhead dominates small batches."""
    cuts = 1
    while cuts < 5 and len(lo) * 2 ** (cuts + 1) <= cells_per_round:
        cuts += 1
    for _ in range(cuts):
        widest = np.argmax(hi - lo, axis=1)
        rows = np.arange(len(lo))
        cut = 0.5 * (lo[rows, widest] + hi[rows, widest])
        lo2, hi2 = lo.copy(), hi.copy()
        hi[rows, widest] = cut
        lo2[rows, widest] = cut
        axis, sign = np.concatenate([axis, axis]), np.concatenate([sign, sign])
        lo, hi = np.vstack([lo, lo2]), np.vstack([hi, hi2])
    return axis, sign, lo, hi
