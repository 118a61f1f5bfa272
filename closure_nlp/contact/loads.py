"""Load cases: the wrenches a part must hold (LOADS.json).

A case is one force at a point with an optional torque, or several such ``components`` applied
together. Points are in the model's frame and units; forces in the file's force unit, which is
also the unit of every contact's ``f_max`` when loads are given (the numbers are used as given).
A case becomes one wrench about the contact set's reference point, its torque rows times the set's
``torque_scale``, like the contacts' own wrenches (:mod:`closure_nlp.contact.contact_set`).
"""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike

import numpy as np

from closure_nlp.base.files import load_json
from closure_nlp.base.validation import as_coordinates, as_vector, check_keys

MAX_CASES = 1000
MAX_COMPONENTS = 1000
LOAD_LIMIT = 1e15  # |force| or |torque| component


@dataclass(frozen=True, eq=False)
class LoadComponent:
    """A force (3,) at ``point`` (3,) (``None``: the reference point) and a free torque (3,)."""

    force: np.ndarray
    point: np.ndarray | None
    torque: np.ndarray


@dataclass(frozen=True, eq=False)
class LoadCase:
    """One named case: its components act together."""

    name: str
    components: tuple[LoadComponent, ...]

    def wrench(self, reference_point=None, torque_scale: float = 1.0) -> np.ndarray:
        """The case's resultant (6,): force, then ``torque_scale`` times its moment about
        ``reference_point`` (default the origin) plus its free torques."""
        ref = np.zeros(3) if reference_point is None else np.asarray(reference_point, float)
        force, moment = np.zeros(3), np.zeros(3)
        for c in self.components:
            arm = np.zeros(3) if c.point is None else c.point - ref
            force += c.force
            moment += np.cross(arm, c.force) + c.torque
        return np.concatenate([force, torque_scale * moment])

    def to_dict(self) -> dict:
        parts = []
        for c in self.components:
            part = {"force": c.force.tolist()}
            if c.point is not None:
                part["point"] = c.point.tolist()
            if c.torque.any():
                part["torque"] = c.torque.tolist()
            parts.append(part)
        if len(parts) == 1:
            return {"name": self.name, **parts[0]}
        return {"name": self.name, "components": parts}


@dataclass(frozen=True, eq=False)
class Loads:
    """The cases of a LOADS.json and their force unit (``""`` when not said)."""

    cases: tuple[LoadCase, ...]
    force_unit: str = ""

    def __len__(self) -> int:
        return len(self.cases)

    def wrenches(self, reference_point=None, torque_scale: float = 1.0) -> np.ndarray:
        """(cases, 6): each case's :meth:`LoadCase.wrench`."""
        return np.array([c.wrench(reference_point, torque_scale) for c in self.cases])

    def to_dict(self) -> dict:
        units = {"units": {"force": self.force_unit}} if self.force_unit else {}
        return {**units, "loads": [c.to_dict() for c in self.cases]}


_COMPONENT_KEYS = {"force", "point", "torque"}


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _component(data, field: str) -> LoadComponent:
    check_keys(data, field, _COMPONENT_KEYS, {"force"})
    force = as_vector(data["force"], f"{field}.force", 3, limit=LOAD_LIMIT)
    point = as_coordinates(data["point"], f"{field}.point") if "point" in data else None
    torque = as_vector(data.get("torque", [0.0, 0.0, 0.0]), f"{field}.torque", 3, limit=LOAD_LIMIT)
    return LoadComponent(force, point, torque)


def _case(data, field: str) -> LoadCase:
    if not isinstance(data, dict):
        raise TypeError(f"{field}: expected an object, got {_short(data)}")
    if "components" in data:
        check_keys(data, field, {"name", "components"}, {"name"})
        parts = data["components"]
        if not isinstance(parts, list) or not parts or len(parts) > MAX_COMPONENTS:
            raise ValueError(
                f"{field}.components: expected a list of 1 to {MAX_COMPONENTS} components, "
                f"got {_short(parts)}"
            )
        components = tuple(_component(p, f"{field}.components[{j}]") for j, p in enumerate(parts))
    else:
        check_keys(data, field, {"name"} | _COMPONENT_KEYS, {"name", "force"})
        components = (_component({k: v for k, v in data.items() if k != "name"}, field),)
    name = data["name"]
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"{field}.name: expected a non-empty text, got {_short(name)}")
    case = LoadCase(name, components)
    at_reference = sum(c.force for c in components if c.point is None)
    if not case.wrench().any() and not np.any(at_reference):  # zero about every point
        raise ValueError(f"{field}: case {name!r} is zero (no force, no torque)")
    return case


def loads_from_dict(data) -> Loads:
    """:class:`Loads` from the parsed JSON (``ValueError``/``TypeError`` naming the field)."""
    check_keys(data, "loads file", {"units", "loads"}, {"loads"})
    unit = ""
    if "units" in data:
        check_keys(data["units"], "units", {"force"})
        unit = data["units"].get("force", "")
        if not isinstance(unit, str):
            raise TypeError(f"units.force: expected text, got {_short(unit)}")
    cases = data["loads"]
    if not isinstance(cases, list) or not cases or len(cases) > MAX_CASES:
        raise ValueError(f"loads: expected a list of 1 to {MAX_CASES} cases, got {_short(cases)}")
    parsed = tuple(_case(c, f"loads[{i}]") for i, c in enumerate(cases))
    seen: set[str] = set()
    for i, case in enumerate(parsed):
        if case.name in seen:
            raise ValueError(f"loads[{i}].name: duplicate name {case.name!r}")
        seen.add(case.name)
    return Loads(parsed, unit)


def as_loads(value) -> Loads:
    """:class:`Loads` from itself, a LOADS.json file's path, a dict as in LOADS.json, or a list
    of cases."""
    if isinstance(value, Loads):
        return value
    if isinstance(value, (str, PathLike)):
        return load_loads(value)
    if isinstance(value, list):
        value = {"loads": value}
    return loads_from_dict(value)


def load_loads(path) -> Loads:
    """Read and validate a LOADS.json file."""
    return loads_from_dict(load_json(path))
