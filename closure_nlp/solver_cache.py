"""Caches bounded by recency. Built NLP solvers: building a CasADi solver costs tens to hundreds
of ms and it holds MBs, so each cache keeps the most recently used shapes only; and plan's memo
of iterative runs and placements (:func:`closure_nlp.planning.plan`), a few KB each."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def cached(cache: dict, key, build: Callable[[], T], limit: int) -> T:
    """``cache[key]``, made by ``build()`` when missing. The dict's order is its recency (a hit
    is re-inserted last); a new entry first drops the least recently used ones beyond ``limit``.
    A plain dict does, so callers may share one."""
    value = cache.pop(key, None)
    if value is None:
        value = build()
        while len(cache) >= limit:
            del cache[next(iter(cache))]
    cache[key] = value
    return value
