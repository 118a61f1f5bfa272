"""Compile (or load) the numeric kernels before the first timed answer."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from closure_nlp import kernels


def warm_up(notify=None, *, rho_only: bool = False, capacity: bool = True) -> float | None:
    """Compile (or load from the disk cache) the kernels called from Python, on tiny sets, so
    that the first answer's ``seconds`` holds none of it.

    Parameters
    ----------
    notify : callable, optional
        ``notify(text)`` is called before a compile (when the disk cache lacks a kernel) and
        after it, with the seconds it took; the library itself never prints (the CLI shows
        it on stderr; the ``closure_nlp`` logger records it too).
    rho_only : bool
        Only the kernels a certified rho runs (:data:`RHO_KERNELS`, the ``rho`` command's),
        not those of slot values, row terms, Wolfe's nearest point of given points and the
        zonotope's capacity (elements and placements): a cold compile of fewer kernels, and
        from the disk cache fewer loads (milliseconds each, at every start).
    capacity : bool
        Also the zonotope's capacity (:data:`CAPACITY_KERNELS`), which only placements of
        contacts that are all frictionless run: False for a command that places none.

    Returns
    -------
    float or None
        Seconds spent compiling, None when everything came from the cache.
    """
    import logging
    import time

    import numpy as np

    compiles = not kernels.cached(rho_only, capacity, notify)
    log = logging.getLogger("closure_nlp")
    where = os.environ.get("NUMBA_CACHE_DIR") or str(Path(kernels.__file__).resolve().parent)
    text = f"compiling the numeric kernels (once; cached in {where})"
    if compiles:
        log.info(text)
        if notify is not None:
            notify(text)
    start = time.perf_counter()  # loading from the cache costs too: done here, not in an answer
    if compiles:
        kernels.compile_in_parallel(rho_only, capacity, notify)
    from closure_nlp.contact.contact_set import Contact, ContactSet
    from closure_nlp.criterion.support_minimum import rho

    normals = np.vstack([np.eye(3), -np.eye(3)])
    closure = ContactSet(tuple(Contact(-n, n) for n in normals[[0, 1, 2, 3]]))
    apart = ContactSet(tuple(Contact(-n, n) for n in normals[[0, 1]]))
    for contact_set in (closure, apart):
        rho(contact_set)
    if not rho_only:
        _warm_the_others(closure, normals, capacity)
    seconds = time.perf_counter() - start
    if not compiles:
        return None
    text = f"compiled the numeric kernels in {seconds:.1f} s"
    log.info(text)
    if notify is not None:
        notify(text)
    return seconds


def _warm_the_others(closure, normals, capacity: bool) -> None:
    """The kernels called from Python that a certified rho does not run (the zonotope's
    capacity only with ``capacity``)."""
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.hull_distance import min_norm_point
    from closure_nlp.criterion.sphere_search import descend

    slots = WrenchSlots.from_contacts(closure)
    U = normals[:1].repeat(2, axis=1)
    slots.slot_values(U)
    slots.row_support(U)
    slots.row_terms(U)
    min_norm_point(slots.support_points(np.vstack([U, -U])))
    descend(slots, np.eye(6)[:2], 1, 0.1)  # the smoothed descent's steps
    if capacity:
        from closure_nlp.criterion.frictionless import frictionless_capacity

        frictionless_capacity(np.ones((1, 7, 6)))
