"""Eligibility of element sets: rho(0, What_c^M) (paper section 4, eqs 33-36).

One contact per listed element (an element may be listed twice). The wrench set of a contact on
element ``i`` lies in the convex hull of its vertex sets ``W_ij``, so slot ``i`` of the
:class:`WrenchSlots` has one row per vertex and the same :class:`SupportMinimizer` as rho
computes ``rho_hat`` with the max over vertices inside its epigraph.

Vertex rows are padded (by repeating the last vertex, which changes no support value) to a few
bucket sizes, so a whole selection run needs only a handful of NLP shapes, each built once.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from closure_nlp.base.solver_cache import PerThread
from closure_nlp.base.validation import as_flag, as_id_list, as_torque_scale
from closure_nlp.contact.accuracy import NO_TOLERANCE, ModelTolerance
from closure_nlp.contact.contact_set import ContactSpec
from closure_nlp.contact.wrenches import WrenchSlots, padded_rows
from closure_nlp.criterion.robustness import (
    has_tolerance,
    row_shifts,
    support_shift,
    with_robustness,
)
from closure_nlp.criterion.support_minimum import (
    Certificate,
    SolverStats,
    SupportMinimizer,
    SupportMinimum,
    certificate_keys,
    certificate_of,
    certified_rho,
    certified_search,
    checked_tol,
    signed_distance,
    timing_keys,
    tol_variant,
)
from closure_nlp.model.elements import Model
from closure_nlp.model.fixed_contacts import fixed_contacts
from closure_nlp.model.regions import excluded_elements, marked_unusable
from closure_nlp.model.scale import AUTO, auto_torque_scale


@dataclass(frozen=True)
class EligibilityResult(Certificate):
    """rho_hat of one element set.

    Attributes
    ----------
    elements : tuple of int
        Element ids, one per contact, in contact order.
    rho_hat : float
        rho(0, What_c^M): negative iff the set is eligible; then ``-rho_hat`` is the radius of the
        largest origin-centred ball in What_c^M.
    eligible : bool
    direction : (6,) float
        Unit ``u*`` at which the support function attains ``-rho_hat``.
    stats : SolverStats
    bounds : (float, float) or None
        Certified ``(lo, hi)`` with ``lo <= rho_hat <= hi``; None for the search alone
        (``certify=False``, inside the selection loops).
    marginal : bool
        The bounds reach within the tolerance of zero; never eligible then.
    converged : bool
        ``hi - lo`` within the tolerance (1e-6 relative).
    robust : bool or None
        Eligible for every element set within the model's tolerance (None: no tolerance).
    shift : float
        How far the support function can move within that tolerance.
    timing : (float, float) or None
        Seconds of the search and of the certificate; ``stats.seconds`` is their sum.
    """

    elements: tuple[int, ...]
    rho_hat: float
    eligible: bool
    direction: np.ndarray
    stats: SolverStats

    def to_dict(self) -> dict:
        return {
            **element_set_keys(self),
            "solver": self.stats.solver,
            "seconds": self.stats.seconds,
            **timing_keys(self),
        }


def element_set_keys(result) -> dict:
    """The JSON keys of a rho_hat result (:class:`EligibilityResult`, a selection's result)."""
    return {
        "elements": list(result.elements),
        "rho_hat": result.rho_hat,
        "eligible": result.eligible,
        "direction": result.direction.tolist(),
        **certificate_keys(result),
    }


class Eligibility:
    """rho_hat of element sets of one model for one list of contact specs, solvers reused.

    Parameters
    ----------
    model : Model
    specs : sequence of ContactSpec
        One per contact; ``len(specs)`` is the number of contacts m
        (``contact_specs(m, ..., model=model)`` gives soft fingers the command line's ``mu_s``).
    torque_scale : float or "auto"
        Factor on every torque row. ``"auto"`` (the default, as on the command line):
        ``1 / R``, R the part's radius about its reference point
        (:func:`closure_nlp.model.scale.auto_torque_scale`), so rho does not depend on the model's
        unit.
    minimizer : SupportMinimizer, optional
        Holds the cached NLPs (one per shape) and the search options.
    tolerance : ModelTolerance, optional
        The accuracy of every element (even zero: the model is the part); default the model's
        own when it sets one, else each element's own. Results carry ``robust``.
    only, exclude : region or list of regions, optional
        Where contacts may go (:mod:`closure_nlp.model.regions`: ``"ids:3,7,10-14"``,
        ``"facing:+z:10"``, ``"box:X0,Y0,Z0,X1,Y1,Z1"`` or a list of ids): the elements outside
        every ``only`` region, or inside an ``exclude`` one, are used by no step of selection or
        placement (:attr:`excluded`). The automatic torque scale stays the whole part's.
    fixed : contact-set file, ContactSet or contacts, optional
        Contacts already in place, in the model's frame and units (:attr:`fixed`, a
        :class:`~closure_nlp.model.fixed_contacts.FixedContacts`): every element set's wrench
        set holds them too, each with its own type, mu, mu_s and f_max, and no step moves
        them; ``specs`` are the new contacts only. ``ValueError`` when one is off the part.
    """

    def __init__(
        self,
        model: Model,
        specs,
        torque_scale: float | str = AUTO,
        minimizer: SupportMinimizer | None = None,
        tolerance: ModelTolerance | None = None,
        *,
        only=None,
        exclude=None,
        fixed=None,
    ):
        if not isinstance(model, Model):
            raise TypeError(f"model: expected a Model, got {type(model).__name__}")
        specs = tuple(specs)
        if not specs:
            raise ValueError("specs: at least one contact is needed, got none")
        for i, s in enumerate(specs):
            if not isinstance(s, ContactSpec):
                raise TypeError(f"specs[{i}]: expected a ContactSpec, got {type(s).__name__}")
        self.excluded = excluded_elements(model, only, exclude)
        self.model = marked_unusable(model, self.excluded)
        self.specs = specs
        auto = isinstance(torque_scale, str) and torque_scale == AUTO
        self.torque_scale = auto_torque_scale(model) if auto else as_torque_scale(torque_scale)
        self.minimizer = minimizer or SupportMinimizer()
        self._tol_minimizers: dict = {}  # the minimizer's variants of other brackets
        self._counts: PerThread[Counter] = PerThread(Counter)
        if tolerance is None and model.tolerance:
            tolerance = model.tolerance
        if not (tolerance is None or isinstance(tolerance, ModelTolerance)):
            raise TypeError(f"tolerance: expected a ModelTolerance, got {tolerance!r}")
        self.tolerance = tolerance  # None: each element's own
        self._vertex_G = [e.grasp_matrices(self.torque_scale) for e in model.elements]
        self._all: dict[ContactSpec, WrenchSlots] = {}
        self._shifts: dict[ContactSpec, np.ndarray] = {}
        self.fixed = fixed_contacts(model, fixed)
        self._fixed_G = [e.grasp_matrices(self.torque_scale) for e in self.fixed.elements]

    @property
    def all_specs(self) -> tuple[ContactSpec, ...]:
        """The fixed contacts' specs, then the new ones': what the count checks count."""
        return self.fixed.specs + self.specs

    @property
    def evaluations(self) -> int:
        """Element sets evaluated so far by the calling thread (a selection counts its own
        evaluations by it, also while other threads use this eligibility)."""
        return self._counts.get()["evaluations"]

    @property
    def m(self) -> int:
        return len(self.specs)

    def check_elements(self, elements, field: str = "elements", partial: bool = False):
        """Validate a list of ``m`` element ids (``1..m`` of them when ``partial``)."""
        elements = as_id_list(elements, field)
        if not (1 <= len(elements) <= self.m if partial else len(elements) == self.m):
            wanted = f"1 to {self.m}" if partial else f"{self.m}"
            raise ValueError(
                f"{field}: expected {wanted} element ids (one per contact), got {len(elements)}"
            )
        ids = tuple(self.model.check_id(e, f"{field}[{k}]") for k, e in enumerate(elements))
        return check_usable(self.model, ids, field)

    def slots(self, elements) -> WrenchSlots:
        """The slots of What_c^M: contact ``i`` on element ``elements[i]``, one row per vertex,
        and the fixed contacts, one row each."""
        rows = [
            (G, spec.type, spec.mu, spec.mu_s, spec.f_max)
            for spec, G in zip(self.all_specs, self._all_G(elements))
        ]
        return WrenchSlots.build([rows[i] for i in self._slot_order(elements)])

    def _all_G(self, elements) -> list[np.ndarray]:
        """The vertex grasp matrices of the fixed contacts, then of ``elements``."""
        return self._fixed_G + [self._vertex_G[e] for e in elements]

    def _slot_order(self, elements) -> list[int]:
        """The contacts (fixed ones first) in the order of their slots. rho_hat does not
        depend on the slots' order: sorted by NLP size and type, the sets that differ only by
        order share one NLP shape (the solver cache holds each shape once)."""
        specs, vertices = self.all_specs, [len(G) for G in self._all_G(elements)]

        def key(i):
            s = specs[i]
            return padded_rows(vertices[i]), s.type.value, s.mu, s.mu_s, s.f_max

        return sorted(range(len(vertices)), key=key)

    def contact_tolerance(self, elements):
        """How far each contact (the fixed ones, then those on ``elements``) may lie from the
        model: the tolerance the eligibility was given (or the model's own), for every contact;
        otherwise a tuple of each one's own (``NO_TOLERANCE`` when none has one)."""
        if self.tolerance is not None:
            return self.tolerance
        own = self.fixed.tolerance + tuple(self.model.elements[e].tolerance for e in elements)
        return own if any(own) else NO_TOLERANCE

    def __call__(
        self,
        elements,
        warm_start=None,
        partial: bool = False,
        certify: bool = True,
        stop_above: float | None = None,
        tol: float | None = None,
    ) -> EligibilityResult:
        """rho_hat of ``elements`` (m ids; with ``partial``, the first ``k <= m`` contacts).

        ``warm_start`` adds a start direction (e.g. the ``u*`` of a neighbouring set). With
        ``certify`` (the default) the result carries certified bounds and the verdict is theirs;
        without, it is the search's value alone (for comparisons inside search loops; certify
        what is reported with :meth:`certify`).

        ``stop_above`` (only without ``certify``): the caller only needs to know whether
        rho_hat is below it; the search returns as soon as a direction shows a value at or
        above it. A result at or above ``stop_above`` is then only a value never above the full
        search's (which goes on from there and can only raise it); one below is the full value.

        ``tol`` (only with ``certify``): the relative width of the certified bracket, as
        :func:`~closure_nlp.criterion.support_minimum.rho`'s (default: the minimizer's, 1e-6);
        the verdicts take the same accuracy.
        """
        certify = as_flag(certify, "certify")
        if certify and stop_above is not None:
            raise ValueError("stop_above: a certified result has no early stop")
        if tol is not None and not certify:
            raise ValueError("tol: only a certified result has a bracket")
        minimizer = self.minimizer
        if tol is not None:
            minimizer = tol_variant(minimizer, checked_tol(tol), self._tol_minimizers)
        elements = self.check_elements(elements, partial=partial)
        slots = self.slots(elements)
        self._counts.get()["evaluations"] += 1
        if certify:
            found = certified_search(minimizer, slots, warm_start)
            return self._result(elements, self._robust(elements, found, slots, minimizer))
        stop = None if stop_above is None else -float(stop_above)
        found = self.minimizer(slots, warm_start, stop)
        value = signed_distance(found, slots, self.minimizer.tolerances)
        return EligibilityResult(elements, value, value < 0.0, found.direction, found.stats)

    def certify(self, result: EligibilityResult) -> EligibilityResult:
        """``result`` with certified bounds, started at its direction (no new search)."""
        if result.bounds is not None:
            return result
        slots = self.slots(result.elements)
        u = result.direction
        value = float(slots.support(u[None])[0])
        found = SupportMinimum(value, u, slots.support_point(u), result.stats)
        return self._certified(result.elements, slots, found)

    def _certified(self, elements, slots, found) -> EligibilityResult:
        return self._result(
            elements, self._robust(elements, certified_rho(slots, found, self.minimizer), slots)
        )

    def _robust(self, elements, result, slots, minimizer=None):
        tolerance = self.contact_tolerance(elements)
        if not isinstance(tolerance, ModelTolerance):  # per contact: in the slots' order
            tolerance = tuple(tolerance[i] for i in self._slot_order(elements))
        tolerances = (minimizer or self.minimizer).tolerances
        return with_robustness(result, slots, tolerance, tolerances)

    @staticmethod
    def _result(elements, r) -> EligibilityResult:
        return EligibilityResult(
            elements, r.rho, r.force_closure, r.direction, r.stats, **certificate_of(r)
        )

    def _every_element(self, spec: ContactSpec) -> WrenchSlots:
        """One slot per element of the model for a contact of ``spec``."""
        if spec not in self._all:
            self._all[spec] = WrenchSlots.build(
                (G, spec.type, spec.mu, spec.mu_s, spec.f_max) for G in self._vertex_G
            )
        return self._all[spec]

    def element_values(self, spec_index: int, u: np.ndarray) -> np.ndarray:
        """``max_j p_{W_ij}(u)`` of every element of the model for contact ``spec_index``: (n,)."""
        slots = self._every_element(self.specs[spec_index])
        return slots.slot_values(np.asarray(u, dtype=float)[None])[0]

    def element_shifts(self, spec_index: int) -> np.ndarray:
        """How far a contact ``spec_index`` on each element can move the support function
        within its tolerance (:func:`~closure_nlp.criterion.robustness.support_shift` of that
        one slot): (n,), zeros without a tolerance."""
        spec = self.specs[spec_index]
        if spec not in self._shifts:
            slots = self._every_element(spec)
            tolerance = self.tolerance
            if tolerance is None:  # each element's own
                tolerance = tuple(e.tolerance for e in self.model.elements)
            shifts = np.zeros(slots.m)
            if has_tolerance(tolerance):
                shifts = np.maximum.reduceat(row_shifts(slots, tolerance), slots.starts)
            self._shifts[spec] = shifts
        return self._shifts[spec]

    def shift(self, elements) -> float:
        """The support shift of an element set (or its first contacts) within the tolerance:
        the ``shift`` its certified result carries, a sum over its contacts, so selection can
        steer by ``rho_hat + shift`` without a certificate."""
        new = sum(self.element_shifts(i)[e] for i, e in enumerate(elements))
        return float(self._fixed_shift + new)

    @cached_property
    def _fixed_shift(self) -> float:
        """The fixed contacts' part of every element set's shift."""
        if not len(self.fixed):
            return 0.0
        tolerance = self.tolerance if self.tolerance is not None else self.fixed.tolerance
        rows = [(G, s.type, s.mu, s.mu_s, s.f_max) for s, G in zip(self.fixed.specs, self._fixed_G)]
        return support_shift(WrenchSlots.build(rows), tolerance)


def check_usable(model: Model, ids: tuple[int, ...], field: str) -> tuple[int, ...]:
    """``ids``, or a ``ValueError`` naming those no contact may sit on (``model.unusable``)."""
    bad = sorted(set(ids) & set(model.unusable))
    if bad:
        listed = ",".join(str(e) for e in bad)
        raise ValueError(
            f"{field}: element(s) {listed} may hold no contact (excluded, or too small for the "
            "margin)"
        )
    return ids


def rho_hat(
    model: Model, elements, specs, torque_scale: float | str = AUTO, *, minimizer=None
) -> EligibilityResult:
    """rho(0, What_c^M) of one element set (eq 33); see :class:`Eligibility` for loops."""
    return Eligibility(model, specs, torque_scale, minimizer)(elements)


eligibility = rho_hat  # the command's name for it


__all__ = [
    "Eligibility",
    "EligibilityResult",
    "element_set_keys",
    "eligibility",
    "padded_rows",
    "rho_hat",
]
