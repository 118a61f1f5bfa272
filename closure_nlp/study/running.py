"""Running a study: the pending tasks on a Dask cluster (local, joined or given) or serially."""

from __future__ import annotations

import logging
import os
import re
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from closure_nlp.base.files import escape, write_json
from closure_nlp.study.grid import Study, _integer
from closure_nlp.study.store import read_results, write_row
from closure_nlp.study.summary import summarize, write_outputs
from closure_nlp.study.tasks import Runner, Task, error_row, run_task

# progress(done, total, row): called in the driver before the first task (row None) and after
# every finished task (its row already written); an exception raised there stops the study.
StudyProgress = Callable[[int, int, dict], None]


@dataclass(frozen=True)
class StudyRun:
    """What :func:`run_study` did.

    Attributes
    ----------
    name : str
    total : int
        Tasks in the study.
    run : int
        Tasks run now (including the failed ones).
    skipped : int
        Tasks already done by an earlier run.
    failed : int
        Tasks run now that recorded an error.
    remaining : int
        Tasks still not done (``limit``).
    seconds : float
        Wall time of running the tasks.
    workers : int
        Workers that ran them (1 for a serial run).
    paths : dict of str
        ``results`` (the part-file folder), ``results.csv``, ``summary.md``, ``summary.csv``,
        ``rho.png``, ``seconds.png``, ``study.json``.
    summary : list of dict
        The rows of the summary table.
    """

    name: str
    total: int
    run: int
    skipped: int
    failed: int
    remaining: int
    seconds: float
    workers: int
    paths: dict
    summary: list

    @property
    def tasks_per_second(self) -> float:
        """Tasks run now per second of :attr:`seconds`."""
        return self.run / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict:
        """The CLI's ``--json`` payload: counts, seconds, workers, output paths, summary."""
        return {
            "study": self.name,
            "tasks": {
                "total": self.total,
                "run": self.run,
                "skipped": self.skipped,
                "failed": self.failed,
                "remaining": self.remaining,
            },
            "seconds": self.seconds,
            "workers": self.workers,
            "tasks_per_second": self.tasks_per_second,
            "out": self.paths,
            "summary": self.summary,
        }


def run_study(
    study: Study,
    out,
    *,
    client=None,
    scheduler: str | None = None,
    workers: int | None = None,
    serial: bool = False,
    limit: int | None = None,
    retry_failed: bool = False,
    progress: StudyProgress | None = None,
    runner: Runner = run_task,
) -> StudyRun:
    """Run the tasks of ``study`` not done yet in ``out``, then write the summary and plots.

    Parameters
    ----------
    study : Study
    out : str or Path
        Output folder; ``out/results/`` holds one Parquet part-file per finished task.
    client : distributed.Client, optional
        Run on this client's cluster (left open).
    scheduler : str, optional
        Address of a running Dask scheduler to join (its cluster is left as it is).
    workers : int, optional
        Worker processes of the local cluster started otherwise (default: the machine's cores),
        one thread each.
    serial : bool
        Run the tasks one after another in this process, without Dask.
    limit : int, optional
        Run at most this many of the pending tasks (run again to resume).
    retry_failed : bool
        Run again the tasks whose earlier run recorded an error.
    progress : callable, optional
        ``progress(0, total, None)`` before the first task, then ``progress(done, total, row)``
        after every finished task.
    runner : callable
        ``runner(task, model_text) -> row``; :func:`run_task` (tests swap it).

    Returns
    -------
    StudyRun
    """
    if limit is not None:
        _integer(limit, "limit", 0, "an integer")
    if workers is not None:
        _integer(workers, "workers", 1, "an integer")
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
    if sum(x is not None for x in (client, scheduler)) + bool(serial) > 1:
        raise ValueError("scheduler: give at most one of client, scheduler and serial")
    if workers is not None and (client is not None or scheduler):
        raise ValueError("workers: only for the local cluster (not with a scheduler or client)")
    out = Path(out)
    results_dir = out / "results"
    results_dir.mkdir(parents=True, exist_ok=True)
    write_json(out / "study.json", study.to_dict())
    done = read_results(results_dir)
    finished = set(done.task_id) if not retry_failed else set(done.task_id[done.status == "ok"])
    pending = [t for t in study.tasks if t.task_id not in finished]
    skipped = len(study.tasks) - len(pending)
    if limit is not None:
        pending = pending[:limit]
    texts = {ref.digest: ref.text for ref in study.models}
    count = {"done": 0, "failed": 0}

    def record(row: dict) -> None:
        write_row(results_dir, row)
        count["done"] += 1
        count["failed"] += row["status"] != "ok"
        if progress:
            progress(count["done"], len(pending), row)

    if progress:
        progress(0, len(pending), None)
    t0 = time.perf_counter()
    if serial or not pending:
        used = 1
        for task in pending:
            try:
                row = runner(task, texts[task.model_digest])
            except Exception as exc:  # noqa: BLE001 - the study goes on
                row = error_row(task, f"{type(exc).__name__}: {exc}")
            record(row)
    else:
        used = _run_dask(pending, texts, record, runner, client, scheduler, workers)
    seconds = time.perf_counter() - t0
    paths = {"results": str(results_dir), "study.json": str(out / "study.json")}
    frame = read_results(results_dir)
    summary = summarize(study, frame)
    paths.update(write_outputs(study, frame, summary, out))
    ids = set(frame.task_id)
    return StudyRun(
        study.name,
        len(study.tasks),
        count["done"],
        skipped,
        count["failed"],
        sum(t.task_id not in ids for t in study.tasks),
        seconds,
        used,
        paths,
        [{k: _plain(v) for k, v in r.items()} for r in summary.to_dict("records")],
    )


def _plain(value):
    """A JSON value: numpy scalars as Python ones, NaN as None."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


CONNECT_SECONDS = 20  # to reach a scheduler before giving up
LOST_RESULT_RETRIES = 2  # a task whose finished result died with its worker runs again
_PROTOCOLS = ("tcp", "tls", "ws", "wss", "ucx")
_ADDRESS = re.compile(
    r"(?:(?P<protocol>[a-z]+)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(?P<port>[0-9]{1,5})"
)


def check_scheduler_address(address) -> str:
    """A Dask scheduler address ``[PROTOCOL://]HOST:PORT`` (as the scheduler prints it), or a
    ``ValueError`` naming what is wrong; whether it answers is found when joining it."""
    if not isinstance(address, str):
        raise TypeError(f"scheduler: expected an address tcp://HOST:PORT, got {address!r}")
    match = _ADDRESS.fullmatch(address) if address.isascii() else None
    if match is None or not 1 <= int(match["port"]) <= 65535:
        raise ValueError(
            f"scheduler: expected an address tcp://HOST:PORT (a port in 1..65535), got "
            f"{escape(repr(address))[:80]}"
        )
    if match["protocol"] is not None and match["protocol"] not in _PROTOCOLS:
        raise ValueError(
            f"scheduler: unknown protocol {match['protocol']!r} (expected one of "
            f"{', '.join(_PROTOCOLS)})"
        )
    return address


class _Dispatch:
    """Which pending task a worker runs next. A worker keeps to one group of tasks (the same
    model, contact parameters and options, :meth:`~closure_nlp.study.tasks.Task.memo_group`)
    until it is done, then starts the next group nobody has started (grid order); when every
    group is started, it helps the one with the most tasks left, from its far end.

    Seeds of a group often meet the same element sets, and a worker's plan memo serves only its
    own tasks: a group spread over workers places such a set once on each."""

    def __init__(self, tasks: Sequence[Task]):
        groups: dict = {}
        for task in tasks:
            groups.setdefault(task.memo_group(), deque()).append(task)
        self.fresh = deque(groups.values())
        self.started: list[deque] = []
        self.current: dict = {}  # worker -> (its group, whether it takes from the front)

    def next(self, worker) -> Task | None:
        group, front = self.current.get(worker, (None, True))
        if not group:
            if self.fresh:
                group, front = self.fresh.popleft(), True
                self.started.append(group)
            else:
                group, front = max(self.started, key=len, default=None), False
                if not group:
                    return None
            self.current[worker] = (group, front)
        return group.popleft() if front else group.pop()

    def __bool__(self) -> bool:
        """Whether any task is left to hand out."""
        return bool(self.fresh) or any(self.started)


def _run_dask(tasks: Sequence[Task], texts, record, runner, client, scheduler, workers) -> int:
    """Run every task, record rows as they complete; returns the number of workers.

    Each worker holds one task per thread (:class:`_Dispatch` picks them; a worker that dies
    takes no queued task with it); a task goes to another worker only if its own is gone. A
    joined cluster without workers runs nothing until some join; a worker that joins later
    gets tasks as the others finish theirs.
    """
    import asyncio
    import uuid

    from distributed import Client, as_completed

    cluster = own_client = None
    if client is None:
        if scheduler:
            try:
                client = own_client = Client(scheduler, timeout=CONNECT_SECONDS)
            except (OSError, TimeoutError) as exc:  # unreachable: the network, not the input
                detail = " ".join(str(exc).split())[:200] or type(exc).__name__
                raise ConnectionError(f"scheduler {scheduler}: cannot connect: {detail}") from None
        else:
            cluster = local_cluster(workers)
            client = own_client = Client(cluster)
            client.register_plugin(_ctrl_c_plugin())
    futures = {}  # future -> (task, the worker it was given to)
    try:
        used = len(client.scheduler_info(n_workers=-1).get("workers", {}))
        # every worker holds each model: one that dies does not take the models with it
        models = {d: client.scatter(text, hash=False, broadcast=True) for d, text in texts.items()}
        tag = uuid.uuid4().hex[:8]
        tries = dict.fromkeys((task.task_id for task in tasks), 0)
        dispatch, held, retry = _Dispatch(tasks), {}, deque()
        completed = as_completed()

        def submit(task, worker=None):
            if models[task.model_digest].status != "finished":  # lost with every holder
                models[task.model_digest] = client.scatter(
                    texts[task.model_digest], hash=False, broadcast=True
                )
            tries[task.task_id] += 1
            key = f"study-{task.task_id}-{tag}-{tries[task.task_id]}"
            # its worker, or any other one if that one is gone (a retry: any worker)
            place = {} if worker is None else {"workers": [worker], "allow_other_workers": True}
            future = client.submit(runner, task, models[task.model_digest], key=key, **place)
            futures[future] = (task, worker)
            held[worker] = held.get(worker, 0) + 1
            completed.add(future)

        def fill():
            while retry:
                submit(retry.popleft())
            info = client.scheduler_info(n_workers=-1).get("workers", {})
            for worker, about in info.items():
                while held.get(worker, 0) < about.get("nthreads", 1):
                    task = dispatch.next(worker)
                    if task is None:
                        return
                    submit(task, worker)

        while True:
            fill()
            if not futures:
                if not (dispatch or retry):
                    break
                client.wait_for_workers(1)  # nothing runs before a worker joins
                continue
            future = next(completed)
            task, worker = futures.pop(future)
            held[worker] -= 1
            try:
                row = future.result()
            except CancelledError as exc:
                # a result lost with its worker after the task ended: not the task's doing
                if tries[task.task_id] <= LOST_RESULT_RETRIES:
                    future.release()
                    retry.append(task)
                    continue
                row = error_row(task, f"{type(exc).__name__}: {exc}")
            except (Exception, asyncio.CancelledError) as exc:  # noqa: BLE001 - a dead worker
                row = error_row(task, f"{type(exc).__name__}: {exc}")
            future.release()
            record(row)
        return used
    except BaseException:
        if futures:  # stopped (Ctrl-C, a failing callback): leave no work behind on the cluster
            client.cancel(list(futures))
        raise
    finally:
        if own_client is not None:
            own_client.close()
        if cluster is not None:
            cluster.close()


def _ctrl_c_plugin():
    """A worker plugin for our own local workers: they ignore SIGINT. Ctrl-C reaches the whole
    process group; the client stops the study and closes the cluster, while a worker that took
    the signal itself printed its asyncio traceback on the user's terminal."""
    from distributed import WorkerPlugin

    class CtrlCForTheClient(WorkerPlugin):
        def setup(self, worker):
            import signal
            import threading

            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return CtrlCForTheClient()


def local_cluster(workers: int | None = None, **kwargs):
    """A ``distributed.LocalCluster`` for studies: ``workers`` processes (default: the cores), one
    thread each, the scheduler's HTTP server on a free port, quiet logs.

    Dask starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which makes the many small
    allocations of CasADi and IPOPT about a third slower; these workers keep glibc's default.
    ``kwargs`` go to ``LocalCluster``.
    """
    import dask
    from distributed import LocalCluster

    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    options = {
        "n_workers": workers or os.cpu_count() or 1,
        "threads_per_worker": 1,
        "processes": True,
        "dashboard_address": ":0",  # any free port: several clusters may run at once
        "silence_logs": logging.ERROR,
        **kwargs,
    }
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
        return LocalCluster(**options)
