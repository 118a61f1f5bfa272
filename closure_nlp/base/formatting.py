"""Numbers as a person reads them: as many digits as the result knows, never float noise.

A certified value is known within its bracket ``[lo, hi]``, so it is printed to the last decimal
the bracket pins down, and the bracket with one more; a length is printed to the accuracy of the
model it lies on (its ``tolerance`` when the file gives one, otherwise 1e-4 of the part's radius,
so the same part in metres and in millimetres shows the same digits). A value that rounds to
zero is printed without a sign.

However tight the bracket or small the tolerance (a certificate to 1e-15), a number never shows
more than ``MAX_SIGNIFICANT`` significant digits: of itself for a dimensionless value such as
rho (one below 1e-6 is zero to six decimals), of the part's radius for a length (the same
digits in metres and in millimetres).
"""

from __future__ import annotations

import math

RELATIVE_LENGTH_ACCURACY = 1e-4  # of the part's radius, for models without a tolerance
MAX_DECIMALS = 12
MAX_SIGNIFICANT = 7
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


def significant_decimals(scale: float) -> int:
    """Decimals that show ``MAX_SIGNIFICANT`` significant digits of a number of size ``scale``."""
    if not scale > 0 or not math.isfinite(scale):
        return MAX_DECIMALS
    return min(max(0, MAX_SIGNIFICANT - 1 - math.floor(math.log10(scale))), MAX_DECIMALS)


def _scale(*values) -> float:
    """The size the significant digits of dimensionless numbers count from: the largest of them,
    or 1 when they are all below ``10**-(MAX_SIGNIFICANT - 1)`` (zero to the six decimals a
    person reads: ``0.000000``, not twelve zeros from a 1e-15 bracket around it)."""
    scale = max([0.0, *(abs(float(v)) for v in values if math.isfinite(float(v)))])
    return scale if scale >= 10.0 ** -(MAX_SIGNIFICANT - 1) else 1.0


def certain(value: float, bounds=None) -> str:
    """A certified value to its bracket's digits (6 significant ones without bounds), at most
    ``MAX_SIGNIFICANT`` significant digits of its scale."""
    if bounds is None:
        return f"{value:.{DEFAULT_SIGNIFICANT}g}"
    cap = significant_decimals(_scale(value, *bounds))
    return fixed(value, min(bracket_decimals(bounds), cap))


def bracket(bounds) -> tuple[str, str]:
    """``lo`` and ``hi`` with one decimal more than the value, so that they differ (unless that
    digit is past ``MAX_SIGNIFICANT``: a bracket tighter than that prints as one number)."""
    lo, hi = bounds
    cap = significant_decimals(_scale(lo, hi))
    decimals = min(bracket_decimals(bounds) + 1, MAX_DECIMALS, cap)
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


def _length_decimals(values, model) -> int:
    """Decimals of lengths on ``model``: its accuracy's, at most ``MAX_SIGNIFICANT`` significant
    digits of the part's radius (or of the largest value, a point far from the origin)."""
    scale = max([float(getattr(model, "radius", 0.0) or 0.0), *(abs(float(v)) for v in values)])
    return min(length_decimals(model_accuracy(model)), significant_decimals(scale))


def length(value: float, model) -> str:
    """One coordinate or length on ``model``, to the model's accuracy."""
    return fixed(value, _length_decimals([value], model))


def lengths(values, model, sep: str = " ") -> str:
    values = [float(v) for v in values]
    decimals = _length_decimals(values, model)
    return sep.join(fixed(v, decimals) for v in values)


__all__ = [
    "bracket",
    "bracket_decimals",
    "certain",
    "fixed",
    "length",
    "length_decimals",
    "lengths",
    "model_accuracy",
    "significant_decimals",
]
