"""Choices that round-off cannot flip: ties taken in index order, and the analytic centre of a
linear programme's optimal face (a point of the face that the data's round-off moves by
round-off only)."""

from __future__ import annotations

import numpy as np

from closure_nlp.base.ties import first_largest, lowest_first
from closure_nlp.placement.analytic_centre import analytic_centre


def test_near_equal_values_are_taken_in_index_order_at_any_scale():
    for scale in (1e-3, 1.0, 1e3):
        values = scale * np.array([[0.3, 0.5, 0.5 + 1e-15, 0.1], [0.5 + 1e-15, 0.2, 0.5, 0.5]])
        np.testing.assert_array_equal(first_largest(values, scale), [1, 0])
        assert first_largest(scale * np.array([0.1, 0.3, 0.2]), scale) == 1
        lows = lowest_first(scale * np.array([0.2, 0.1 + 1e-15, 0.1, 0.3, 0.1]), scale, 3)
        np.testing.assert_array_equal(lows, [1, 2, 4])


def test_the_centre_of_a_whole_optimal_simplex_is_its_centroid():
    # every row has the same value at every weight: the optimal face is the whole simplex
    A = np.ones((3, 4))
    owner = np.zeros(4, int)
    lo, hi = np.zeros(4), np.ones(4)
    for start in (np.array([1.0, 0, 0, 0]), np.array([0.1, 0.2, 0.3, 0.4])):
        centre = analytic_centre(A, owner, lo, hi, 1.0, start)
        np.testing.assert_allclose(centre, 0.25, atol=1e-12)


def test_the_centre_stays_on_the_optimal_face_and_ignores_round_off():
    # two contacts of two weights; row 0 is best at lam_0 = 1 for the first contact, whatever
    # the second contact's weights (its columns are zero there): the face is {1, 0} x simplex
    A = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.5, 0.5]])
    owner = np.array([0, 0, 1, 1])
    lo, hi = np.zeros(4), np.ones(4)
    start = np.array([1.0, 0.0, 0.9, 0.1])
    centre = analytic_centre(A, owner, lo, hi, 1.0, start)
    assert centre[0] > 1 - 1e-5 and abs(centre[2] - 0.5) < 1e-9  # optimal, the second centred
    assert np.min(A @ centre) >= 1.0 - 2e-6
    # the data times 1 + 1e-15 (round-off of a change of units) moves it by round-off only
    again = analytic_centre(A * (1 + 1e-15), owner, lo, hi, 1.0 + 1e-15, np.array([1, 0, 0.2, 0.8]))
    np.testing.assert_allclose(again, centre, atol=1e-12)
