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


def robust_value(value: float, shift: float) -> float:
    """What selection, placement and plans steer by: rho (or rho_hat, the search's value or the
    certified ``hi``) plus the support shift within the tolerance, so that of two sets the one
    with more capacity left within the tolerance wins; rho itself without a tolerance (shift
    0). Certified (``hi + shift``) it is ``robust_rho``."""
    return float(value) + float(shift)


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


def _bisect(robust_at, steps: int = 60) -> float:
    """The largest factor in [0, 1] at which ``robust_at(factor)`` holds, to ``2**-steps``
    (``robust_at`` holds at 0, fails at 1 and is monotone: shifts grow with the tolerance)."""
    lo, hi = 0.0, 1.0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if robust_at(mid) else (lo, mid)
    return lo


def _scaled(tolerance: ModelTolerance, factor: float) -> ModelTolerance:
    return ModelTolerance(tolerance.position * factor, tolerance.normal_deg * factor)


def to_be_robust(contacts, bounds, tolerance=None, tolerances=None) -> dict | None:
    """What would make a contact set that is force closure but not robust within its
    tolerance robust: None when it is robust, has no tolerance or is not force closure (no
    tolerance helps then).

    Robust means ``hi + shift < -certify * unit`` (:func:`is_robust`), and the shift grows with
    every tolerance, so the largest factor on them that keeps it is found by bisection on the
    certified ``hi``: ``factor``, the share of every contact's tolerance at which the set would
    be robust, and per contact its ``shift`` (what its tolerance costs) and the ``factor`` (and
    ``tolerance``) its own tolerance alone would have to shrink to, the others' kept (None when
    shrinking it alone cannot do); with one tolerance for every contact, ``tolerance_all`` is
    that tolerance times ``factor``. ``costliest`` is the contact whose tolerance costs most.
    ``tolerance``: default the contact set's own (one, or one per contact)."""
    from closure_nlp.base.tolerances import DEFAULT_TOLERANCES
    from closure_nlp.criterion.certificate import tolerance_unit

    tolerances = tolerances or DEFAULT_TOLERANCES
    slots = as_slots(contacts)
    if tolerance is None:
        tolerance = contacts.tolerance
    if bounds is None or not has_tolerance(tolerance):
        return None
    if isinstance(tolerance, ModelTolerance):
        tolerance = (tolerance,) * slots.m
    need = -float(bounds[1]) - tolerances.certify * tolerance_unit(slots)
    costs = np.maximum.reduceat(row_shifts(slots, tolerance), slots.starts)
    if need <= 0.0 or costs.sum() < need:  # not force closure, or robust already
        return None

    def robust_with(shrunk) -> bool:
        return float(np.maximum.reduceat(row_shifts(slots, shrunk), slots.starts).sum()) < need

    factor = _bisect(lambda f: robust_with([_scaled(t, f) for t in tolerance]))
    entries = []
    for i, own in enumerate(tolerance):
        alone = None
        if own and costs.sum() - costs[i] < need:
            alone = _bisect(
                lambda f, i=i: robust_with(
                    [_scaled(t, f) if k == i else t for k, t in enumerate(tolerance)]
                )
            )
        entries.append(
            {
                "contact": i,
                "shift": float(costs[i]),
                "factor": alone,
                "tolerance": None if alone is None else _scaled(own, alone).to_dict(),
            }
        )
    same = all(t == tolerance[0] for t in tolerance)
    return {
        "factor": factor,
        **({"tolerance_all": _scaled(tolerance[0], factor).to_dict()} if same else {}),
        "shift": float(costs.sum()),
        "allowed_shift": need,
        "costliest": int(np.argmax(costs)),
        "contacts": entries,
    }


def to_be_robust_text(advice: dict, elements=None, unit: str = "") -> str:
    """:func:`to_be_robust`'s answer in words: the share of every tolerance that would do, and
    the contact whose tolerance alone could shrink the least to do it (or the costliest)."""
    name = (
        (lambda i: f"contact {i}")
        if elements is None
        else (lambda i: f"contact {i} (element {elements[i]})")
    )
    text = f"robust if every contact's tolerance were {advice['factor']:.3g} of its own"
    if "tolerance_all" in advice:  # one tolerance for every contact: say it in its units
        t = advice["tolerance_all"]
        text += f" (within {t['position']:.3g}{' ' + unit if unit else ''} and "
        text += f"{t['normal_deg']:.3g} degrees)"
    text += f" (shift {advice['shift']:.3g} against {advice['allowed_shift']:.3g} allowed)"
    alone = [c for c in advice["contacts"] if c["factor"] is not None]
    if alone:
        best = max(alone, key=lambda c: c["factor"])
        t = best["tolerance"]
        text += (
            f", or if {name(best['contact'])}'s alone were within {t['position']:.3g}"
            f"{' ' + unit if unit else ''} and {t['normal_deg']:.3g} degrees"
        )
    else:
        costliest = advice["contacts"][advice["costliest"]]
        text += (
            f"; {name(costliest['contact'])} costs most ({costliest['shift']:.3g}), and no "
            "one contact's tolerance alone can do it"
        )
    return text


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
    "robust_value",
    "to_be_robust",
    "to_be_robust_text",
    "row_shifts",
    "support_shift",
    "tolerance_from_dict",
]
