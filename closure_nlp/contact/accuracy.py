"""The model's accuracy: how far the real part's contact points and normals may lie from the
file's (``"tolerance": {"position": LENGTH, "normal_deg": DEGREES}`` in model and contact-set
files; :mod:`closure_nlp.criterion.robustness` turns it into robust verdicts)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ModelTolerance:
    """How far the real part's contact points (``position``, model units) and normals
    (``normal_deg``, degrees) may lie from the file's. Zero: the file is the part."""

    position: float = 0.0
    normal_deg: float = 0.0

    def __post_init__(self) -> None:
        for name, top in (("position", np.inf), ("normal_deg", 90.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise TypeError(f"tolerance.{name}: expected a number, got {value!r}")
            if not 0.0 <= value < top:
                raise ValueError(
                    f"tolerance.{name}: expected a number in [0, {top:g}), got {value!r}"
                )
            object.__setattr__(self, name, float(value))

    def __bool__(self) -> bool:
        return self.position > 0.0 or self.normal_deg > 0.0

    def to_dict(self) -> dict:
        return {"position": self.position, "normal_deg": self.normal_deg}

    def merged(self, position=None, normal_deg=None) -> ModelTolerance:
        """This tolerance with the given values (command-line flags) in place of its own."""
        return ModelTolerance(
            self.position if position is None else position,
            self.normal_deg if normal_deg is None else normal_deg,
        )


NO_TOLERANCE = ModelTolerance()


def tolerance_from_dict(data, field: str = "tolerance") -> ModelTolerance:
    """``{"position": LENGTH, "normal_deg": DEGREES}`` (either optional) of a file; absent: none."""
    if data is None:
        return NO_TOLERANCE
    if not isinstance(data, dict):
        raise TypeError(f"{field}: expected an object with position and normal_deg, got {data!r}")
    unknown = set(data) - {"position", "normal_deg"}
    if unknown:
        raise ValueError(f"{field}: unknown key(s) {sorted(unknown)} (position, normal_deg)")
    try:
        return ModelTolerance(data.get("position", 0.0), data.get("normal_deg", 0.0))
    except (TypeError, ValueError) as exc:
        raise type(exc)(str(exc).replace("tolerance.", f"{field}.")) from None


__all__ = ["NO_TOLERANCE", "ModelTolerance", "tolerance_from_dict"]
