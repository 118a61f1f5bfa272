"""The one tolerance object of the package: every numeric threshold lives here."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class Tolerances:
    """Numeric thresholds.

    Attributes
    ----------
    ipopt : float
        IPOPT's ``tol`` (and ``constr_viol_tol``) for every NLP of the package.
    zero_rho : float
        ``|rho|`` at or below this (relative to ``max(1, scale)``) is reported as exactly 0
        and is not force closure: the set has no interior or the origin is on its boundary.
    certify : float
        Relative gap ``hi - lo <= certify * max(|rho|, unit)`` at which certified bounds stop,
        ``unit`` the set's own wrench scale (the certificate's ``tolerance_unit``, set by its
        strongest contacts): locators with 1000x the new contacts' ``f_max`` make the bracket
        of a rho_hat that the weak contacts set up to about 1e-3 of it wide.
    geometry : float
        Relative tolerance for planarity, perpendicular normals and distinct vertices,
        measured against an element's size.
    distinct_start : float
        A candidate start direction closer than this (Euclidean, on the unit sphere) to a
        start already tried, or to the minimum it led to, is taken to lie in the same basin.
    """

    ipopt: float = 1e-12
    zero_rho: float = 1e-9
    certify: float = 1e-6
    geometry: float = 1e-6
    distinct_start: float = 0.05

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not value > 0 or value != value:
                raise ValueError(f"tolerances.{f.name}: must be a positive number, got {value!r}")


DEFAULT_TOLERANCES = Tolerances()
