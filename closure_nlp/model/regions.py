"""Where contacts may go: regions of a model's elements named by the user, and the model with
every element outside them marked unusable (no step of selection or placement uses it).

A region is an id list, or a SPEC string:

* ``ids:3,7,10-14``: those element ids;
* ``facing:AXIS[:DEG]``: elements whose outward normal (the opposite of the inward one) lies
  within DEG degrees (default 10) of AXIS, written ``+x``, ``-z`` or ``x,y,z``;
* ``box:X0,Y0,Z0,X1,Y1,Z1``: elements whose every vertex lies inside the box (model units, the
  model's frame).

``only`` regions are united, then ``exclude`` regions removed from them (or from every element
when there is no ``only``). The elements stay in the model, with their ids: the part's radius,
and so the automatic torque scale and mu_s, are those of the whole part.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from closure_nlp.base.validation import is_whole
from closure_nlp.model.elements import Model

DEFAULT_FACING_DEG = 10.0
_AXES = {"x": 0, "y": 1, "z": 2}


def region(model: Model, spec, field: str = "region") -> frozenset[int]:
    """The element ids of one region of ``model``: a SPEC string or a sequence of ids."""
    if isinstance(spec, str):
        kind, sep, rest = spec.strip().partition(":")
        kind = kind.strip().lower()
        if not sep or kind not in _KINDS:
            raise ValueError(
                f"{field}: expected ids:I,J,A-B, facing:AXIS[:DEG] or box:X0,Y0,Z0,X1,Y1,Z1, "
                f"got {spec!r}"
            )
        return frozenset(_KINDS[kind](model, rest, f"{field} ({kind})"))
    try:
        ids = list(spec)
    except TypeError:
        raise TypeError(f"{field}: expected a SPEC string or element ids, got {spec!r}") from None
    return frozenset(model.check_id(e, f"{field}[{k}]") for k, e in enumerate(ids))


def excluded_elements(model: Model, only=(), exclude=()) -> tuple[int, ...]:
    """Ids of the elements outside the ``only`` regions (all, when none is given) or inside an
    ``exclude`` region, ascending."""
    only, exclude = _specs(only, "only"), _specs(exclude, "exclude")
    allowed = set(range(len(model)))
    if only:
        allowed = set().union(*(region(model, s, f"only[{k}]") for k, s in enumerate(only)))
    for k, spec in enumerate(exclude):
        allowed -= region(model, spec, f"exclude[{k}]")
    return tuple(sorted(set(range(len(model))) - allowed))


def with_exclusions(model: Model, only=(), exclude=()) -> Model:
    """``model`` with the elements :func:`excluded_elements` names marked unusable (beside those
    it already has)."""
    return marked_unusable(model, excluded_elements(model, only, exclude))


def marked_unusable(model: Model, ids) -> Model:
    """``model`` with the elements ``ids`` marked unusable too (itself when there are none)."""
    if not ids:
        return model
    return replace(model, unusable=tuple(sorted(set(model.unusable) | set(ids))))


def _specs(value, field: str) -> tuple:
    """One region or a list of them, as a tuple of regions."""
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    value = tuple(value)
    if value and all(is_whole(v) and not isinstance(v, bool) for v in value):
        return (value,)  # one list of ids
    return value


def _ids(model: Model, text: str, field: str) -> set[int]:
    out = set()
    for part in text.split(","):
        part = part.strip()
        first, dash, last = part.partition("-")
        try:
            lo, hi = int(first), int(last) if dash else int(first)
        except ValueError:
            raise ValueError(f"{field}: expected ids or ranges A-B, got {part!r}") from None
        if hi < lo:
            raise ValueError(f"{field}: a range must not run backwards, got {part!r}")
        model.check_id(lo, field)
        model.check_id(hi, field)
        out.update(range(lo, hi + 1))
    return out


def _facing(model: Model, text: str, field: str) -> set[int]:
    axis_text, _, degrees_text = text.partition(":")  # no axis form holds a colon
    axis = _axis(axis_text, field)
    degrees = DEFAULT_FACING_DEG
    if degrees_text:
        try:
            degrees = float(degrees_text)
        except ValueError:
            degrees = float("nan")
        if not 0.0 <= degrees <= 180.0:
            raise ValueError(f"{field}: expected degrees in [0, 180], got {degrees_text!r}")
    outward = -np.array([e.inward_normal for e in model.elements])
    cosines = outward @ axis
    return set(np.flatnonzero(cosines >= np.cos(np.radians(degrees)) - 1e-12).tolist())


def _axis(text: str, field: str) -> np.ndarray:
    text = text.strip().lower()
    if len(text) in (1, 2) and text[-1] in _AXES and text[:-1] in ("", "+", "-"):
        axis = np.zeros(3)
        axis[_AXES[text[-1]]] = -1.0 if text.startswith("-") else 1.0
        return axis
    try:
        axis = np.array([float(v) for v in text.split(",")])
    except ValueError:
        axis = np.zeros(0)
    norm = float(np.linalg.norm(axis)) if axis.shape == (3,) else 0.0
    if not (np.isfinite(norm) and norm > 0.0):
        raise ValueError(f"{field}: expected an axis +x, -z or x,y,z (non-zero), got {text!r}")
    return axis / norm


def _box(model: Model, text: str, field: str) -> set[int]:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        values = np.zeros(0)
    if values.shape != (6,) or not np.all(np.isfinite(values)):
        raise ValueError(f"{field}: expected six numbers X0,Y0,Z0,X1,Y1,Z1, got {text!r}")
    lo, hi = np.minimum(values[:3], values[3:]), np.maximum(values[:3], values[3:])
    return {
        i for i, e in enumerate(model.elements) if np.all((e.vertices >= lo) & (e.vertices <= hi))
    }


_KINDS = {"ids": _ids, "facing": _facing, "box": _box}


__all__ = ["excluded_elements", "marked_unusable", "region", "with_exclusions"]
