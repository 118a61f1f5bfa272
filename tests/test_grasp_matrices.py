"""A contact set's grasp matrices, built for all its contacts at once."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet, grasp_matrices, local_frames


def _normals(rng, m):
    n = rng.normal(size=(m, 3)) * 10.0 ** rng.integers(-3, 4, size=(m, 1))
    n[rng.random((m, 3)) < 0.3] = 0.0  # axis-aligned normals: ties in the least-aligned axis
    n[~n.any(axis=1), 2] = -1.0
    return n


@pytest.mark.parametrize("seed", range(5))
def test_a_sets_grasp_matrices_are_each_contacts_own_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 40))
    contacts = tuple(Contact(rng.normal(size=3) * 50.0, n) for n in _normals(rng, m))
    reference = rng.normal(size=3)
    scale = float(rng.random() + 0.1)
    G = ContactSet(contacts, torque_scale=scale, reference_point=reference).grasp_matrices()
    for c, Gi in zip(contacts, G, strict=True):
        assert np.array_equal(Gi, grasp_matrices(c.position - reference, c.inward_normal, scale))


def test_a_sets_grasp_matrices_map_forces_to_wrenches():
    rng = np.random.default_rng(7)
    contacts = tuple(Contact(rng.normal(size=3), n) for n in _normals(rng, 6))
    scale = 0.5
    G = ContactSet(contacts, torque_scale=scale).grasp_matrices()
    for c, Gi in zip(contacts, G, strict=True):
        frame = Gi[:3, :3]
        assert np.allclose(frame.T @ frame, np.eye(3), atol=1e-12)
        assert np.allclose(frame[:, 0], c.inward_normal, atol=1e-12)
        assert np.allclose(np.cross(frame[:, 1], frame[:, 2]), frame[:, 0], atol=1e-12)
        torque = np.cross(c.position, frame.T)  # r x each axis, by numpy's own cross
        assert np.allclose(Gi[3:, :3], scale * torque.T, atol=1e-12)
        assert np.allclose(Gi[3:, 3], scale * c.inward_normal, atol=1e-12)
        assert not Gi[:3, 3].any()


def _reference_frame(n):
    """The frame's rule written out with numpy's own cross: o along n x e_k for the axis e_k
    least aligned with n, t = n x o."""
    e = np.zeros(3)
    e[np.argmin(np.abs(n))] = 1.0
    o = np.cross(n, e)
    o = o / np.sqrt(o @ o)
    return np.column_stack([n, o, np.cross(n, o)])


@pytest.mark.parametrize("seed", range(3))
def test_frames_follow_the_least_aligned_axis_rule(seed):
    rng = np.random.default_rng(seed)
    normals = _normals(rng, 50)
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    frames = local_frames(normals)
    for n, frame in zip(normals, frames, strict=True):
        expected = _reference_frame(n)
        assert np.allclose(frame, expected, rtol=0.0, atol=1e-15)
        assert np.allclose(frame.T @ frame, np.eye(3), rtol=0.0, atol=1e-15)
        assert np.linalg.det(frame) > 0.0
