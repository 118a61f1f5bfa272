"""Caches bounded by recency, and caches kept per thread. Built NLP solvers: building a CasADi
solver costs tens to hundreds of ms and it holds MBs, so each cache keeps the most recently used
shapes only; and plan's memo of iterative runs and placements
(:func:`closure_nlp.planning.plan.plan`),
a few KB each.

A built CasADi solver must not run in two threads at once: four threads calling ``rho`` on one
shared solver cache crashed the process (segmentation faults inside IPOPT). Each thread therefore
builds its own solvers (:class:`PerThread`) rather than sharing one cache behind a lock, which
would run every IPOPT solve one at a time: CasADi releases the interpreter during a solve, so
threads with their own solvers run IPOPT in parallel, and that outweighs building the solvers
once per thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")

# Options of the NLP solvers these caches hold (exchange, support minimum). CasADi also builds,
# unless told not to, the gradient of the Lagrangian with respect to the parameters, for their
# multipliers ``lam_p``, which nothing here reads: without it the NLPs build faster, and IPOPT
# takes the same iterates to the bit.
NLPSOL_OPTIONS = {
    "print_time": False,
    "error_on_fail": False,
    "calc_lam_p": False,
    "no_nlp_grad": True,
}

_LOCK = threading.Lock()  # guards the dict operations of cached(), never a build


def cached(cache: dict, key, build: Callable[[], T], limit: int) -> T:
    """``cache[key]``, made by ``build()`` when missing. The dict's order is its recency (a hit
    is re-inserted last); a new entry first drops the least recently used ones beyond ``limit``.
    A plain dict does, so callers may share one, also between threads: two threads missing the
    same key both build it (builds are deterministic), and the later one's value is kept."""
    with _LOCK:
        value = cache.pop(key, None)
        if value is not None:
            cache[key] = value
            return value
    value = build()
    with _LOCK:
        cache.pop(key, None)
        while len(cache) >= limit:
            del cache[next(iter(cache))]
        cache[key] = value
    return value


class PerThread(Generic[T]):
    """One object per thread, made by ``factory()`` on a thread's first :meth:`get`.

    Pickled (sent to another process) it arrives empty: what it holds is rebuilt there.
    """

    def __init__(self, factory: Callable[[], T] = dict):
        self.factory = factory
        self._local = threading.local()

    def get(self) -> T:
        """This thread's object."""
        try:
            return self._local.value
        except AttributeError:
            self._local.value = self.factory()
            return self._local.value

    def __reduce__(self):
        return (PerThread, (self.factory,))


__all__ = ["NLPSOL_OPTIONS", "PerThread", "cached"]
