"""What a placement run answers: the placed contacts, the moves between elements and the
certified values."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from closure_nlp.contact.contact_set import ContactSet
from closure_nlp.criterion.robustness import to_be_robust, to_be_robust_text
from closure_nlp.criterion.support_minimum import certificate_keys, robust_rho


@dataclass(frozen=True)
class PlacedContact:
    """A contact on an element: barycentric ``weights`` (k,), its ``position`` and normal."""

    element: int
    weights: np.ndarray
    position: np.ndarray
    inward_normal: np.ndarray

    def to_dict(self) -> dict:
        return {
            "element": self.element,
            "weights": self.weights.tolist(),
            "position": self.position.tolist(),
            "inward_normal": self.inward_normal.tolist(),
        }


@dataclass(frozen=True)
class Move:
    """Contact ``contact`` moved from element ``source`` to its neighbour ``target``."""

    contact: int
    source: int
    target: int
    rho_before: float
    rho_after: float


@dataclass(frozen=True)
class PlacementResult:
    """Outcome of :func:`place`.

    Attributes
    ----------
    contacts : tuple of PlacedContact
    contact_set : ContactSet
        The placed contacts with their specs, ready for
        :func:`closure_nlp.criterion.support_minimum.rho`.
    rho : float
        rho(0, W_c^M) of the placed contacts, recomputed by the rho solver from the final
        positions, and certified.
    force_closure : bool
    direction : (6,) float
        Their weakest direction ``u*``.
    start_rho : float
        rho of the start (centroids, or the given weights): the search's value, which is never
        above the certified one, unless the certified final rho was above it; then the start's
        certified rho (and the start is kept if it is better).
    model_value : float
        The trust-region model's last prediction of ``-rho`` (close to it when converged; the
        method is local, so this is not a bound on other placements).
    rounds : int
        Exchange rounds over all element sets tried.
    moves : tuple of Move
    seconds : float
    bounds : (float, float) or None
        Certified ``lo <= rho <= hi`` of the placed contacts.
    marginal, converged : bool
        As in :class:`~closure_nlp.criterion.support_minimum.RhoResult`.
    capacity_bound : float or None
        Certified ceiling: no placement on the elements searched (``bound_elements``) has
        ``-rho`` above it (None without the bound).
    gap : float or None
        ``(capacity_bound - capacity) / capacity_bound`` with ``capacity = -hi`` (the certified
        capacity of these contacts), when they are force closure; None otherwise.
    gap_reached : bool or None
        The gap target was met (False: the time budget ended first).
    bound_elements : tuple of tuple of int
        The element ids each contact could sit on in the bound.
    bound_nodes : int
        Cells of the branch and bound.
    bound_seconds : float
        The bound's part of ``seconds``.
    root_gap : float or None
        The gap after the ceiling's root cell (None as for ``gap``).
    gap_per_cell : float or None
        How fast the gap fell over the last quarter of the ceiling's cells (relative gap per
        cell; None when the search stopped at its root cell): what more cells would buy, and
        with ``bound_seconds`` over ``bound_nodes`` what more seconds would.
    exchange_rho : float or None
        The exchange method's own certified rho, before the bound's search (equal to ``rho``
        unless that search found better contacts).
    robust : bool or None
        Force closure for every contact set within the model's tolerance (None: no tolerance).
    shift : float
        How far the support function can move within that tolerance.
    exchange_solver : str
        The solver of the exchange method's restricted problems: ``"highs"`` (a linear
        programme: every contact frictionless), ``"mixed"`` (IPOPT, and IPOPT's problem by
        sequential linear programming on the exploring runs), ``"slp"`` (sequential linear
        programming), ``"slp-ipopt"`` (that, then IPOPT), ``"slp-model"`` or ``"ipopt"``.
    """

    contacts: tuple[PlacedContact, ...]
    contact_set: ContactSet
    rho: float
    force_closure: bool
    direction: np.ndarray
    start_rho: float
    model_value: float
    rounds: int
    moves: tuple[Move, ...]
    seconds: float
    bounds: tuple[float, float] | None = None
    marginal: bool = False
    converged: bool = True
    capacity_bound: float | None = None
    gap: float | None = None
    gap_reached: bool | None = None
    bound_elements: tuple[tuple[int, ...], ...] = ()
    bound_nodes: int = 0
    bound_seconds: float = 0.0
    exchange_rho: float | None = None
    root_gap: float | None = None
    gap_per_cell: float | None = None
    robust: bool | None = None
    shift: float = 0.0
    exchange_solver: str = "ipopt"

    @property
    def elements(self) -> tuple[int, ...]:
        return tuple(c.element for c in self.contacts)

    @property
    def robust_rho(self) -> float | None:
        """The capacity left within the tolerance, certified (``hi + shift``)."""
        return robust_rho(self)

    def to_be_robust_text(self, unit: str = "") -> str:
        """:meth:`to_be_robust` in words (empty when there is nothing to say)."""
        advice = self.to_be_robust()
        return "" if advice is None else to_be_robust_text(advice, self.elements, unit)

    def to_be_robust(self) -> dict | None:
        """What would make these contacts robust when they are force closure but not robust
        (:func:`~closure_nlp.criterion.robustness.to_be_robust`, each contact's entry with its
        ``element``); None otherwise."""
        if self.robust is not False or not self.force_closure:
            return None
        advice = to_be_robust(self.contact_set, self.bounds)
        if advice is not None:
            for entry, placed in zip(advice["contacts"], self.contacts):
                entry["element"] = placed.element
        return advice

    def to_dict(self) -> dict:
        advice = self.to_be_robust()
        return {
            "contacts": [c.to_dict() for c in self.contacts],
            "rho": self.rho,
            "force_closure": self.force_closure,
            "direction": self.direction.tolist(),
            "start_rho": self.start_rho,
            "model_value": self.model_value,
            "rounds": self.rounds,
            "moves": [vars(m) for m in self.moves],
            "seconds": self.seconds,
            "exchange_solver": self.exchange_solver,
            **certificate_keys(self),
            **self.bound_keys(),
            **({} if advice is None else {"to_be_robust": advice}),
        }

    def bound_keys(self) -> dict:
        """The JSON keys of the certified ceiling (none when it was not computed)."""
        if self.capacity_bound is None:
            return {}
        return {
            "capacity_bound": self.capacity_bound,
            "gap": self.gap,
            "gap_reached": self.gap_reached,
            "bound_elements": [list(ids) for ids in self.bound_elements],
            "bound_nodes": self.bound_nodes,
            "root_gap": self.root_gap,
            "gap_per_cell": self.gap_per_cell,
            "exchange_rho": self.exchange_rho,
            "timing": {
                "exchange": self.seconds - self.bound_seconds,
                "bound": self.bound_seconds,
            },
        }

    def contact_file(self, name: str = "", units: str = "") -> dict:
        """The placed contacts as a contact-set file (docs/formats.md), each with its ``element``
        and ``weights``; :func:`closure_nlp.load_contact_set` reads it back to the same set."""
        data = {"torque_scale": self.contact_set.torque_scale}
        reference = getattr(self.contact_set, "reference_point", None)
        if reference is not None:  # models with a reference point
            data["reference_point"] = np.asarray(reference, float).tolist()
        if name:
            data["name"] = name
        if units:
            data["units"] = units
        verdict = "force closure" if self.force_closure else "not force closure"
        data["description"] = f"placed contacts: rho = {self.rho:.9g} ({verdict})"
        as_file = self.contact_set.to_dict()  # its tolerance too: rho of it gives this verdict
        if "tolerance" in as_file:
            data["tolerance"] = as_file["tolerance"]
        # the fixed contacts first (in their given order), then the placed ones
        entries, k = as_file["contacts"], len(as_file["contacts"]) - len(self.contacts)
        data["contacts"] = [{**c, "fixed": True} for c in entries[:k]] + [
            {**c, "element": p.element, "weights": p.weights.tolist()}
            for c, p in zip(entries[k:], self.contacts)
        ]
        return data
