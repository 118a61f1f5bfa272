"""The Python entries that hand a caller's arrays to the compiled kernels refuse a short,
mis-shaped or complex array with a ValueError naming it and its shape (the kernels index
without bounds checks: such an array would be read or written past its end)."""

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.frictionless import frictionless_capacity
from closure_nlp.criterion.hull_distance import min_norm_point, nearest_point_bounds
from closure_nlp.criterion.sphere_branch_bound import sphere_minimum
from closure_nlp.criterion.sphere_search import descend

NORMALS = np.vstack([np.eye(3), -np.eye(3)])
SHAPE = "expected real numbers of shape"


def _slots(rows=(0, 1, 2, 3)) -> WrenchSlots:
    return WrenchSlots.from_contacts(ContactSet(tuple(Contact(-n, n) for n in NORMALS[list(rows)])))


def _refused(message: str, call, *args, **kwargs) -> None:
    """``call`` raises a ValueError whose message is ``message``."""
    with pytest.raises(ValueError) as raised:
        call(*args, **kwargs)
    assert str(raised.value) == message


@pytest.mark.parametrize(
    "method", ["support", "evaluate", "row_support", "row_terms", "row_values", "slot_values"]
)
def test_directions_of_another_width_are_refused(method):
    evaluate = getattr(_slots(), method)
    _refused(f"U: {SHAPE} (N, 6), got shape (4, 3)", evaluate, np.ones((4, 3)))
    _refused(f"U: {SHAPE} (N, 6), got shape (1, 5)", evaluate, np.ones(5))  # one, short
    _refused(f"U: {SHAPE} (N, 6), got an array of complex128", evaluate, np.ones((2, 6), complex))


def test_one_direction_is_a_row_and_a_short_one_is_refused():
    slots = _slots()
    u = NORMALS[0].repeat(2) / np.sqrt(2)
    assert slots.support(u).shape == (1,)
    np.testing.assert_array_equal(slots.support_point(u), slots.support_points(u[None])[0])
    _refused(f"u: {SHAPE} (6,), got shape (3,)", slots.support_point, u[:3])


def _replaced(slots: WrenchSlots, **fields) -> WrenchSlots:
    now = {k: getattr(slots, k) for k in ("G", "starts", "f_max", "pieces", "types", "n_pieces")}
    return WrenchSlots(**{**now, **fields})


STARTS = "starts: expected whole numbers rising from 0, each slot's first of the 4 rows of G, got"


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"G": np.ones((4, 6, 3))}, f"G: {SHAPE} (K, 6, 4), got shape (4, 6, 3)"),
        ({"f_max": np.ones(3)}, f"f_max: {SHAPE} (4,), got shape (3,)"),
        ({"pieces": np.zeros((4, 1, 4))}, f"pieces: {SHAPE} (4, 2, 4), got shape (4, 1, 4)"),
        ({"starts": np.array([0, 1, 2, 4])}, f"{STARTS} [0 1 2 4] (int64)"),  # past the rows
        ({"starts": np.array([0, 2, 2, 3])}, f"{STARTS} [0 2 2 3] (int64)"),  # an empty slot
        ({"starts": np.array([1, 2, 3])}, f"{STARTS} [1 2 3] (int64)"),
        ({"starts": np.array([0.0, 1.0, 2.0, 3.0])}, f"{STARTS} [0. 1. 2. 3.] (float64)"),
        ({"n_pieces": (1, 1, 1)}, "n_pieces: expected one count per slot (4), got 3"),
    ],
)
def test_slots_whose_arrays_disagree_are_refused_before_any_kernel(fields, message):
    _refused(message, _replaced(_slots(), **fields).support, np.eye(6))


def test_the_descent_refuses_directions_of_another_width():
    message = f"U: {SHAPE} (N, 6), got shape (3, 5)"
    _refused(message, descend, _slots(), np.ones((3, 5)))
    _refused(message, descend, _slots(), np.ones((3, 5)), tau=0.1)  # the smoothed one


def test_the_nearest_point_refuses_no_points_and_short_inputs():
    _refused(
        "points: expected at least one point, got shape (0, 6)", min_norm_point, np.ones((0, 6))
    )
    _refused(f"points: {SHAPE} (n, d), got shape (6,)", min_norm_point, np.ones(6))
    slots = _slots((0, 1))  # the origin outside: the nearest-point iteration's case
    u0 = -NORMALS[0].repeat(2) / np.sqrt(2)
    _refused(f"u0: {SHAPE} (6,), got shape (3,)", nearest_point_bounds, slots, u0[:3], 1e-6)
    _refused("max_iter: must be >= 0, got -5", nearest_point_bounds, slots, u0, 1e-6, -5)
    lo, hi, *_ = nearest_point_bounds(slots, u0, 1e-6, max_iter=0)  # no iteration: still bounds
    assert 0 < lo <= hi


def test_the_branch_and_bound_refuses_short_directions_and_metrics():
    slots = _slots()
    _refused(
        f"incumbent: {SHAPE} (6,), got shape (5,)", sphere_minimum, slots, np.ones(5), gap=1e-6
    )
    _refused(
        f"metric: {SHAPE} (6,), got shape (3,)", sphere_minimum, slots, gap=1e-6, metric=[1] * 3
    )
    _refused(
        "metric: expected six positive finite numbers, got [1.0, 1.0, 1.0, 0.0, 1.0, 1.0]",
        sphere_minimum,
        slots,
        gap=1e-6,
        metric=[1, 1, 1, 0, 1, 1],
    )
    # the first round lowers the incumbent (none given) by more than the gap: a polish is asked
    short = lambda u: u[:3]  # noqa: E731
    _refused(
        f"polish(u): {SHAPE} (6,), got shape (3,)", sphere_minimum, slots, gap=1e-6, polish=short
    )


def test_the_frictionless_capacity_refuses_complex_wrenches():
    W = np.ones((2, 7, 6), dtype=complex)
    _refused(f"W: {SHAPE} (B, m, 6), got an array of complex128", frictionless_capacity, W)
