"""Contact models (FPC, PCwF, SFCl, SFCe), the local frame and the grasp matrix (paper eqs 1-6).

A contact's allowable forces are ``f = (f_n, f_o, f_t, f_s)`` in its local frame ``{n, o, t}``
(``n = o x t``, ``n`` the unit inward normal) with ``0 <= f_n <= f_max`` and the friction cone of
its type. Every cone used here has the form ``max_k sqrt(sum_j w_kj f_j^2 / w_kj^2) <= f_n``;
its support function is written once, in :mod:`closure_nlp.contact.wrenches`, from the weights
returned by :func:`friction_pieces`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from closure_nlp.base.files import load_json
from closure_nlp.base.validation import (
    MAX_SET_CONTACTS,
    as_coordinates,
    as_count,
    as_element_id,
    as_f_max,
    as_mu,
    as_mu_s,
    as_numbers,
    as_torque_scale,
    as_unit_vector,
    as_units,
    check_keys,
    parse_choice,
)
from closure_nlp.contact.accuracy import NO_TOLERANCE, ModelTolerance, tolerance_from_dict

DEFAULT_MU = 0.2
DEFAULT_MU_S = 0.2
DEFAULT_F_MAX = 1.0


class ContactType(str, Enum):
    """Contact model: frictionless, with friction, soft finger (linear or elliptic)."""

    FPC = "fpc"
    PCWF = "pcwf"
    SFCL = "sfcl"
    SFCE = "sfce"

    @classmethod
    def parse(cls, value, field: str = "type") -> ContactType:
        return parse_choice(cls, value, field, "contact type")


SOFT_FINGERS = frozenset({ContactType.SFCL, ContactType.SFCE})  # the types mu_s acts on


def friction_pieces(kind: ContactType, mu: float, mu_s: float) -> np.ndarray:
    """Weights of the friction term of the support function (eqs 29-32).

    The support function of one contact is ``f_max * (d_n + max_k sqrt(sum_j W[k, j] d_j^2))``
    with ``d = G^T u = (d_n, d_o, d_t, d_s)``.

    Returns
    -------
    W : (k, 4) float
        One row per piece: none for FPC, one for PCwF and SFCe, two for SFCl.
    """
    mu2, mus2 = mu * mu, mu_s * mu_s
    return {
        ContactType.FPC: np.zeros((0, 4)),
        ContactType.PCWF: np.array([[0.0, mu2, mu2, 0.0]]),
        ContactType.SFCL: np.array([[0.0, mu2, mu2, 0.0], [0.0, 0.0, 0.0, mus2]]),
        ContactType.SFCE: np.array([[0.0, mu2, mu2, mus2]]),
    }[kind]


def is_frictionless(kind: ContactType, mu: float, mu_s: float) -> bool:
    """No friction piece (FPC, or zero friction): the contact pushes along its normal only, and
    its wrench set is a segment."""
    return not friction_pieces(kind, mu, mu_s).any()


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of 3-vectors along the last axis (broadcast), by the same products: numpy's
    own spends ~30 us moving axes per call, which models of thousands of elements pay per
    element. a, b : (..., 3) float."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def local_frame(normal: np.ndarray) -> np.ndarray:
    """Unit tangents completing the inward normal to a right-handed frame.

    Parameters
    ----------
    normal : (3,) float
        Unit inward normal ``n``.

    Returns
    -------
    frame : (3, 3) float
        Columns ``n, o, t`` with ``n = o x t``.
    """
    return local_frames(np.asarray(normal, dtype=float)[None])[0]


def local_frames(normals: np.ndarray) -> np.ndarray:
    """:func:`local_frame` of each of ``normals`` (m, 3): (m, 3, 3)."""
    n = np.asarray(normals, dtype=float)
    helper = np.zeros(n.shape)
    # the axis least aligned with n: never parallel
    helper[np.arange(len(n)), np.argmin(np.abs(n), axis=1)] = 1.0
    o = cross(n, helper)
    for row in o:  # a vector norm per frame: norm(axis=1) rounds differently
        row /= np.linalg.norm(row)
    t = cross(n, o)  # o x (n x o) = n for unit, orthogonal n and o
    return np.stack([n, o, t], axis=-1)


def grasp_matrices(positions: np.ndarray, normal: np.ndarray, torque_scale: float = 1.0):
    """Grasp matrices ``G`` (eq 6) of contacts sharing one inward normal.

    Used for one contact (``positions`` of shape (3,)) and for the vertex grasp matrices of an
    element (eq 19, one row per vertex). Torque rows, the spin column included, are multiplied by
    ``torque_scale``.

    Returns
    -------
    G : (6, 4) float, or (k, 6, 4) float for ``positions`` of shape (k, 3)
    """
    r = np.asarray(positions, dtype=float)
    single = r.ndim == 1
    G = frame_grasp_matrices(np.atleast_2d(r), local_frame(normal)[None], torque_scale)
    return G[0] if single else G


def frame_grasp_matrices(r: np.ndarray, frames: np.ndarray, torque_scale: float) -> np.ndarray:
    """Grasp matrices (k, 6, 4) of contacts at ``r`` (k, 3) with the frames ``frames`` (k or 1,
    3, 3) of :func:`local_frames`; ``torque_scale`` one for all or (k,) one per contact."""
    G = np.zeros((r.shape[0], 6, 4))
    G[:, :3, :3] = frames
    axes = frames.transpose(0, 2, 1)  # the frames' columns as rows
    scale = np.asarray(torque_scale, dtype=float).reshape(-1, 1, 1)
    G[:, 3:, :3] = scale * cross(r[:, None, :], axes).transpose(0, 2, 1)
    G[:, 3:, 3] = scale[:, :, 0] * frames[:, :, 0]
    return G


def unmasked(value, field: str):
    """``value``, or the data of a masked array without a masked entry: converting one to floats
    drops its mask, so a masked coordinate would silently count with whatever its data holds."""
    if isinstance(value, np.ma.MaskedArray):
        if np.ma.getmaskarray(value).any():
            raise ValueError(f"{field}: a masked array with masked entries; give every number")
        return np.ma.getdata(value)
    return value


def per_contact(value, count: int, key: str) -> list:
    """``value`` for each of ``count`` contacts: one value for all, or a sequence of ``count``
    values (a list, tuple or array; a string is one value)."""
    if not isinstance(value, (list, tuple, np.ndarray)):
        return [value] * count
    if len(value) != count:
        raise ValueError(
            f"{key}: expected one value or {count} values (one per contact), got {len(value)}"
        )
    return list(value)


def _check_parameters(obj, name: str) -> None:
    """Validate and normalise the ``type, mu, mu_s, f_max`` fields of a frozen dataclass."""
    set_ = object.__setattr__
    set_(obj, "type", ContactType.parse(obj.type, f"{name}.type"))
    set_(obj, "mu", as_mu(obj.mu, f"{name}.mu"))
    set_(obj, "mu_s", as_mu_s(obj.mu_s, f"{name}.mu_s"))
    set_(obj, "f_max", as_f_max(obj.f_max, f"{name}.f_max"))


@dataclass(frozen=True)
class ContactSpec:
    """What a contact can carry, wherever it is put: type, ``mu``, ``mu_s`` and ``f_max``."""

    type: ContactType = ContactType.PCWF
    mu: float = DEFAULT_MU
    mu_s: float = DEFAULT_MU_S
    f_max: float = DEFAULT_F_MAX
    name: str = field(default="contact", compare=False, repr=False)

    def __post_init__(self) -> None:
        _check_parameters(self, self.name)

    def at(self, position, inward_normal, name: str | None = None) -> Contact:
        """A :class:`Contact` with these parameters at ``position``."""
        return Contact(
            position, inward_normal, self.type, self.mu, self.mu_s, self.f_max, name or self.name
        )


@dataclass(frozen=True, eq=False)
class Contact:
    """One contact: where, which way it pushes, and what it can carry.

    Attributes
    ----------
    position : (3,) float
    inward_normal : (3,) float
        Normalised on creation; zero or non-finite is rejected.
    type : ContactType
    mu, mu_s, f_max : float
        Coulomb coefficient, spin coefficient (soft fingers, a length), normal-force bound.
    """

    position: np.ndarray
    inward_normal: np.ndarray
    type: ContactType = ContactType.PCWF
    mu: float = DEFAULT_MU
    mu_s: float = DEFAULT_MU_S
    f_max: float = DEFAULT_F_MAX
    name: str = field(default="contact")

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        position, normal = f"{self.name}.position", f"{self.name}.inward_normal"
        set_(self, "position", as_coordinates(unmasked(self.position, position), position))
        set_(self, "inward_normal", as_unit_vector(unmasked(self.inward_normal, normal), normal))
        _check_parameters(self, self.name)

    @property
    def spec(self) -> ContactSpec:
        return ContactSpec(self.type, self.mu, self.mu_s, self.f_max, self.name)

    def to_dict(self) -> dict:
        return {
            "position": self.position.tolist(),
            "inward_normal": self.inward_normal.tolist(),
            "type": self.type.value,
            "mu": self.mu,
            "mu_s": self.mu_s,
            "f_max": self.f_max,
        }


@dataclass(frozen=True, eq=False)
class ContactSet:
    """Contacts acting together on one object, with the torque scale of their grasp matrices."""

    contacts: tuple[Contact, ...]
    torque_scale: float = 1.0
    reference_point: np.ndarray | None = None  # torques are taken about it; None: the origin
    # how far the real contacts may lie from these (robust verdicts,
    # closure_nlp.criterion.robustness): one for all, or a tuple of one per contact
    tolerance: ModelTolerance | tuple[ModelTolerance, ...] = NO_TOLERANCE

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "reference_point", as_reference_point(self.reference_point, "reference_point")
        )
        contacts = tuple(self.contacts)
        if not contacts:
            raise ValueError("contacts: at least one contact is needed, got an empty list")
        as_count(len(contacts), "contacts", MAX_SET_CONTACTS, "contacts")
        for i, c in enumerate(contacts):
            if not isinstance(c, Contact):
                raise TypeError(f"contacts[{i}]: expected a Contact, got {type(c).__name__}")
        object.__setattr__(self, "tolerance", _set_tolerance(self.tolerance, len(contacts)))
        object.__setattr__(self, "contacts", contacts)
        object.__setattr__(
            self,
            "torque_scale",
            as_torque_scale(self.torque_scale),
        )

    @classmethod
    def from_arrays(
        cls,
        positions,
        inward_normals,
        *,
        type=ContactType.PCWF,
        mu=DEFAULT_MU,
        mu_s=DEFAULT_MU_S,
        f_max=DEFAULT_F_MAX,
        torque_scale: float = 1.0,
        reference_point=None,
        tolerance=NO_TOLERANCE,
        name: str = "contacts",
    ) -> ContactSet:
        """One contact set from arrays.

        Parameters
        ----------
        positions, inward_normals : (m, 3) float
        type, mu, mu_s, f_max : one value, or (m,) values (one per contact)
        torque_scale, reference_point, tolerance
            As the fields of the same names.
        name : str
            How errors name the contacts (``name[i].position``...).
        """
        P = np.asarray(unmasked(positions, f"{name}.positions"))
        U = np.asarray(unmasked(inward_normals, f"{name}.inward_normals"))
        if P.ndim != 2 or P.shape[-1:] != (3,) or U.shape != P.shape:
            raise ValueError(
                f"{name}: expected positions and inward_normals of one shape (m, 3), "
                f"got {P.shape} and {U.shape}"
            )
        m = len(P)
        columns = [
            per_contact(value, m, key)
            for key, value in (("type", type), ("mu", mu), ("mu_s", mu_s), ("f_max", f_max))
        ]
        contacts = tuple(
            Contact(P[i], U[i], *(column[i] for column in columns), name=f"{name}[{i}]")
            for i in range(m)
        )
        return cls(contacts, torque_scale, reference_point, tolerance)

    def __len__(self) -> int:
        return len(self.contacts)

    @property
    def types(self) -> tuple[ContactType, ...]:
        return tuple(c.type for c in self.contacts)

    def grasp_matrices(self) -> np.ndarray:
        """(m, 6, 4) float: ``G_i`` of every contact (eq 6)."""
        r = np.array([c.position for c in self.contacts]) - self.reference_point
        frames = local_frames(np.array([c.inward_normal for c in self.contacts]))
        return frame_grasp_matrices(r, frames, self.torque_scale)

    def to_dict(self) -> dict:
        out = {"torque_scale": self.torque_scale}
        if self.reference_point.any():
            out["reference_point"] = self.reference_point.tolist()
        contacts = [c.to_dict() for c in self.contacts]
        if isinstance(self.tolerance, tuple):
            for entry, tolerance in zip(contacts, self.tolerance):
                entry["tolerance"] = tolerance.to_dict()
        elif self.tolerance:
            out["tolerance"] = self.tolerance.to_dict()
        return {**out, "contacts": contacts}


def _set_tolerance(tolerance, count: int):
    """A contact set's tolerance: one :class:`ModelTolerance`, or a tuple of one per contact
    (``NO_TOLERANCE`` when none of them lets anything move)."""
    if isinstance(tolerance, ModelTolerance):
        return tolerance
    if not isinstance(tolerance, (tuple, list)):
        raise TypeError(
            f"tolerance: expected a ModelTolerance or one per contact, got {tolerance!r}"
        )
    if len(tolerance) != count:
        raise ValueError(f"tolerance: expected one per contact ({count}), got {len(tolerance)}")
    for i, t in enumerate(tolerance):
        if not isinstance(t, ModelTolerance):
            raise TypeError(f"tolerance[{i}]: expected a ModelTolerance, got {t!r}")
    return tuple(tolerance) if any(tolerance) else NO_TOLERANCE


def as_reference_point(value, field: str) -> np.ndarray:
    """The point torques are taken about: (3,) float, read-only; None means the origin."""
    if value is None:
        point = np.zeros(3)
    else:
        point = np.array(as_coordinates(unmasked(value, field), field), dtype=float)
    point.flags.writeable = False
    return point


CONTACT_KEYS = {
    "position",
    "inward_normal",
    "type",
    "mu",
    "mu_s",
    "f_max",
    "element",
    "weights",
    "name",
    "tolerance",
    "fixed",
}
DEFAULT_KEYS = {"type", "mu", "mu_s", "f_max"}
FILE_KEYS = {
    "torque_scale",
    "reference_point",
    "defaults",
    "contacts",
    "name",
    "description",
    "units",
    "comment",
    "tolerance",
    "margin",
}


def contact_set_from_dict(data) -> ContactSet:
    """Build a :class:`ContactSet` from the contact-set file layout of docs/formats.md."""
    check_keys(data, "file", FILE_KEYS, required={"contacts"})
    if "units" in data:
        as_units(data["units"])
    defaults = data.get("defaults", {})
    check_keys(defaults, "defaults", DEFAULT_KEYS)
    entries = data["contacts"]
    if not isinstance(entries, list):
        raise TypeError(f"contacts: expected a list, got {type(entries).__name__}")
    if not entries:
        raise ValueError("contacts: at least one contact is needed, got an empty list")
    as_count(len(entries), "contacts", MAX_SET_CONTACTS, "contacts")  # before building any
    contacts, own = [], []
    for i, entry in enumerate(entries):
        name = f"contacts[{i}]"
        check_keys(entry, name, CONTACT_KEYS, required={"position", "inward_normal"})
        _check_kept_keys(entry, name)
        merged = {
            "type": ContactType.PCWF.value,
            "mu": DEFAULT_MU,
            "mu_s": DEFAULT_MU_S,
            "f_max": DEFAULT_F_MAX,
            **defaults,
            **entry,
        }
        contacts.append(
            Contact(
                position=merged["position"],
                inward_normal=merged["inward_normal"],
                type=merged["type"],
                mu=merged["mu"],
                mu_s=merged["mu_s"],
                f_max=merged["f_max"],
                name=name,
            )
        )
        given = entry.get("tolerance")
        own.append(None if given is None else tolerance_from_dict(given, f"{name}.tolerance"))
    tolerance = tolerance_from_dict(data.get("tolerance"))
    if any(t is not None for t in own):  # each contact's own; the file's for the others
        tolerance = tuple(tolerance if t is None else t for t in own)
    return ContactSet(
        tuple(contacts),
        data.get("torque_scale", 1.0),
        data.get("reference_point"),
        tolerance,
    )


def _check_kept_keys(entry: dict, name: str) -> None:
    """Keys a contact file keeps but rho does not use (where a plan placed the contact) are
    still checked: a wrong one is a wrong file."""
    if "element" in entry:
        as_element_id(entry["element"], f"{name}.element")
    if "weights" in entry:
        as_numbers(entry["weights"], f"{name}.weights")
    if "fixed" in entry and not isinstance(entry["fixed"], bool):
        raise TypeError(f"{name}.fixed: expected true or false, got {entry['fixed']!r}")
    if "name" in entry and not isinstance(entry["name"], str):
        raise TypeError(f"{name}.name: expected text, got {entry['name']!r}")


def load_contact_set(path) -> ContactSet:
    """Read a ``*.contacts.json`` file (docs/formats.md)."""
    return contact_set_from_dict(load_json(path))
