"""A plan over worker processes when a worker dies, or when the plan itself is ended: an answer
from the seeds that finished (or a clear error), never a wait without end; workers that end with
their parent, quietly."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from closure_nlp.base.errors import MethodError
from closure_nlp.planning import seeds
from tests.test_seeds import OUTCOMES, hand, patch_plan

ROOT = Path(__file__).resolve().parents[1]


def dying_plan(eligibility, placer, seed, **kwargs):
    """Seed 0 ends at once; seed 1, in its worker, kills that worker; the others take long."""
    if seed == 0:
        return OUTCOMES[0]
    if seed == 1:
        time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(5.0)
    return OUTCOMES[4]


def test_a_killed_worker_ends_the_plan_with_the_seeds_that_finished(monkeypatch):
    patch_plan(monkeypatch, dying_plan)
    t0 = time.perf_counter()
    best = seeds.plan_seeds(hand(), seed=0, seeds=6, workers=2)
    assert time.perf_counter() - t0 < 4.0  # not the seeds' 5 s: the running ones are given up
    spread = best.seeds
    assert spread.runs[spread.chosen].seed == 0 and best.placement.rho == -0.2
    lost = [run for run in spread.runs if not run.ok]
    assert 1 in [run.seed for run in lost]
    assert all(run.error.startswith("WorkerLost: a worker process ended") for run in lost)
    assert len(spread.runs) < spread.requested  # no seed started after the pool broke
    assert "(a worker process ended)" in spread.line() and "failed (seed 1" in spread.line()


def killed(eligibility, placer, seed, **kwargs):
    os.kill(os.getpid(), signal.SIGKILL)


def test_every_worker_lost_is_a_method_error(monkeypatch):
    patch_plan(monkeypatch, killed)
    with pytest.raises(MethodError, match="worker process ended abruptly"):
        seeds.plan_seeds(hand(), seed=0, seeds=3, workers=2)


def _plan_process():
    command = [
        sys.executable,
        "-m",
        "closure_nlp.cli",
        "plan",
        str(ROOT / "models" / "lamp.model.json"),
    ]
    args = [
        "--contacts",
        "4",
        "--type",
        "pcwf",
        "--seeds",
        "4",
        "--workers",
        "2",
        "--json",
        "--quiet",
    ]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    return subprocess.Popen(
        command + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True
    )


def _workers(pid: int, count: int = 2, timeout: float = 60.0) -> list[int]:
    """The child processes of ``pid`` once there are ``count`` of them."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        path = Path(f"/proc/{pid}/task/{pid}/children")
        children = [int(c) for c in path.read_text().split()] if path.exists() else []
        if len(children) >= count:
            return children
        time.sleep(0.1)
    raise AssertionError(f"no {count} workers in {timeout} s")


def _ended(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return True
    return state in ("Z", "X")


needs_proc = pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="Linux /proc")


@pytest.mark.slow
@needs_proc
def test_cli_plan_answers_when_a_worker_is_killed():
    proc = _plan_process()
    workers = _workers(proc.pid)
    time.sleep(3.0)  # the workers run seeds now
    os.kill(workers[0], signal.SIGKILL)
    out, err = proc.communicate(timeout=120)
    assert "Traceback" not in err
    assert proc.returncode in (0, 1), err
    if proc.returncode == 0:
        runs = json.loads(out.splitlines()[-1])["seeds"]["runs"]
        assert any((run.get("error") or "").startswith("WorkerLost") for run in runs)
    else:
        assert "worker process ended abruptly" in err


@pytest.mark.slow
@needs_proc
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGKILL])
def test_ending_a_plan_ends_its_workers_at_once_and_quietly(signum):
    proc = _plan_process()
    workers = _workers(proc.pid)
    time.sleep(2.0)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == -signum
    t0 = time.monotonic()
    while not all(_ended(w) for w in workers) and time.monotonic() - t0 < 2.0:
        time.sleep(0.05)
    assert all(_ended(w) for w in workers)
    assert err.strip() == ""  # the workers' stderr is the parent's: no traceback from them
