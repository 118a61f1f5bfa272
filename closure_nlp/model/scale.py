"""The part's scale: torque scale ``auto``, the default spin coefficient, and scale warnings.

A wrench mixes forces (no length) and torques (force x length), so rho depends on the unit of the
model unless torques are divided by a length of the part. ``auto`` takes the radius R of the
part's bounding sphere about the reference point (:attr:`Model.radius`): the same part in metres
and in millimetres then has the same grasp matrices, and the same rho, once lengths given by the
user (``mu_s``) are scaled alike; the default ``mu_s`` is ``MU_S_FRACTION * R`` for that reason.
"""

from __future__ import annotations

from dataclasses import dataclass

from closure_nlp.base.validation import MAX_ELEMENT_CONTACTS, UNITS, as_count, as_torque_scale
from closure_nlp.contact.contact_set import (
    DEFAULT_F_MAX,
    DEFAULT_MU,
    DEFAULT_MU_S,
    ContactSpec,
    ContactType,
    per_contact,
)
from closure_nlp.model.elements import Model

AUTO = "auto"
MU_S_FRACTION = 0.01  # default spin coefficient of a model's soft fingers: 1% of its radius
ROW_RATIO_LIMIT = 100.0  # torque rows this many times larger or smaller than force rows: warn
PART_SIZE_METRES = (1e-3, 10.0)  # radius of a part that a robot grasps or a fixture holds


def is_auto(value) -> bool:
    return value is None or (isinstance(value, str) and value.strip().lower() == AUTO)


def auto_torque_scale(model: Model) -> float:
    """``1 / R``, R the radius of the part's bounding sphere about its reference point."""
    radius = model.radius
    if not radius > 0:
        raise ValueError(
            "torque_scale: auto needs a part of non-zero size (every vertex is at the reference "
            "point); give a number"
        )
    return as_torque_scale(1.0 / radius)


def default_mu_s(model: Model) -> float:
    """``MU_S_FRACTION * R`` in the model's units (soft fingers' spin coefficient is a length)."""
    return MU_S_FRACTION * model.radius


@dataclass(frozen=True)
class ModelScale:
    """What a model command used: every number a report needs to be reproduced."""

    units: str
    reference_point: tuple[float, float, float]
    radius: float
    torque_scale: float
    torque_scale_auto: bool
    mu_s: float | tuple[float, ...]
    mu_s_auto: bool

    def to_dict(self) -> dict:
        return {
            "units": self.units,
            "reference_point": list(self.reference_point),
            "radius": self.radius,
            "torque_scale": self.torque_scale,
            "torque_scale_auto": self.torque_scale_auto,
            "mu_s": list(self.mu_s) if isinstance(self.mu_s, tuple) else self.mu_s,
            "mu_s_auto": self.mu_s_auto,
        }

    def text(self, soft_fingers: bool = True) -> str:
        """One line; mu_s only where it plays a part (``soft_fingers``: some contact is one)."""
        unit = f" {self.units}" if self.units else ""
        point = ", ".join(f"{x:.6g}" for x in self.reference_point)
        ts = f"torque scale {self.torque_scale:.6g}"
        if self.torque_scale_auto:
            ts += f" (auto: 1 / {self.radius:.6g}{unit}, the part's radius)"
        mu_s = self.mu_s if isinstance(self.mu_s, tuple) else (self.mu_s,)
        ms = "mu_s " + ",".join(f"{v:.6g}" for v in mu_s) + unit
        if self.mu_s_auto:
            ms += f" (auto: {MU_S_FRACTION:g} x radius)"
        return f"torques about [{point}]{unit}; {ts}" + (f"; {ms}" if soft_fingers else "")


def resolve(model: Model, torque_scale=AUTO, mu_s=AUTO) -> ModelScale:
    """The torque scale and ``mu_s`` to use on ``model``: numbers kept, ``auto`` resolved."""
    ts_auto, ms_auto = is_auto(torque_scale), is_auto(mu_s)
    ts = auto_torque_scale(model) if ts_auto else as_torque_scale(torque_scale)
    if ms_auto:
        ms = default_mu_s(model)
    elif isinstance(mu_s, (list, tuple)):
        ms = tuple(float(v) for v in mu_s)
    else:
        ms = float(mu_s)
    return ModelScale(
        model.units,
        tuple(float(x) for x in model.reference_point),
        model.radius,
        ts,
        ts_auto,
        ms,
        ms_auto,
    )


def units_warning(radius: float, units: str) -> str | None:
    """A line when a part of this radius is implausible in ``units`` (a file in another unit)."""
    if units not in UNITS or not radius > 0:
        return None
    metres = radius * UNITS[units]
    lo, hi = PART_SIZE_METRES
    if lo <= metres <= hi:
        return None
    size = "small" if metres < lo else "large"
    return (
        f"the part's radius is {radius:.3g} {units} ({metres:.3g} m), far too {size} for a part "
        f"held by a hand or a fixture: is the mesh in another unit than {units}?"
    )


def scale_warnings(scale: ModelScale, types=()) -> list[str]:
    """Lines for stderr where the numbers look wrong for the part's size (never silent)."""
    out = []
    message = units_warning(scale.radius, scale.units)
    if message:
        out.append(message)
    ratio = scale.torque_scale * scale.radius
    if not scale.torque_scale_auto and not (1 / ROW_RATIO_LIMIT <= ratio <= ROW_RATIO_LIMIT):
        out.append(
            f"torque scale {scale.torque_scale:.3g} x radius {scale.radius:.3g} = {ratio:.3g}: "
            "torque rows and force rows differ by more than "
            f"{ROW_RATIO_LIMIT:g}x, so rho mostly measures one of them; --torque-scale auto "
            "makes them even"
        )
    soft = [str(t).lower() in ("sfcl", "sfce") for t in types] if types else []
    mu_s = scale.mu_s if isinstance(scale.mu_s, tuple) else (scale.mu_s,) * max(len(soft), 1)
    if any(soft) and not scale.mu_s_auto:
        worst = max(m for m, s in zip(mu_s, soft) if s)
        if worst > scale.radius:
            out.append(
                f"mu_s {worst:.3g} exceeds the part's radius {scale.radius:.3g} (mu_s is a length "
                "in the model's units): the soft fingers resist almost any spin; leave --mu-s "
                f"out for {MU_S_FRACTION:g} x radius"
            )
    return out


def contact_specs(
    count: int,
    *,
    type=ContactType.PCWF,
    mu=DEFAULT_MU,
    mu_s="auto",
    f_max=DEFAULT_F_MAX,
    model=None,
) -> tuple[ContactSpec, ...]:
    """``count`` specs; each parameter is one value for all or a sequence of ``count`` values.

    ``count`` is at most ``MAX_ELEMENT_CONTACTS``: these specs are for element sets.

    Parameters
    ----------
    mu_s : float, sequence of float or "auto"
        ``"auto"`` (the default): with ``model``, the command line's default for that model
        (:func:`closure_nlp.model.scale.default_mu_s`, 0.01 x the part's radius); without a model,
        ``DEFAULT_MU_S`` as in contact-set files. Numbers are kept as given.
    model : Model, optional
        The part the specs are for; it only resolves ``mu_s="auto"``.
    """
    count = as_count(count, "contacts", MAX_ELEMENT_CONTACTS, "contacts of an element set")
    if isinstance(mu_s, str) and is_auto(mu_s):
        mu_s = DEFAULT_MU_S if model is None else default_mu_s(model)
    columns = {
        key: per_contact(value, count, key)
        for key, value in (("type", type), ("mu", mu), ("mu_s", mu_s), ("f_max", f_max))
    }
    return tuple(
        ContactSpec(**{k: v[i] for k, v in columns.items()}, name=f"contacts[{i}]")
        for i in range(count)
    )


__all__ = [
    "AUTO",
    "MU_S_FRACTION",
    "ModelScale",
    "auto_torque_scale",
    "contact_specs",
    "default_mu_s",
    "is_auto",
    "resolve",
    "scale_warnings",
    "units_warning",
]
