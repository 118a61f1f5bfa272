"""Ferrari-Canny epsilons of linearised friction cones, written from Dex-Net's and GraspIt!'s
conventions and sharing no code with closure_nlp (not its frames, grasp matrices or solvers):
the reference that ``bench dexnet`` and the interoperability tests hold rho against.

A contact is a point ``x`` and an inward unit normal ``n``; its cone is the pyramid of ``k``
edges ``n + mu (cos a_j t1 + sin a_j t2)`` (Dex-Net ``Contact3D.friction_cone``, GraspIt!
``Contact::wrenchFromFrictionEdge``: unit normal force, edges on the Coulomb cone, so the pyramid
is inscribed in it); a frictionless contact has the single edge ``n``. Edge wrenches are
``(f, s (x - r) x f)`` with the torque scale ``s`` and reference point ``r``.

* **L1** (Dex-Net ``ferrari_canny_L1``, GraspIt! "L1 Norm"): the hull of the *union* of all edge
  wrenches, i.e. the wrenches of contact forces whose normal components *sum* to at most 1.
* **L-infinity** (GraspIt! "LInfinity Norm"): the hull of every sum of one edge or nothing per
  contact, the Minkowski sum of the truncated pyramids: each normal force at most 1 on its own.

epsilon is the smallest distance from the origin to a facet's hyperplane (qhull's unit facet
normals); negative when the origin is outside (GraspIt! then reports -1, Dex-Net 0), and 0 when
the hull has no interior.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError


def tangents(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents completing ``normal`` to a right-handed frame, from the SVD as Dex-Net
    does (``Contact3D.tangents`` without its axis alignment: the pyramid turns about ``n`` but
    the edges stay on the cone)."""
    U = np.linalg.svd(normal.reshape(3, 1))[0]
    t1, t2 = U[:, 1], U[:, 2]
    return (t1, -t2) if np.dot(np.cross(t1, t2), normal) < 0 else (t1, t2)


def edge_wrenches(positions, inward_normals, mu, edges: int, torque_scale=1.0, reference=None):
    """(m, k, 6) wrenches of every contact's pyramid edges (unit normal force); ``mu`` one value
    or one per contact, 0 for a frictionless contact (its ``k`` rows then repeat ``n``)."""
    P = np.asarray(positions, float)
    N = np.asarray(inward_normals, float)
    N = N / np.linalg.norm(N, axis=1, keepdims=True)
    r = np.zeros(3) if reference is None else np.asarray(reference, float)
    mu = np.broadcast_to(np.asarray(mu, float), (len(P),))
    angles = 2 * np.pi * np.arange(edges) / edges
    out = np.empty((len(P), edges, 6))
    for i, (x, n) in enumerate(zip(P, N)):
        t1, t2 = tangents(n)
        forces = n + mu[i] * (np.cos(angles)[:, None] * t1 + np.sin(angles)[:, None] * t2)
        out[i, :, :3] = forces
        out[i, :, 3:] = torque_scale * np.cross(x - r, forces)
    return out


def _epsilon(points: np.ndarray) -> float:
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return 0.0  # no full-dimensional hull: the origin cannot be interior
    return float(np.min(-hull.equations[:, -1]))


def epsilon_l1(wrenches: np.ndarray) -> float:
    """L1 epsilon: hull of the union of the (m, k, 6) edge wrenches."""
    return _epsilon(np.unique(wrenches.reshape(-1, 6), axis=0))


def minkowski_points(wrenches: np.ndarray) -> np.ndarray:
    """Every sum of one edge wrench or none per contact: ((k + 1)^m, 6) points (repeated edges
    of a frictionless contact counted once)."""
    points = np.zeros((1, 6))
    for own in wrenches:
        own = np.vstack([np.zeros((1, 6)), np.unique(own, axis=0)])
        points = (points[:, None, :] + own[None, :, :]).reshape(-1, 6)
    return points


def epsilon_linf(wrenches: np.ndarray) -> float:
    """L-infinity epsilon: hull of the Minkowski sum of the truncated pyramids."""
    return _epsilon(minkowski_points(wrenches))
