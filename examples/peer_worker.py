"""Adapters to outside grasp-quality implementations, run inside each peer's own environment.

    <peer venv>/bin/python examples/peer_worker.py NAME

Reads one JSON request per line on stdin, answers one JSON line per request on stdout (the
original stdout: the peers' own prints go to stderr). Only the standard library, numpy and the
peer itself are imported here, because the peers' environments do not have closure_nlp (Dex-Net's
code needs numpy < 2). A request is one contact set, already converted by ``examples/peers.py``::

    {"positions": [[x, y, z], ...], "normals": [[...], ...] (unit inward), "mu": [...],
     "types": ["pcwf", ...], "forces": [[fx, fy, fz], ...], "torques": [[...], ...],
     "edge_contact": [i, ...]}

``forces``/``torques`` are the wrenches of every contact's 8-edge cone (and soft fingers' two spin
tips) at ``f_max``, torques already multiplied by ``torque_scale``; ``edge_contact`` says which
contact each belongs to. The answer maps each metric the peer offers to ``{"verdict": bool or
null, "value": float or null, "ms": float}`` or ``{"error": "..."}``; ms times the peer's call
alone. Adapters written from the peers' public APIs and documentation.

Names: ``klampt`` (``klampt.robotsim.force_closure`` with 4, 8 and 64 cone edges: point contacts
only), ``dexnet`` (Dex-Net's ``PointGraspMetrics3D`` as vendored in PyPI ``graspnetAPI``:
``ferrari_canny_L1``, ``force_closure_qp`` and, for two point contacts, the antipodal
``force_closure``), ``graspit`` (GraspIt!'s L-infinity epsilon from its published algorithm,
written by us: Minkowski sum of the contacts' edge pyramids and the origin, one qhull, distance to
the nearest facet; scipy).
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
import types

import numpy as np

KLAMPT_EDGES = (4, 8, 64)


def _timed(function, *args, **kwargs):
    t0 = time.perf_counter()
    value = function(*args, **kwargs)
    return value, 1e3 * (time.perf_counter() - t0)


# --- Klampt -------------------------------------------------------------------------------------


def klampt_adapter():
    from klampt import robotsim

    def run(request):
        if any(t not in ("fpc", "pcwf") for t in request["types"]):
            return {f"klampt_{k}": {"error": "unsupported: soft fingers"} for k in KLAMPT_EDGES}
        mu = [0.0 if t == "fpc" else m for t, m in zip(request["types"], request["mu"])]
        # [x, y, z, nx, ny, nz, k] per contact: n is the direction the contact pushes.
        rows = [[*p, *n, k] for p, n, k in zip(request["positions"], request["normals"], mu)]
        out = {}
        for edges in KLAMPT_EDGES:
            robotsim.set_friction_cone_approximation_edges(edges)
            verdict, ms = _timed(robotsim.force_closure, rows)
            out[f"klampt_{edges}"] = {"verdict": bool(verdict), "value": None, "ms": ms}
        return out

    return run


# --- Dex-Net (graspnetAPI) ----------------------------------------------------------------------


def dexnet_adapter():
    import importlib.util

    # graspnetAPI/__init__.py imports its dataset tools (open3d, cv2, ...), which Dex-Net's
    # quality module does not need: register the package without running it.
    spec = importlib.util.find_spec("graspnetAPI")
    if spec is None:
        raise ImportError("graspnetAPI is not installed")
    package = types.ModuleType("graspnetAPI")
    package.__path__ = list(spec.submodule_search_locations)
    sys.modules.setdefault("graspnetAPI", package)
    from graspnetAPI.utils.dexnet.grasping.quality import PointGraspMetrics3D as metrics

    class Params(dict):
        """GraspQualityConfig stand-in: the keys the metrics read, as attributes too."""

        __getattr__ = dict.__getitem__

    class Point:  # Contact3D stand-in for the antipodal test: point and outward normal
        def __init__(self, point, inward_normal):
            self.point = np.asarray(point, float)
            self.normal = -np.asarray(inward_normal, float)

    def run(request):
        forces = np.asarray(request["forces"], float).T
        torques = np.asarray(request["torques"], float).T
        owner = np.asarray(request["edge_contact"])
        normals = np.asarray(request["normals"], float)[owner].T
        # The wrenches come scaled already; soft-finger spin tips are columns like the edges.
        params = Params(torque_scaling=1.0, friction_coef=float(max(request["mu"])))
        out = {}
        try:
            value, ms = _timed(
                metrics.ferrari_canny_L1, forces, torques, normals, soft_fingers=False,
                params=params,
            )  # fmt: skip
            out["dexnet_l1"] = {"verdict": bool(value > 0), "value": float(value), "ms": ms}
            # Not timed: how far the origin is from the hull, by Dex-Net's own QP (diagnosis).
            G = metrics.grasp_matrix(forces, torques, normals, False, params=params)
            distance = float(metrics.min_norm_vector_in_facet(G)[0])
            out["dexnet_l1"]["hull_distance"] = out["dexnet_qp_distance"] = distance
        except Exception as exc:  # noqa: BLE001  (a peer's failure is data)
            out["dexnet_l1"] = {"error": f"{type(exc).__name__}: {exc}"}
        try:
            value, ms = _timed(
                metrics.force_closure_qp, forces, torques, normals, soft_fingers=False,
                params=params,
            )  # fmt: skip
            out["dexnet_qp"] = {"verdict": bool(value), "value": None, "ms": ms}
            if "dexnet_qp_distance" in out:
                out["dexnet_qp"]["hull_distance"] = out.pop("dexnet_qp_distance")
        except Exception as exc:  # noqa: BLE001
            out["dexnet_qp"] = {"error": f"{type(exc).__name__}: {exc}"}
        if len(request["types"]) == 2 and set(request["types"]) == {"pcwf"}:
            c1, c2 = (Point(p, n) for p, n in zip(request["positions"], request["normals"]))
            value, ms = _timed(metrics.force_closure, c1, c2, float(request["mu"][0]))
            out["dexnet_antipodal"] = {"verdict": bool(value), "value": None, "ms": ms}
        return out

    return run


# --- GraspIt!-style L-infinity epsilon (ours, from the published algorithm) ---------------------


def graspit_adapter():
    from scipy.spatial import ConvexHull, QhullError

    def linf_epsilon(request):
        """(epsilon, verdict): min facet distance of the Minkowski sum of edge pyramids."""
        wrenches = np.hstack([request["forces"], request["torques"]])
        owner = np.asarray(request["edge_contact"])
        points = np.zeros((1, 6))
        for i in range(len(request["types"])):  # every sum of one point per contact, 0 included
            own = np.vstack([np.zeros((1, 6)), wrenches[owner == i]])
            points = (points[:, None, :] + own[None, :, :]).reshape(-1, 6)
        try:
            hull = ConvexHull(points)
        except QhullError:
            return -1.0, False  # GraspIt! returns -1 when qhull finds no full-dimensional hull
        epsilon = float(np.min(-hull.equations[:, -1]))
        # The set always holds the origin (all forces zero): on its boundary when not closure.
        scale = float(np.max(np.linalg.norm(points, axis=1)))
        return epsilon, epsilon > 1e-9 * scale

    def run(request):
        (epsilon, verdict), ms = _timed(linf_epsilon, request)
        return {"graspit_linf": {"verdict": bool(verdict), "value": epsilon, "ms": ms}}

    return run


ADAPTERS = {"klampt": klampt_adapter, "dexnet": dexnet_adapter, "graspit": graspit_adapter}


def serve(name: str) -> int:
    if name not in ADAPTERS:
        print(f"error: peer: expected one of {sorted(ADAPTERS)}, got {name!r}", file=sys.stderr)
        return 2
    # A job started in the background by a shell (`cmd &`, nohup in a script, CI runners)
    # inherits SIGINT ignored; Klampt's force_closure then aborts on every call (glibc
    # "munmap_chunk(): invalid pointer"). The handler a terminal's Python has makes it work.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    answers = os.fdopen(os.dup(1), "w")  # the protocol's channel
    os.dup2(2, 1)  # Klampt and Dex-Net print to stdout (C and Python): send that to stderr
    sys.stdout = sys.stderr
    run = ADAPTERS[name]()
    answers.write(json.dumps({"ready": name}) + "\n")
    answers.flush()
    for line in sys.stdin:
        request = json.loads(line)
        try:
            result = run(request)
        except Exception as exc:  # noqa: BLE001  (reported per set, the worker goes on)
            result = {"error": f"{type(exc).__name__}: {exc}"}
        answers.write(json.dumps(result) + "\n")
        answers.flush()
    return 0


if __name__ == "__main__":
    sys.exit(serve(sys.argv[1] if len(sys.argv) > 1 else ""))
