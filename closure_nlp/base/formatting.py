"""Numbers as a person reads them: as many digits as the result knows, never float noise.

A certified value is known within its bracket ``[lo, hi]``, so it is printed to the last decimal
the bracket pins down, and the bracket with one more; a length is printed to the accuracy of the
model it lies on (its ``tolerance`` when the file gives one, otherwise 1e-4 of the part's radius,
so the same part in metres and in millimetres shows the same digits). A value that rounds to
zero is printed without a sign.
"""

from __future__ import annotations

import math

RELATIVE_LENGTH_ACCURACY = 1e-4  # of the part's radius, for models without a tolerance
MAX_DECIMALS = 12
DEFAULT_SIGNIFICANT = 6  # a value without bounds


def fixed(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals; ``-0.000`` is written ``0.000``."""
    text = f"{value:.{max(decimals, 0)}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def bracket_decimals(bounds) -> int:
    """Decimals the bracket ``(lo, hi)`` pins down: the first decimal its width leaves open."""
    lo, hi = (float(b) for b in bounds)
    width = hi - lo
    floor = 10.0**-MAX_DECIMALS * max(1.0, abs(lo), abs(hi))
    return min(max(0, math.floor(-math.log10(max(width, floor)))), MAX_DECIMALS)


def certain(value: float, bounds=None) -> str:
    """A certified value to its bracket's digits (6 significant ones without bounds)."""
    if bounds is None:
        return f"{value:.{DEFAULT_SIGNIFICANT}g}"
    return fixed(value, bracket_decimals(bounds))


def bracket(bounds) -> tuple[str, str]:
    """``lo`` and ``hi`` with one decimal more than the value, so that they differ."""
    decimals = min(bracket_decimals(bounds) + 1, MAX_DECIMALS)
    lo, hi = bounds
    return fixed(lo, decimals), fixed(hi, decimals)


def length_decimals(accuracy: float) -> int:
    """Decimals of a length known to ``accuracy`` (in the same unit)."""
    if not accuracy > 0 or not math.isfinite(accuracy):
        return 4
    return min(max(0, math.ceil(-math.log10(accuracy))), MAX_DECIMALS)


def model_accuracy(model) -> float:
    """How well ``model``'s positions are known: its ``tolerance`` position when it has one,
    otherwise ``RELATIVE_LENGTH_ACCURACY`` x its radius."""
    tolerance = getattr(model, "tolerance", None)
    position = getattr(tolerance, "position", None)
    if isinstance(tolerance, dict):
        position = tolerance.get("position")
    if position:
        return float(position)
    return RELATIVE_LENGTH_ACCURACY * float(model.radius)


def length(value: float, model) -> str:
    """One coordinate or length on ``model``, to the model's accuracy."""
    return fixed(value, length_decimals(model_accuracy(model)))


def lengths(values, model, sep: str = " ") -> str:
    decimals = length_decimals(model_accuracy(model))
    return sep.join(fixed(float(v), decimals) for v in values)


__all__ = [
    "bracket",
    "bracket_decimals",
    "certain",
    "fixed",
    "length",
    "length_decimals",
    "lengths",
    "model_accuracy",
]
