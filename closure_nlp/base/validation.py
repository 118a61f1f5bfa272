"""Checks at the public boundary: each failure names the field and the offending value.

Accepted magnitudes and limits
------------------------------
Every number the method uses must be representable in every product the engine forms, so the
ranges below are checked on input, not discovered as a NaN answer:

- coordinates (positions, vertices, reference points): ``|x| <= MAX_COORDINATE`` (1e12);
- ``f_max`` in ``SCALE_RANGE`` [1e-12, 1e12], ``torque_scale`` in ``TORQUE_SCALE_RANGE``
  [1e-15, 1e15] (wide enough for ``auto`` = 1 / radius of any accepted part);
- ``mu`` in [0, MAX_MU] (1e6), ``mu_s`` (a length) in [0, MAX_COORDINATE];
- a normal: any finite non-zero 3-vector (it is normalised without overflow);
- at most ``MAX_SET_CONTACTS`` (2000) contacts in a contact set, ``MAX_ELEMENT_CONTACTS`` (32)
  in an element set (one per listed element id), where every selection step solves many sets;
  at most ``MAX_STUDY_TASKS`` (100,000) grid points in a study, seeds in [0, 2**63 - 1].

With these bounds a grasp-matrix entry is at most ``torque_scale * |x|`` ~ 2e27, a local
component ``d = G^T u`` of a unit direction at most ~4e27, a friction square ``mu^2 d^2`` at
most ~2e67 and a support value (times ``f_max``) at most ~5e45: squared once more (norms,
Hessians) that is ~2e91, far from the 1.8e308 of a double. At the small end, products of the
smallest scales (1e-12, 1e-15) stay far above the 2.2e-308 where doubles lose precision.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

MAX_COORDINATE = 1e12
SCALE_RANGE = (1e-12, 1e12)  # f_max
# torque_scale: wider, so that `auto` (1 / the part's radius) of any part within MAX_COORDINATE
# (radius up to 2 sqrt(3) 1e12 about a far reference point) is accepted.
TORQUE_SCALE_RANGE = (1e-15, 1e15)
MAX_MU = 1e6
MAX_MU_S = MAX_COORDINATE

# Limits on the size of the work, checked before any of it starts.
MAX_SET_CONTACTS = 2000  # contacts of one contact set (rho): time grows with the count
MAX_ELEMENT_CONTACTS = 32  # contacts of an element set (eligibility, select, place, plan)
MAX_STUDY_TASKS = 100_000  # grid points of a study (models x parameters x seeds), before expansion
MAX_SEED = 2**63 - 1  # seeds are stored as 64-bit integers


def _check_numbers(value, field: str, depth: int) -> None:
    """Refuse strings, booleans and other non-numbers anywhere in a nested list of ``depth``
    levels (``np.asarray`` would turn ``"25"`` or ``true`` into a number silently)."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise TypeError(f"{field}: expected numbers, got an array of {value.dtype}")
        return
    if depth == 0:
        if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (numbers.Real, np.floating, np.integer)
        ):
            raise TypeError(f"{field}: expected a number, got {_short(value)}")
        return
    if not isinstance(value, (list, tuple)):
        raise TypeError(f"{field}: expected a list of numbers, got {_short(value)}")
    for i, item in enumerate(value):
        # a JSON number (exactly a float or an int, never a bool) passes without the ABC
        # checks: a file of contacts validates a few dozen of them
        if depth > 1 or type(item) not in _PLAIN_NUMBERS:
            _check_numbers(item, f"{field}[{i}]", depth - 1)


_PLAIN_NUMBERS = (float, int)


def _short(value, limit: int = 60) -> str:
    """``repr`` cut to ``limit`` characters: an error line stays one readable line."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _as_float_array(value, field: str, depth: int) -> np.ndarray:
    """A copy of ``value`` as floats: what is validated is never the caller's buffer, which the
    caller may reuse or change afterwards."""
    _check_numbers(value, field, depth)
    try:
        return np.array(value, dtype=float, copy=True)
    except OverflowError:  # an integer beyond the float range, e.g. 10**400 in a JSON file
        raise ValueError(f"{field}: a number is too large for a float") from None
    except (TypeError, ValueError):  # ragged nesting
        raise ValueError(f"{field}: expected a regular list of numbers") from None


def as_vector(value, field: str, length: int, *, limit: float | None = None) -> np.ndarray:
    """Return ``value`` as a finite float vector of ``length`` entries, each ``|x| <= limit``.

    Raises
    ------
    TypeError
        If ``value`` is not a sequence of numbers (strings and booleans included).
    ValueError
        If it has the wrong length, a NaN/infinite entry, or one beyond ``limit``.
    """
    arr = _as_float_array(value, field, 1)
    if arr.shape != (length,):
        raise ValueError(f"{field}: expected {length} numbers, got {_short(value)}")
    _check_finite(arr, field, limit)
    return _read_only(arr)


def as_numbers(value, field: str) -> np.ndarray:
    """A list of finite numbers of any length (e.g. barycentric weights kept in a file)."""
    arr = _as_float_array(value, field, 1)
    if arr.ndim != 1:
        raise ValueError(f"{field}: expected a list of numbers, got {_short(value)}")
    _check_finite(arr, field, None)
    return _read_only(arr)


def is_whole(value) -> bool:
    """A whole number, Python's or numpy's, that is not a boolean."""
    return isinstance(value, (numbers.Integral, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    )


def as_whole(value, field: str, least: int | None = None) -> int:
    """A whole number (``int`` or a numpy integer; not a boolean), ``>= least`` if given."""
    if not is_whole(value):
        raise TypeError(f"{field}: expected a whole number, got {_short(value)}")
    if least is not None and value < least:
        raise ValueError(f"{field}: must be >= {least}, got {value}")
    return int(value)


def as_flag(value, field: str) -> bool:
    """A boolean: ``True``/``False`` or a numpy boolean (never a number or a string)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{field}: expected True or False, got {_short(value)}")
    return bool(value)


def as_id_list(value, field: str) -> list:
    """Element ids in the order given (one per contact): a list, a tuple or a 1-d array; a set
    (no order), a mapping, text or an iterator is refused. The ids are checked by the caller."""
    if isinstance(value, np.ndarray):
        if value.ndim != 1:
            raise TypeError(
                f"{field}: expected a list of element ids, got an array of shape {value.shape}"
            )
        return value.tolist() if value.dtype.kind in "iu" else list(value)
    if isinstance(value, (set, frozenset)):
        raise TypeError(
            f"{field}: expected a list of element ids in contact order, got a "
            f"{type(value).__name__} (no order)"
        )
    if not isinstance(value, (list, tuple, range)):
        raise TypeError(f"{field}: expected a list of element ids, got {_short(value)}")
    return list(value)


def as_element_id(value, field: str) -> int:
    """An element id: a whole number >= 0 (whether the model has it is checked with the model)."""
    if not is_whole(value):
        raise TypeError(f"{field}: expected an element id, got {_short(value)}")
    if value < 0:
        raise ValueError(f"{field}: an element id is >= 0, got {value}")
    return int(value)


def as_points(value, field: str) -> np.ndarray:
    """Return ``value`` as a (k, 3) float array of coordinates (k >= 1), each within range."""
    arr = _as_float_array(value, field, 2)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ValueError(f"{field}: expected a list of [x, y, z] points, got shape {arr.shape}")
    _check_finite(arr, field, MAX_COORDINATE)
    return _read_only(arr)


def as_shaped(value, field: str, shape: tuple) -> np.ndarray:
    """``value`` as an array (not copied) of real numbers in ``shape``: an int fixes an axis'
    length, a str names a free one. For arrays handed to the compiled kernels, which index
    without bounds checks (a short array would be read or written past its end) and take
    float64 (a complex array would lose its imaginary part silently)."""
    arr = np.asarray(value)
    fits = arr.ndim == len(shape) and arr.dtype.kind in "biuf"
    for s, n in zip(shape, arr.shape):  # a loop, not any(): this runs per batch of directions
        fits &= type(s) is not int or s == n
    if not fits:
        wanted = "(" + ", ".join(map(str, shape)) + ("," if len(shape) == 1 else "") + ")"
        got = f"shape {arr.shape}" if arr.dtype.kind in "biuf" else f"an array of {arr.dtype}"
        raise ValueError(f"{field}: expected real numbers of shape {wanted}, got {got}")
    return arr


def as_coordinates(value, field: str) -> np.ndarray:
    """A point [x, y, z] with every ``|x| <= MAX_COORDINATE``."""
    return as_vector(value, field, 3, limit=MAX_COORDINATE)


def _check_finite(arr: np.ndarray, field: str, limit: float | None) -> None:
    if not arr.size:
        return
    top = float(np.abs(arr).max())  # NaN if any is NaN, inf if any is infinite
    if not math.isfinite(top):
        raise ValueError(f"{field}: numbers must be finite")
    if limit is not None and top > limit:
        raise ValueError(
            f"{field}: |coordinate| {top:.3g} is beyond the accepted range [-{limit:g}, {limit:g}]"
        )


def as_unit_vector(value, field: str, length: int = 3) -> np.ndarray:
    """Return a vector of ``length`` entries (a normal; a wrench direction with 6) normalised to
    unit length; reject a zero or non-finite one.

    Divided by its largest component first, so a normal of length 1e200 (whose length
    overflows) or 1e-200 (whose square underflows) keeps its direction exactly.
    """
    arr = as_vector(value, field, length)
    largest = float(np.abs(arr).max())
    if largest == 0.0:
        raise ValueError(f"{field}: zero vector {_short(value)} has no direction")
    if not 1e-150 < largest < 1e150:  # the squares would under/overflow: scale them first
        arr = arr / largest
    return _read_only(arr / np.linalg.norm(arr))


def _read_only(arr: np.ndarray) -> np.ndarray:
    """``arr`` (a copy the validation made) frozen: objects that keep it stay as validated."""
    arr.flags.writeable = False
    return arr


def as_number(
    value,
    field: str,
    *,
    minimum: float | None = None,
    strict: bool = False,
    maximum: float | None = None,
) -> float:
    """Return a finite float, optionally ``>= minimum`` (``> minimum`` when ``strict``) and
    ``<= maximum``."""
    if type(value) not in _PLAIN_NUMBERS and (  # a JSON number skips the ABC checks
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (numbers.Real, np.floating, np.integer))
    ):
        raise TypeError(f"{field}: expected a number, got {_short(value)}")
    try:
        number = float(value)
    except OverflowError:
        raise ValueError(f"{field}: {_short(value)} is too large for a float") from None
    if not np.isfinite(number):
        raise ValueError(f"{field}: must be finite, got {_short(value)}")
    if minimum is not None:
        if strict and not number > minimum:
            raise ValueError(f"{field}: must be > {minimum:g}, got {_short(value)}")
        if not strict and not number >= minimum:
            raise ValueError(f"{field}: must be >= {minimum:g}, got {_short(value)}")
    if maximum is not None and number > maximum:
        low = "" if minimum is None else f"{minimum:g}"
        raise ValueError(f"{field}: {number:g} is beyond the accepted range [{low}, {maximum:g}]")
    return number


def in_range(value, field: str, bounds: tuple[float, float]) -> float:
    """A finite number in ``[bounds[0], bounds[1]]``; the message names the range."""
    number = as_number(value, field)
    lo, hi = bounds
    if not lo <= number <= hi:
        side = f">= {lo:g}" if number < lo else f"<= {hi:g}"
        raise ValueError(
            f"{field}: must be {side} (accepted range [{lo:g}, {hi:g}]), got {_short(value)}"
        )
    return number


def as_f_max(value, field: str) -> float:
    """``f_max``: the normal-force bound, in ``SCALE_RANGE``."""
    return in_range(value, field, SCALE_RANGE)


def as_torque_scale(value, field: str = "torque_scale") -> float:
    """``torque_scale``: the factor on every torque row, in ``TORQUE_SCALE_RANGE``."""
    return in_range(value, field, TORQUE_SCALE_RANGE)


def as_mu(value, field: str) -> float:
    """Coulomb coefficient in [0, MAX_MU]."""
    return in_range(value, field, (0.0, MAX_MU))


def as_mu_s(value, field: str) -> float:
    """Spin coefficient (a length) in [0, MAX_MU_S]."""
    return in_range(value, field, (0.0, MAX_MU_S))


def as_count(value, field: str, limit: int, what: str = "items") -> int:
    """A whole number in [1, limit]; the message names the limit."""
    if not is_whole(value):
        raise TypeError(f"{field}: expected a whole number, got {_short(value)}")
    if not 1 <= value <= limit:
        raise ValueError(f"{field}: {value} {what} is outside the limit 1..{limit}")
    return int(value)


def check_keys(mapping: dict, field: str, allowed: set[str], required: set[str] = frozenset()):
    """Reject unknown keys (a typo silently ignored is a wrong answer) and missing ones."""
    if not isinstance(mapping, dict):
        raise TypeError(f"{field}: expected an object, got {type(mapping).__name__}")
    unknown = sorted(set(mapping) - allowed)
    if unknown:
        raise ValueError(
            f"{field}: unknown key {_short(unknown[0])} (allowed: {', '.join(sorted(allowed))})"
        )
    missing = sorted(required - set(mapping))
    if missing:
        raise ValueError(f"{field}: missing key {missing[0]!r}")


def parse_choice(cls, value, field: str, what: str):
    """A member of the string enum ``cls`` from its value, compared exactly but for the case of
    ASCII letters: stray spaces (a no-break space included) or look-alike letters are refused."""
    if isinstance(value, cls):
        return value
    if isinstance(value, str) and value.isascii():
        try:
            return cls(value.lower())
        except ValueError:
            pass
    names = ", ".join(member.value for member in cls)
    raise ValueError(f"{field}: unknown {what} {_short(value)} (expected one of {names})")


# Length units a model or contact-set file may name (metres per unit); "" when not said. A closed
# list: an unknown unit ("km", "mm ") would silently skip the scale checks of the known ones.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}


def as_units(value, field: str = "units") -> str:
    """``value`` if it is one of ``UNITS`` or ``""``, compared exactly."""
    if not isinstance(value, str):
        raise TypeError(f"{field}: expected text, got {_short(value)}")
    if value != "" and value not in UNITS:
        raise ValueError(
            f"{field}: unknown unit {_short(value)} (expected one of {', '.join(UNITS)}, "
            'or "" when not said)'
        )
    return value


def ascii_number(text: str, field: str, convert=float):
    """A number written in ASCII (``int`` or ``float`` of ``text``): Python also reads
    full-width or other Unicode digits (``"４８"`` as 48), which no file format here allows."""
    if not (isinstance(text, str) and text.isascii()):
        raise ValueError(f"{field}: not a number in {_short(text)} (ASCII digits only)")
    return convert(text)
