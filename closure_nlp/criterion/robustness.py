"""Verdicts within the model's accuracy: force closure for every contact set near the file's.

A model or contact-set file may say how far the real part's contact points and normals may lie
from the file's (:class:`ModelTolerance`: ``position``, a length, and ``normal_deg``, an angle).
A contact set is *robust* when every set whose contacts lie within those tolerances of its own
is force closure. :func:`support_shift` bounds how far the support function can move; robust iff
``hi + shift < 0`` (``hi`` the certified upper bound of rho), beyond the certificate's tolerance.

The bound (proof)
-----------------
Contact ``i`` has wrench set ``W_i = G_i F_i`` with ``G_i = [[R, 0], [s [x]_x R, s n]]`` (``R =
[n, o, t]`` its frame, ``x`` its position about the reference point, ``s`` the torque scale) and
``F_i`` a set of local forces ``f = (g, f_s)``, ``g = (f_n, f_o, f_t)``, with ``0 <= f_n <=
f_max``, ``|(f_o, f_t)| <= mu f_n`` and ``|f_s| <= mu_s f_n`` (every contact type: FPC has
``mu = mu_s = 0``, PCwF ``mu_s = 0``; SFCl's and SFCe's sets lie inside both bounds). So
``|g| <= f_max sqrt(1 + mu^2)`` and ``|f_s| <= mu_s f_max``. ``F_i`` is invariant under rotations
about the normal, so a contact at ``x'`` with normal ``n'`` has the set ``G' F_i`` with frame
``R' = Q R``, ``Q`` the rotation by the angle ``a <= theta`` between ``n`` and ``n'`` about
``n x n'``: ``|R' - R| = |Q - I| = 2 sin(a / 2) <= eps := 2 sin(theta / 2)``.

For a unit ``u = (u_f, u_t)`` and ``f`` in ``F_i``,

    u.(G' - G) f = u_f.(R' - R) g + s u_t.((x' - x) x R' g + x x (R' - R) g) + s f_s u_t.(n' - n)

so ``|u.(G' - G) f| <= |u_f| A + |u_t| B <= sqrt(A^2 + B^2)`` (Cauchy-Schwarz, ``|u_f|^2 +
|u_t|^2 = 1``) with ``A = eps |g|max`` and ``B = s (|g|max (delta + |x| eps) + mu_s f_max
eps)``. Support functions of ``G F`` and ``G' F`` then differ by at most ``Delta_i = sqrt(A^2 +
B^2)`` in every direction. An element slot's value is the max over its vertex rows, so it moves
by at most the largest row's ``Delta``. ``p = max over non-empty subsets S of sum_{i in S} P_i``
is a max of functions that are 1-Lipschitz in the l1 norm of ``P``, so ``|p' - p| <= sum_i
Delta_i`` in every direction, and ``min_u p' >= min_u p - sum_i Delta_i = -rho - shift``: every
perturbed set is force closure when ``-hi - shift > 0``.

``|x|`` and ``s`` are read from the grasp matrices themselves: ``|G[3:, :3]|_F = s sqrt(2) |x|``
(the cross products with an orthonormal frame) and ``|G[3:, 3]| = s``.
"""

from __future__ import annotations

import numpy as np

from closure_nlp.contact.accuracy import NO_TOLERANCE, ModelTolerance, tolerance_from_dict
from closure_nlp.contact.wrenches import WrenchSlots, as_slots


def has_tolerance(tolerance) -> bool:
    """Whether ``tolerance`` (one :class:`ModelTolerance`, or one per slot) lets anything move."""
    if isinstance(tolerance, ModelTolerance):
        return bool(tolerance)
    return any(bool(t) for t in tolerance)


def _per_row(slots: WrenchSlots, tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Position tolerance and ``2 sin(theta / 2)`` of every row (K,): one tolerance for all, or
    one per slot (its rows share it)."""
    if isinstance(tolerance, ModelTolerance):
        tolerance = (tolerance,) * slots.m
    if len(tolerance) != slots.m:
        raise ValueError(f"tolerance: expected one per slot ({slots.m}), got {len(tolerance)}")
    counts = slots.rows_per_slot
    position = np.repeat([t.position for t in tolerance], counts)
    degrees = np.repeat([t.normal_deg for t in tolerance], counts)
    return position, 2.0 * np.sin(np.radians(degrees) / 2.0)


def row_shifts(slots: WrenchSlots, tolerance) -> np.ndarray:
    """``Delta`` of every row: the most its support value can move (K,). ``tolerance``: one
    :class:`ModelTolerance` for every slot, or a sequence of one per slot."""
    position, eps = _per_row(slots, tolerance)
    G = slots.G
    s = np.linalg.norm(G[:, 3:, 3], axis=1)  # the torque scale
    sx = np.linalg.norm(G[:, 3:, :3], axis=(1, 2)) / np.sqrt(2.0)  # s |x|
    mu2 = slots.pieces[:, :, 1].max(axis=1)
    mu_s = np.sqrt(slots.pieces[:, :, 3].max(axis=1))
    g = slots.f_max * np.sqrt(1.0 + mu2)
    A = eps * g
    B = g * (s * position + sx * eps) + s * mu_s * slots.f_max * eps
    return np.hypot(A, B)


def support_shift(slots, tolerance: ModelTolerance) -> float:
    """Sum over slots of the largest row shift: no set within ``tolerance`` of ``slots`` (a
    :class:`WrenchSlots` or a contact set) has a support value further than this from theirs,
    in any direction."""
    slots = as_slots(slots)
    if not has_tolerance(tolerance):
        return 0.0
    shifts = row_shifts(slots, tolerance)
    return float(np.maximum.reduceat(shifts, slots.starts).sum())


def is_robust(result, shift: float, unit: float, tolerances) -> bool:
    """Robust force closure: ``hi + shift`` below zero by more than the certificate's tolerance
    (``force_closure`` alone when ``shift`` is 0)."""
    closure = bool(getattr(result, "force_closure", getattr(result, "eligible", False)))
    if not closure:
        return False
    if shift == 0.0:
        return True
    bounds = result.bounds
    if bounds is None:
        return False
    return bounds[1] + shift < -tolerances.certify * unit


def with_robustness(result, slots: WrenchSlots, tolerance: ModelTolerance, tolerances):
    """``result`` (any certified result with ``robust`` and ``shift`` fields) with its robust
    verdict under ``tolerance``; unchanged without a tolerance."""
    from dataclasses import replace

    from closure_nlp.criterion.certificate import tolerance_unit

    if not has_tolerance(tolerance) or result.bounds is None:
        return result
    shift = support_shift(slots, tolerance)
    robust = is_robust(result, shift, tolerance_unit(slots), tolerances)
    return replace(result, robust=robust, shift=shift)


__all__ = [
    "has_tolerance",
    "with_robustness",
    "ModelTolerance",
    "NO_TOLERANCE",
    "is_robust",
    "row_shifts",
    "support_shift",
    "tolerance_from_dict",
]
