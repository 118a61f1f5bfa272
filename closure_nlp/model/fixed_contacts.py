"""Contacts already in place (the base locators of a 3-2-1 layout, say): given in the model's
frame and units, counted in every rho, rho_hat and ceiling, never moved.

Each one is held as a point element (one vertex: no weights can move it) carrying its own type,
mu, mu_s and f_max. It must lie on the part: within :data:`POSITION_SHARE` of the part's size
(plus the element's own position tolerance) of an element whose inward normal is within
:data:`NORMAL_DEG` degrees (plus the element's own normal tolerance) of the contact's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from closure_nlp.contact.accuracy import NO_TOLERANCE, ModelTolerance
from closure_nlp.contact.contact_set import Contact, ContactSet, ContactSpec, load_contact_set
from closure_nlp.model.elements import Element, ElementKind, Model, nearest_weights, part_size

POSITION_SHARE = 1e-3  # of the part's size: a fixed contact farther from every element is off it
NORMAL_DEG = 1.0  # degrees between a fixed contact's normal and its element's, at most


@dataclass(frozen=True, eq=False)
class FixedContacts:
    """Contacts already in place on a model.

    Attributes
    ----------
    contacts : tuple of Contact
        As given, in order.
    elements : tuple of Element
        One point element per contact (its position and inward normal, moments about the
        model's reference point).
    on : tuple of int
        The model element each contact lies on.
    tolerance : tuple of ModelTolerance
        Each contact's: the one its file gives, else its element's.
    """

    contacts: tuple[Contact, ...] = ()
    elements: tuple[Element, ...] = ()
    on: tuple[int, ...] = ()
    tolerance: tuple[ModelTolerance, ...] = ()

    def __len__(self) -> int:
        return len(self.contacts)

    @property
    def specs(self) -> tuple[ContactSpec, ...]:
        return tuple(c.spec for c in self.contacts)

    @property
    def positions(self) -> np.ndarray:
        """(k, 3) float."""
        return np.array([c.position for c in self.contacts]).reshape(-1, 3)


NO_FIXED = FixedContacts()


def fixed_contacts(model: Model, fixed, field: str = "fixed") -> FixedContacts:
    """``fixed`` (a contact-set file's path, a :class:`ContactSet`, a sequence of
    :class:`Contact`, or :class:`FixedContacts`; None: none) checked to lie on ``model``.

    Raises ``ValueError`` naming the contact, its distance from the part and the tolerance when
    one lies off the part's surface, or its normal disagrees with the element it lies on.
    """
    if fixed is None:
        return NO_FIXED
    if isinstance(fixed, FixedContacts):
        return fixed
    if isinstance(fixed, (str, Path)):
        fixed = load_contact_set(fixed)
    own: tuple = ()
    if isinstance(fixed, ContactSet):
        t = fixed.tolerance
        own = t if isinstance(t, tuple) else (t,) * len(fixed)
        fixed = fixed.contacts
    try:
        contacts = tuple(fixed)
    except TypeError:
        raise TypeError(
            f"{field}: expected a contact-set file, a ContactSet or contacts, got {fixed!r}"
        ) from None
    own = own or (NO_TOLERANCE,) * len(contacts)
    size = part_size(model.elements)
    lows = np.array([e.vertices.min(axis=0) for e in model.elements])
    highs = np.array([e.vertices.max(axis=0) for e in model.elements])
    elements, on, tolerance = [], [], []
    for i, c in enumerate(contacts):
        name = f"{field}[{i}]"
        if not isinstance(c, Contact):
            raise TypeError(f"{name}: expected a Contact, got {type(c).__name__}")
        e = _element_under(model, c, lows, highs, size, name)
        elements.append(
            Element(
                ElementKind.POINT,
                c.position[None],
                c.inward_normal,
                name=name,
                reference_point=model.reference_point,
            )
        )
        on.append(e)
        tolerance.append(own[i] if own[i] else model.elements[e].tolerance)
    return FixedContacts(contacts, tuple(elements), tuple(on), tuple(tolerance))


def _element_under(model: Model, contact: Contact, lows, highs, size: float, name: str) -> int:
    """The element ``contact`` lies on (nearest among those whose normal agrees), or a
    ``ValueError`` saying how far it is and why."""
    x = contact.position
    # a lower bound of each element's distance (its bounding box's): the nearest are checked
    # first, and the search stops once no box is nearer than the best element found
    boxes = np.linalg.norm(np.maximum(0.0, np.maximum(lows - x, x - highs)), axis=1)
    reach = POSITION_SHARE * size + max(e.tolerance.position for e in model.elements)
    best, best_any = (np.inf, -1), (np.inf, -1, 0.0)
    for e in np.argsort(boxes, kind="stable"):
        if boxes[e] > (best[0] if best[1] >= 0 else max(best_any[0], reach)):
            break
        element = model.elements[e]
        w = nearest_weights(element.vertices, x)
        distance = float(np.linalg.norm(w @ element.vertices - x))
        cosine = np.clip(element.inward_normal @ contact.inward_normal, -1.0, 1.0)
        angle = float(np.degrees(np.arccos(cosine)))
        allowed = POSITION_SHARE * size + element.tolerance.position
        if distance <= allowed and angle <= NORMAL_DEG + element.tolerance.normal_deg:
            if distance < best[0]:
                best = (distance, int(e))
        if distance < best_any[0]:
            best_any = (distance, int(e), angle)
    if best[1] >= 0:
        return best[1]
    distance, e, angle = best_any
    allowed = POSITION_SHARE * size + model.elements[e].tolerance.position
    if distance > allowed:
        raise ValueError(
            f"{name}: off the part's surface: {distance:.6g} from the nearest element ({e}), "
            f"more than the tolerance {allowed:.3g} ({POSITION_SHARE:g} of the part's size)"
        )
    limit = NORMAL_DEG + model.elements[e].tolerance.normal_deg
    raise ValueError(
        f"{name}: its inward normal is {angle:.3g} degrees from that of element {e}, where it "
        f"lies ({distance:.3g} away), more than {limit:g}"
    )


__all__ = ["FixedContacts", "NO_FIXED", "fixed_contacts"]
