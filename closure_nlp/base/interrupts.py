"""Ctrl-C during a CasADi solve: a ``KeyboardInterrupt`` once Python code runs again.

CasADi polls Python's signal handlers during IPOPT and, when one raises, stops the solver and
returns its last iterate as if it were the answer, status and all: the interrupt is lost and a
half-solved value looks like a result. Inside :func:`interruptible` the SIGINT handler only notes
an interrupt that lands while CasADi (or another package that swallows interrupts,
:data:`SWALLOWING_PACKAGES`) is on the stack and raises as soon as Python code runs outside it
again (a 2 ms timer), or when the block ends. The CLI holds it around a whole command; every
solver call of the API holds it too, so library users get the interrupt as well. Nested uses
cost nothing.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import signal
import threading

_active = threading.local()


@contextlib.contextmanager
def interruptible():
    """Ctrl-C raises ``KeyboardInterrupt`` in Python code, never inside a CasADi call.

    Only in the main thread (signal handlers live there); elsewhere, and inside another
    ``interruptible`` block, it does nothing.
    """
    if threading.current_thread() is not threading.main_thread() or getattr(_active, "on", False):
        yield
        return
    folders = _swallowing_folders(SWALLOWING_PACKAGES)
    interrupted: list[int] = []
    silenced: list[bool] = []

    def on_signal(signum, frame):
        if signum != signal.SIGALRM or interrupted:
            if _inside(frame, folders):
                interrupted.append(signum)
                signal.setitimer(signal.ITIMER_REAL, 0.002)
                return
            signal.setitimer(signal.ITIMER_REAL, 0)
            silenced.append(True)
            logging.disable(logging.CRITICAL)  # Dask's teardown logs are not for the user now
            raise KeyboardInterrupt

    # Not SIGTERM: a Python handler runs only between bytecodes, so `kill` or `timeout` would
    # wait for a long C call (qhull, a big numpy product) instead of ending the process.
    signums = (signal.SIGINT, signal.SIGALRM)
    saved = [signal.signal(signum, on_signal) for signum in signums]
    _active.on = True
    try:
        yield
        if interrupted:  # noted inside CasADi; the timer had not fired yet
            raise KeyboardInterrupt
    finally:
        _active.on = False
        if interrupted:
            signal.setitimer(signal.ITIMER_REAL, 0)
        for signum, handler in zip(signums, saved):
            signal.signal(signum, handler)
        if silenced:  # only what this block disabled: every solve passes here
            logging.disable(logging.NOTSET)  # an in-process caller gets its logging back


# Packages that catch every exception somewhere, a KeyboardInterrupt included: CasADi inside a
# solve (see above), trimesh round its optional imports (an interrupt while it is imported was
# lost, and the command ran on to its end).
SWALLOWING_PACKAGES = ("casadi", "trimesh")


@functools.cache  # every IPOPT solve of the API enters interruptible(): a path search is 0.1 ms
def _swallowing_folders(names: tuple[str, ...]) -> tuple[str, ...]:
    """The folders of the packages ``names`` that are installed (none imported here)."""
    import importlib.util

    folders = []
    for name in names:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.submodule_search_locations:
            folders.extend(os.path.join(p, "") for p in spec.submodule_search_locations)
    return tuple(folders)


def _inside(frame, folders: tuple[str, ...]) -> bool:
    """Whether a frame of ``frame``'s stack runs code from one of ``folders``."""
    while frame is not None:
        if frame.f_code.co_filename.startswith(folders):
            return True
        frame = frame.f_back
    return False


def leave_to_parent() -> None:
    """In a worker process: Ctrl-C (sent to the whole process group) is ignored, and
    :func:`interruptible` does nothing; the parent stops the workers itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _active.on = True
