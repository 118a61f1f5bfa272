"""The adapters of compare_solvers.py --peers, on two sets, for each peer that is set up.

The peers live in their own environments under .peers/ (``make compare-peers``); ``make test``
never installs them, so each test skips when its peer's environment is missing.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.contact.contact_set import Contact, ContactSet, load_contact_set
from closure_nlp.criterion.support_minimum import rho

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))
import compare_solvers  # noqa: E402
import peers  # noqa: E402

# Force closure with every linearisation: 3 contacts with friction on a ring (3 are the fewest;
# GraspIt!'s sum of all point combinations stays at 9^3 points).
RING = [[np.cos(a), np.sin(a), 0.0] for a in 2 * np.pi * np.arange(3) / 3]
CLOSURE = ContactSet(tuple(Contact(p, -np.array(p), "pcwf", mu=0.5) for p in RING))
# Not force closure: two contacts on one face, every force with a positive z component.
NOT_CLOSURE = ContactSet(
    (Contact([0, 0, -1], [0, 0, 1], "pcwf", mu=0.5), Contact([1, 0, -1], [0, 0, 1], "pcwf", mu=0.5))
)


def worker(name):
    if peers.peer_python(name) is None:
        pytest.skip(f"peer {name}: no environment under {peers.PEERS_DIR} (make compare-peers)")
    return peers.PeerWorker(name, timeout=60.0)


def ask(w, contact_set):
    wrenches, owner = compare_solvers.edge_wrenches(contact_set, owners=True)
    return w.ask(peers.request(contact_set, wrenches, owner))


@pytest.mark.parametrize("name", sorted(peers.PEERS))
def test_adapter_answers_both_sets(name):
    w = worker(name)
    try:
        for contact_set, expected in ((CLOSURE, True), (NOT_CLOSURE, False)):
            answer = ask(w, contact_set)
            for metric in peers.PEERS[name][1]:
                if metric == "dexnet_antipodal" and len(contact_set) != 2:
                    assert metric not in answer
                    continue
                result = answer[metric]
                assert result["verdict"] is expected, (metric, result)
                assert result["ms"] >= 0.0
    finally:
        w.close()


@pytest.mark.parametrize(("name", "metric"), [("dexnet", "dexnet_l1"), ("graspit", "graspit_linf")])
def test_epsilons_are_below_the_certified_load_capacity(name, metric):
    """Both epsilons measure sets inside ours (inscribed cones; their union's hull, or the L-inf
    sum), so neither exceeds -rho: the one value comparison that holds for every set."""
    w = worker(name)
    try:
        value = ask(w, CLOSURE)[metric]["value"]
    finally:
        w.close()
    lo, _ = rho(CLOSURE).bounds
    assert 0.0 < value <= -lo * (1 + 1e-6), (value, lo)


def test_worker_crash_is_reported_and_recovered(monkeypatch):
    """A worker that dies mid-set is a crash for that set, and the next set gets a new one."""
    w = worker("graspit")  # our own interpreter: always there
    request = peers.request(CLOSURE, *compare_solvers.edge_wrenches(CLOSURE, owners=True))
    try:
        w.start()
        read = w._read

        def die_then_read(timeout):  # as if the peer's C code aborted on this set
            w.process.kill()
            w.process.wait()
            return read(timeout)

        monkeypatch.setattr(w, "_read", die_then_read)
        answer = w.ask(request)
        assert "crash" in answer and len(w.crashes) == 1
        monkeypatch.undo()
        assert w.ask(request)["graspit_linf"]["verdict"] is True
    finally:
        w.close()


ABORTING_WORKER = """
import json, os, sys, time
print(json.dumps({"ready": sys.argv[1]}), flush=True)
sys.stdin.readline()
os.close(1)  # glibc's abort: the pipes close first, the core dump takes its time
time.sleep(1.0)
os.abort()
"""


def test_an_abort_is_a_crash_not_a_timeout(monkeypatch, tmp_path):
    """A worker whose output ends before the process is reaped (an abort writing its core) is a
    crash: ending output and no output were both read as None, and 101 of 129 Klampt aborts
    were reported as timeouts."""
    script = tmp_path / "aborting_worker.py"
    script.write_text(ABORTING_WORKER)
    monkeypatch.setattr(peers, "WORKER", script)
    monkeypatch.setattr(peers, "PEERS_DIR", tmp_path)
    w = peers.PeerWorker("graspit", timeout=30.0)
    try:
        answer = w.ask({"positions": []})
    finally:
        w.close()
    assert "crash" in answer and "timeout" not in answer, answer
    assert [status for status, _ in w.crashes] == [-6]  # SIGABRT


def test_klampt_answers_when_started_with_sigint_ignored():
    """Jobs a shell starts in the background inherit SIGINT ignored, and Klampt's
    force_closure aborted on every call there (munmap_chunk(): invalid pointer)."""
    import signal

    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)  # the worker inherits it
    try:
        w = worker("klampt")
        w.start()
    finally:
        signal.signal(signal.SIGINT, saved)
    try:
        answer = ask(w, CLOSURE)
    finally:
        w.close()
    assert "crash" not in answer, answer
    assert all(answer[metric]["verdict"] is True for metric in peers.PEERS["klampt"][1])


def test_polyhedral_closure_and_cases():
    """The LP that tells linearisation from a bug, on the saved minimal cases."""
    assert peers.polyhedral_closure(compare_solvers.edge_wrenches(CLOSURE))
    assert not peers.polyhedral_closure(compare_solvers.edge_wrenches(NOT_CLOSURE))
    ring = load_contact_set(peers.CASES / "ring_cone_edges.contacts.json")
    assert peers.polyhedral_closure(compare_solvers.edge_wrenches(ring, 64))
    frictionless = load_contact_set(peers.CASES / "klampt_frictionless.contacts.json")
    assert not peers.polyhedral_closure(compare_solvers.edge_wrenches(frictionless))
