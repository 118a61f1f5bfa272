"""The :class:`WrenchSlots` of many contact sets given as arrays, built in one numpy pass.

``WrenchSlots.from_contacts(ContactSet.from_arrays(...))`` of each set builds and validates a
:class:`Contact` per contact and the set's grasp matrices one set at a time: on sets of four
contacts that cost more than certifying a set that is not force closure. Here every check runs
once over the whole batch (each distinct ``type``, ``mu``, ``mu_s``, ``f_max`` and torque scale
through the same validators) and the grasp matrices of all sets come from the same operations,
applied elementwise to every contact at once, so each set's slots hold the same numbers to the
bit as the per-set path gives. Any input that the per-set path would refuse or treat specially
(a non-finite or out-of-range number, a normal too small or too large to square) returns None:
the caller then takes that path, which raises its error naming the set and field.
"""

from __future__ import annotations

import numpy as np

from closure_nlp.base.validation import (
    MAX_COORDINATE,
    MAX_SET_CONTACTS,
    as_f_max,
    as_mu,
    as_mu_s,
    as_torque_scale,
)
from closure_nlp.contact.contact_set import (
    ContactType,
    cross,
    frame_grasp_matrices,
    friction_pieces,
)
from closure_nlp.contact.wrenches import MAX_PIECES, WrenchSlots

# A normal's largest component outside this range is rescaled before its norm (as_unit_vector):
# the per-set path handles it.
NORMAL_RANGE = (1e-150, 1e150)


def slots_of_arrays(P, U, kinds, mu, mu_s, f_max, scales, points) -> list[WrenchSlots] | None:
    """Each set's slots, one row per contact, or None where the per-set path must decide.

    P, U : (N, m, 3) float positions and inward normals (not yet normalised); kinds (N, m)
    object; mu, mu_s, f_max (N, m) float; scales (N,) float; points (N, 3) float or None.
    """
    N, m, _ = P.shape
    if m > MAX_SET_CONTACTS or not _finite_within(P, MAX_COORDINATE):
        return None
    if points is not None and not _finite_within(points, MAX_COORDINATE):
        return None
    largest = np.abs(U).max(axis=2)
    if not (np.all(largest > NORMAL_RANGE[0]) and np.all(largest < NORMAL_RANGE[1])):
        return None  # zero, tiny, huge or non-finite normals
    try:
        kinds = _checked(kinds, ContactType.parse, object)
        mu, mu_s = _checked(mu, as_mu, float), _checked(mu_s, as_mu_s, float)
        f_max = _checked(f_max, as_f_max, float)
        scales = _checked(scales, as_torque_scale, float)
    except (TypeError, ValueError):
        return None
    # as_unit_vector: each normal divided by its own norm (np.linalg.norm of that vector)
    rows = U.reshape(-1, 3).astype(float)
    normals = rows / np.array([np.linalg.norm(n) for n in rows])[:, None]
    frames = _local_frames(normals)
    reference = np.zeros((N, 3)) if points is None else points
    r = (P - reference[:, None, :]).reshape(-1, 3)
    G = frame_grasp_matrices(r, frames, np.repeat(scales, m)).reshape(N, m, 6, 4)
    pieces, counts = _pieces(kinds, mu, mu_s)
    starts = np.arange(m)
    return [
        WrenchSlots(
            G[k],
            starts,
            f_max[k],
            pieces[k],
            tuple(kinds[k]),
            tuple(counts[k].tolist()),
        )
        for k in range(N)
    ]


def _finite_within(array: np.ndarray, limit: float) -> bool:
    top = float(np.abs(array).max()) if array.size else 0.0
    return bool(np.isfinite(top) and top <= limit)


def _checked(values: np.ndarray, check, dtype) -> np.ndarray:
    """``values`` with each distinct entry replaced by what ``check`` makes of it (the per-set
    path's validators, run once per distinct value)."""
    flat = values.ravel()
    seen: dict = {}
    out = np.empty(flat.shape, dtype=dtype)
    for i, value in enumerate(flat.tolist()):
        key = (type(value), value)
        if key not in seen:
            seen[key] = check(value, "value")
        out[i] = seen[key]
    return out.reshape(values.shape)


def _local_frames(n: np.ndarray) -> np.ndarray:
    """:func:`~closure_nlp.contact.contact_set.local_frames` of every contact at once, by the
    same operations (a vector norm per frame, as there)."""
    helper = np.zeros(n.shape)
    helper[np.arange(len(n)), np.argmin(np.abs(n), axis=1)] = 1.0
    o = cross(n, helper)
    o /= np.array([np.linalg.norm(row) for row in o])[:, None]
    t = cross(n, o)
    return np.stack([n, o, t], axis=-1)


def _pieces(kinds: np.ndarray, mu: np.ndarray, mu_s: np.ndarray):
    """Friction weights (N, m, MAX_PIECES, 4) and real pieces per contact (N, m) int, as
    :func:`~closure_nlp.contact.contact_set.friction_pieces` gives them."""
    pieces = np.zeros((*kinds.shape, MAX_PIECES, 4))
    counts = np.zeros(kinds.shape, dtype=np.int64)
    names = np.array([kind.value for kind in kinds.ravel().tolist()]).reshape(kinds.shape)
    for kind in set(kinds.ravel().tolist()):
        at = names == kind.value  # (an enum of str compares unequal inside an object array)
        # the template's nonzero entries are mu**2 (columns 1, 2) or mu_s**2 (column 3)
        template = friction_pieces(kind, 1.0, 1.0)
        counts[at] = len(template)
        mu2, mus2 = (mu[at] * mu[at])[:, None], (mu_s[at] * mu_s[at])[:, None]
        for p, row in enumerate(template):
            block = np.zeros((int(at.sum()), 4))
            block[:, 1:3] = row[1:3] * mu2
            block[:, 3] = row[3] * mus2[:, 0]
            pieces[at, p] = block
    return pieces, counts


__all__ = ["slots_of_arrays"]
