"""The cores a process may use, and the ``workers`` argument that asks for them."""

from __future__ import annotations

import os

from closure_nlp.base.validation import is_whole

MAX_WORKERS = 256  # threads or processes one call may ask for


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def checked_workers(workers, name: str = "workers") -> int:
    """``workers`` as an int in ``[1, MAX_WORKERS]``; None: :func:`available_cores`."""
    if workers is None:
        return available_cores()
    if isinstance(workers, bool) or not is_whole(workers) or not 1 <= workers <= MAX_WORKERS:
        raise ValueError(f"{name}: expected an integer in [1, {MAX_WORKERS}], got {workers!r}")
    return int(workers)
