"""Checks at the public boundary: each failure names the field and the offending value."""

from __future__ import annotations

import numbers

import numpy as np


def as_vector(value, field: str, length: int) -> np.ndarray:
    """Return ``value`` as a finite float vector of ``length`` entries.

    Raises
    ------
    TypeError
        If ``value`` is not a sequence of numbers.
    ValueError
        If it has the wrong length or a NaN/infinite entry.
    """
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise TypeError(f"{field}: expected {length} numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{field}: expected {length} numbers, got {value!r}") from None
    if arr.shape != (length,):
        raise ValueError(f"{field}: expected {length} numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{field}: numbers must be finite, got {value!r}")
    return arr


def as_unit_vector(value, field: str) -> np.ndarray:
    """Return a 3-vector normalised to unit length; reject a zero or non-finite one."""
    arr = as_vector(value, field, 3)
    norm = float(np.linalg.norm(arr))
    if not norm > 1e-12:
        raise ValueError(f"{field}: zero vector {value!r} has no direction")
    return arr / norm


def as_number(value, field: str, *, minimum: float | None = None, strict: bool = False) -> float:
    """Return a finite float, optionally ``>= minimum`` (``> minimum`` when ``strict``)."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{field}: expected a number, got {value!r}")
    number = float(value)
    if not np.isfinite(number):
        raise ValueError(f"{field}: must be finite, got {value!r}")
    if minimum is not None:
        if strict and not number > minimum:
            raise ValueError(f"{field}: must be > {minimum:g}, got {value!r}")
        if not strict and not number >= minimum:
            raise ValueError(f"{field}: must be >= {minimum:g}, got {value!r}")
    return number


def check_keys(mapping: dict, field: str, allowed: set[str], required: set[str] = frozenset()):
    """Reject unknown keys (a typo silently ignored is a wrong answer) and missing ones."""
    if not isinstance(mapping, dict):
        raise TypeError(f"{field}: expected an object, got {type(mapping).__name__}")
    unknown = sorted(set(mapping) - allowed)
    if unknown:
        raise ValueError(
            f"{field}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(allowed))})"
        )
    missing = sorted(required - set(mapping))
    if missing:
        raise ValueError(f"{field}: missing key {missing[0]!r}")


def parse_choice(cls, value, field: str, what: str):
    """A member of the string enum ``cls`` from its value (case and spaces ignored)."""
    if isinstance(value, cls):
        return value
    if isinstance(value, str):
        try:
            return cls(value.strip().lower())
        except ValueError:
            pass
    names = ", ".join(member.value for member in cls)
    raise ValueError(f"{field}: unknown {what} {value!r} (expected one of {names})")
