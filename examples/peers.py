"""The outside implementations ("peers") that ``compare_solvers.py --peers`` runs, host side.

Each peer runs ``examples/peer_worker.py`` in its own virtual environment under ``.peers/NAME``
(``make compare-peers`` creates them; git ignores them), because their dependencies clash with
ours (Dex-Net's code needs numpy < 2). A worker is a long-lived subprocess exchanging one JSON
line per contact set; one that dies (a crash in the peer's C code) or overruns its time limit is
recorded against that set and started again.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linprog

ROOT = Path(__file__).resolve().parents[1]
PEERS_DIR = Path(os.environ.get("CLOSURE_NLP_PEERS", ROOT / ".peers"))
WORKER = Path(__file__).resolve().with_name("peer_worker.py")
CASES = Path(__file__).resolve().with_name("peer_cases")

# name -> (venv under PEERS_DIR, or None for our own interpreter; metrics it answers)
PEERS = {
    "klampt": ("klampt", ("klampt_4", "klampt_8", "klampt_64")),
    "dexnet": ("dexnet", ("dexnet_l1", "dexnet_qp", "dexnet_antipodal")),
    "graspit": (None, ("graspit_linf",)),
}
METRICS = {
    "klampt_4": "Klampt force_closure, 4 cone edges (default)",
    "klampt_8": "Klampt force_closure, 8 cone edges",
    "klampt_64": "Klampt force_closure, 64 cone edges",
    "dexnet_l1": "Dex-Net ferrari_canny_L1, 8 edges",
    "dexnet_qp": "Dex-Net force_closure_qp",
    "dexnet_antipodal": "Dex-Net force_closure (2 contacts)",
    "graspit_linf": "GraspIt!-style L-inf epsilon, 8 edges (ours)",
}


ENDED, TIMED_OUT = "ended", "timed out"  # what PeerWorker._read says instead of an answer
EXIT_WAIT = 10.0  # s a worker that closed its output gets to exit (a core dump takes a while)


def peer_python(name: str) -> Path | None:
    """The interpreter of a peer's environment, or None when it is not set up."""
    venv = PEERS[name][0]
    if venv is None:
        return Path(sys.executable)
    python = PEERS_DIR / venv / "bin" / "python"
    return python if python.exists() else None


class PeerWorker:
    """One peer's worker process; ``ask`` sends a set and waits at most ``timeout`` seconds."""

    def __init__(self, name: str, timeout: float = 60.0):
        python = peer_python(name)
        if python is None:
            raise FileNotFoundError(
                f"peer {name}: no environment at {PEERS_DIR / PEERS[name][0]} "
                "(run `make compare-peers`)"
            )
        self.name, self.python, self.timeout = name, python, timeout
        self.process = None
        self.crashes = []  # the worker's exit statuses and last stderr lines, per crash

    def start(self) -> None:
        env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
        PEERS_DIR.mkdir(parents=True, exist_ok=True)
        self.log = (PEERS_DIR / f"{self.name}.stderr.log").open("ab")  # the peers' own output
        self.process = subprocess.Popen(
            [str(self.python), str(WORKER), self.name],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, env=env,
        )  # fmt: skip
        ready = self._read(max(self.timeout, 120.0))  # the first import can take a while
        if not isinstance(ready, dict) or ready.get("ready") != self.name:
            raise RuntimeError(f"peer {self.name}: the worker did not start: {ready!r}")

    def _read(self, timeout: float):
        """The next answer (a dict), ``ENDED`` when the worker closed its output (it died, or is
        dying), or ``TIMED_OUT``."""
        readable, _, _ = select.select([self.process.stdout], [], [], timeout)
        if not readable:
            return TIMED_OUT
        line = self.process.stdout.readline()
        return json.loads(line) if line else ENDED

    def ask(self, request: dict) -> dict:
        """The worker's answer, or ``{"crash": ...}`` / ``{"timeout": ...}`` for every metric."""
        if self.process is None or self.process.poll() is not None:
            self.start()
        try:
            self.process.stdin.write((json.dumps(request) + "\n").encode())
            self.process.stdin.flush()
        except BrokenPipeError:  # it died between two requests
            pass
        t0 = time.perf_counter()
        answer = self._read(self.timeout)
        if isinstance(answer, dict):
            return answer
        if answer is ENDED:  # an aborting process closes its pipes before it is reaped
            try:
                self.process.wait(timeout=EXIT_WAIT)
            except subprocess.TimeoutExpired:
                pass
        if self.process.poll() is None:
            self.close()
            if answer is ENDED:
                return {"crash": f"worker closed its output and did not exit in {EXIT_WAIT} s"}
            return {"timeout": f"no answer in {self.timeout:.0f} s"}
        status = self.process.returncode
        self.close()
        tail = (PEERS_DIR / f"{self.name}.stderr.log").read_bytes()[-300:].decode(errors="replace")
        self.crashes.append((status, tail))
        return {
            "crash": f"worker exited with status {status} after "
            f"{time.perf_counter() - t0:.1f} s: {tail.strip().splitlines()[-1:] or ''}"
        }

    def close(self) -> None:
        if self.process is not None:
            if self.process.poll() is None:
                self.process.kill()
            self.process.wait()
            self.log.close()
            self.process = None


def request(contact_set, wrenches: np.ndarray, owner: np.ndarray) -> dict:
    """The JSON request of one set: contacts and their edge wrenches (see peer_worker.py)."""
    contacts = contact_set.contacts
    return {
        "positions": [(c.position - contact_set.reference_point).tolist() for c in contacts],
        "normals": [c.inward_normal.tolist() for c in contacts],
        "mu": [c.mu for c in contacts],
        "types": [c.type.value for c in contacts],
        "forces": wrenches[:, :3].tolist(),
        "torques": wrenches[:, 3:].tolist(),
        "edge_contact": owner.tolist(),
    }


def polyhedral_closure(wrenches: np.ndarray) -> bool:
    """Force closure of the linearised set: the edges' wrenches positively span R^6.

    The origin is inside the convex hull of the rows iff they have rank 6 and some combination
    with every weight strictly positive sums to zero (max t: W^T l = 0, l >= t, sum l = 1). An
    LP (HiGHS), independent of qhull and of every peer: it tells a linearisation from a bug.
    """
    W = np.asarray(wrenches, float)
    W = W / np.linalg.norm(W, axis=1, keepdims=True)  # positive scaling keeps the span
    if np.linalg.matrix_rank(W, tol=1e-9) < 6:
        return False
    k = len(W)
    # variables (l_1..l_k, t); maximise t
    cost = np.r_[np.zeros(k), -1.0]
    A_eq = np.vstack([np.c_[W.T, np.zeros(6)], np.r_[np.ones(k), 0.0]])
    b_eq = np.r_[np.zeros(6), 1.0]
    A_ub = np.c_[-np.eye(k), np.ones(k)]  # t - l_j <= 0
    res = linprog(cost, A_ub=A_ub, b_ub=np.zeros(k), A_eq=A_eq, b_eq=b_eq,
                  bounds=[(0, None)] * k + [(None, None)], method="highs")  # fmt: skip
    return bool(res.status == 0 and -res.fun > 1e-9 / k)
