"""Turns that map a wrench set onto itself: detection against the reference support function,
the fundamental domain against random directions, and the branch and bound over it against the
reference minimum."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench import cylinder_set, opposite_pair, ring, tetrahedral
from closure_nlp.contact.contact_set import Contact, ContactSet
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.sphere_branch_bound import BranchBoundOptions, sphere_minimum
from closure_nlp.criterion.symmetry import axis_frame, find_symmetry

from . import reference
from .test_certify import symmetric_sets


def _turn(symmetry, angle):
    """The map of wrenches (6, 6) of a turn of ``angle`` about the symmetry's axis (with the
    reflection across the normal plane when improper)."""
    a = symmetry.axis
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    Q = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    if symmetry.improper:
        Q = Q @ (np.eye(3) - 2 * np.outer(a, a))
    R = np.zeros((6, 6))
    R[:3, :3], R[3:, 3:] = Q, np.linalg.det(Q) * Q
    return R


def _mirror(symmetry):
    """The map of wrenches (6, 6) of the half turn about ``symmetry.mirror``, or of the
    reflection across the plane of it and the axis."""
    b, a = symmetry.mirror, symmetry.axis
    c = np.cross(a, b)
    Q = np.eye(3) - 2 * np.outer(c, c) if symmetry.reflects else 2 * np.outer(b, b) - np.eye(3)
    R = np.zeros((6, 6))
    R[:3, :3], R[3:, 3:] = Q, np.linalg.det(Q) * Q
    return R


def _flip(symmetry):
    """The map of wrenches (6, 6) of the reflection across the plane normal to the axis."""
    a = symmetry.axis
    Q = np.eye(3) - 2 * np.outer(a, a)
    R = np.zeros((6, 6))
    R[:3, :3], R[3:, 3:] = Q, -Q
    return R


def _group(symmetry):
    """Every element (6, 6) of a finite group found: turns, turns after a mirror, and all of
    these after the flip."""
    n = symmetry.order
    turns = [_turn(symmetry, 2 * np.pi * j / n) for j in range(n)]
    if symmetry.mirror is not None:
        turns += [R @ _mirror(symmetry) for R in turns]
    if symmetry.flip:
        turns += [R @ _flip(symmetry) for R in turns]
    return turns


def named_set(name: str) -> ContactSet:
    if name == "tetrahedral pcwf":
        return tetrahedral()
    if name.startswith("ring"):
        return ring("sfce", int(name.split("=")[1]))
    return dict(symmetric_sets())[name]


def _units(rng, count):
    U = rng.standard_normal((count, 6))
    return U / np.linalg.norm(U, axis=1, keepdims=True)


FOUND = [
    ("cylinder sfce m=4", 4, True, True, False),
    ("cylinder pcwf m=6", 6, True, True, False),
    ("box sfcl faces (0, 1, 2, 3)", 2, False, True, True),
    ("tetrahedral pcwf", 4, True, True, False),  # S4 about an axis between two contacts
    ("ring sfce m=3", 3, False, True, True),
    ("ring sfce m=6", 6, False, True, True),
]


@pytest.mark.parametrize(("name", "order", "improper", "has_mirror", "flip"), FOUND)
def test_found_turns_keep_the_reference_support_function(name, order, improper, has_mirror, flip):
    cs = named_set(name)
    symmetry = find_symmetry(WrenchSlots.from_contacts(cs))
    assert (symmetry.order, symmetry.improper, symmetry.flip) == (order, improper, flip)
    ref = reference.from_contact_set(cs)
    assert (symmetry.mirror is not None) == has_mirror
    maps = [_turn(symmetry, 2 * np.pi / order)] + ([_mirror(symmetry)] if has_mirror else [])
    maps += [_flip(symmetry)] if flip else []
    for u in _units(np.random.default_rng(order), 30):
        value = reference.support(u, ref)
        for R in maps:
            assert reference.support(R @ u, ref) == pytest.approx(value, rel=1e-12, abs=1e-12)
    assert 0 <= symmetry.slack < 1e-12


@pytest.mark.parametrize(("mu", "mu_s"), [(0.5, 0.5), (0.2, 1.0)])
def test_coaxial_round_cones_keep_every_turn(mu, mu_s):
    cs = opposite_pair(mu, mu_s)
    symmetry = find_symmetry(WrenchSlots.from_contacts(cs))
    assert symmetry.order == 0 and abs(symmetry.axis[2]) == pytest.approx(1.0)
    ref = reference.from_contact_set(cs)
    rng = np.random.default_rng(5)
    for u, angle in zip(_units(rng, 30), rng.uniform(-np.pi, np.pi, 30)):
        value = reference.support(u, ref)
        assert reference.support(_turn(symmetry, angle) @ u, ref) == pytest.approx(value, rel=1e-12)


def test_sets_without_turns_have_none():
    # random sets, and a cylinder or a pair whose one contact moved by 1e-6 of the part
    for seed in range(5):
        cs = random_contact_set(np.random.default_rng(seed), ["pcwf", "sfce", "sfcl", "fpc"])
        assert find_symmetry(WrenchSlots.from_contacts(cs)) is None
    for cs in (cylinder_set("sfce", 4), opposite_pair(0.5, 0.5)):
        moved = list(cs.contacts)
        c = moved[0]
        moved[0] = Contact(c.position + [1e-6, 0, 0], c.inward_normal, c.type, c.mu, c.mu_s)
        assert find_symmetry(WrenchSlots.from_contacts(ContactSet(tuple(moved)))) is None
    # soft fingers whose spin differs cannot be exchanged
    c0, c1 = opposite_pair(0.5, 0.5).contacts
    pair = ContactSet((c0, Contact(c1.position, c1.inward_normal, c1.type, 0.5, 0.4)))
    symmetry = find_symmetry(WrenchSlots.from_contacts(pair))
    assert symmetry is not None and symmetry.order == 0  # each cone is round: every turn still


@pytest.mark.parametrize(
    "name",
    ["cylinder sfce m=6", "cylinder pcwf m=4", "opposite", "tetrahedral pcwf", "ring sfce m=6"],
)
def test_every_orbit_meets_the_domain(name):
    """For random directions, some element of the group takes the direction into the union
    of the domain's cells (its preimage under the cells' map lies in one of the boxes)."""
    cs = opposite_pair(0.5, 0.5) if name == "opposite" else named_set(name)
    symmetry = find_symmetry(WrenchSlots.from_contacts(cs))
    metric = np.array([1, 1, 1, 0.5, 0.5, 0.5])
    rng = np.random.default_rng(2)
    for incumbent in _units(rng, 2):
        frame, axis, sign, lo, hi = symmetry.domain(metric, incumbent)
        P = axis_frame(symmetry.axis)
        for u in _units(rng, 40):
            if symmetry.order:
                turns = _group(symmetry)
            else:  # the turns taking the force pair, or the torque pair, to the positive ray
                pairs = (P.T @ u[:3])[:2], (P.T @ u[3:])[:2]
                turns = [_turn(symmetry, -np.arctan2(w[1], w[0])) for w in pairs]
            best = np.inf
            for R in turns:
                x = np.linalg.solve(frame, R @ u)
                x /= np.abs(x).max()
                k = int(np.argmax(np.abs(x)))
                free = np.delete(x, k)
                on_face = (axis == k) & (sign == np.sign(x[k]))
                outside = np.maximum(lo[on_face] - free, free - hi[on_face]).max(axis=1, initial=0)
                best = min(best, outside.min(initial=np.inf))
            assert best <= 1e-12, (u, best)


CASES = [
    ("4 PCwF cylinder", cylinder_set("pcwf", 4)),
    pytest.param("6 SFCe cylinder", cylinder_set("sfce", 6), marks=pytest.mark.slow),
    ("2 opposite SFCe 0.5/0.5", opposite_pair(0.5, 0.5)),
    ("2 opposite SFCe 0.5/1.0", opposite_pair(0.5, 1.0)),
    ("2 opposite SFCe 0.2/0.2", opposite_pair(0.2, 0.2)),
    ("tetrahedral 4 PCwF", tetrahedral()),
    ("tetrahedral 4 PCwF mu 0.2", tetrahedral(mu=0.2)),
    ("ring of 3 SFCe", ring("sfce", 3)),
    ("ring of 4 SFCe", ring("sfce", 4)),
]


@pytest.mark.parametrize(("name", "cs"), CASES)
def test_the_domain_brackets_the_reference_minimum(name, cs):
    slots = WrenchSlots.from_contacts(cs)
    p_ref, u_ref = reference.reference_min(reference.from_contact_set(cs), samples=400, starts=4)
    gap = 1e-6 * max(1.0, abs(p_ref))
    found = sphere_minimum(slots, u_ref, gap=gap)
    assert found.converged and found.upper - found.lower <= gap
    # the minimum is at most the reference's value, and the upper bound a value of p
    assert found.lower <= p_ref + 1e-12
    ref = reference.from_contact_set(cs)
    assert found.upper == pytest.approx(reference.support(found.direction, ref), rel=1e-12)
    assert found.upper <= p_ref + gap  # the reference's minimum is the global one here
    if "opposite" in name:
        assert found.cells < 3000  # a point, not a circle, of minima


@pytest.mark.parametrize(("mu", "mu_s"), [(0.5, 0.5), (0.5, 1.0), (0.2, 0.2)])
def test_two_opposite_soft_fingers_bracket_their_closed_form(mu, mu_s):
    """Fingers at z = +-1 pressing along z: with f = (a, f_z), tau x e_z = -a and tau_z = 0, the
    lower finger's value is f_z + 2 mu |a| and the upper one's -f_z; at -f_z = 2 mu |a| on the
    sphere, min p = 2 mu / sqrt(4 mu^2 + 2) (the reference finds the same, to 1e-10)."""
    value = 2 * mu / np.sqrt(4 * mu**2 + 2)
    found = sphere_minimum(WrenchSlots.from_contacts(opposite_pair(mu, mu_s)), None, gap=1e-9)
    assert found.converged
    assert found.lower <= value <= found.upper <= value + 1e-9


def test_axis_frame_is_right_handed_with_the_axis_last():
    for a in _units(np.random.default_rng(0), 10)[:, :3]:
        a /= np.linalg.norm(a)
        P = axis_frame(a)
        assert np.allclose(P.T @ P, np.eye(3)) and np.linalg.det(P) == pytest.approx(1.0)
        assert np.allclose(P[:, 2], a)


def test_without_symmetry_the_whole_sphere_is_searched():
    options = BranchBoundOptions(symmetry=False, max_cells=2000, extended_cells=2000)
    slots = WrenchSlots.from_contacts(opposite_pair(0.5, 0.5))
    found = sphere_minimum(slots, None, gap=1e-6, options=options)
    assert not found.converged and found.lower <= 1 / np.sqrt(3) <= found.upper
