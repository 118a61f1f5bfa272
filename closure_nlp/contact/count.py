"""The fewest contacts that can give force closure of a 3-D part, known before any search.

Each contact contributes a closed convex cone of wrenches ``G_i F_i`` (``F_i`` its friction cone,
``f_max`` only bounds it). Its linear span has dimension :func:`wrench_dimensions`: 1 for the
normal force, 2 more for tangential friction when ``mu > 0``, 1 more for spin when a soft finger
has ``mu_s > 0`` (``G_i`` is injective, since ``torque_scale > 0``). Force closure needs the cones
to sum to R^6, and that needs the dimensions to sum to at least 7 (proof in
``tests/test_contact_count.py``). So: 7 frictionless contacts, 3 point contacts with friction,
2 soft fingers, and for a mixed set the sum rule itself. Besides, two point contacts and a
frictionless third never suffice (no moment of both signs about the line through the two).
These bounds depend on nothing but the specs, so ``select``, ``place``, ``plan`` and studies
refuse such sets before any search, while ``rho`` and ``eligibility`` (an element set's vertex
wrenches do span more) still answer.
"""

from __future__ import annotations

from collections.abc import Sequence

from closure_nlp.contact.contact_set import SOFT_FINGERS, ContactSpec, ContactType

WRENCH_SPACE = 6  # force and torque in 3-D
NAMES = {
    ContactType.FPC: "frictionless contacts",
    ContactType.PCWF: "point contacts with friction",
    ContactType.SFCL: "soft fingers",
    ContactType.SFCE: "soft fingers",
}


def wrench_dimensions(spec: ContactSpec) -> int:
    """Dimension of the linear span of one contact's wrench cone."""
    if spec.type is ContactType.FPC:
        return 1
    friction = 2 if spec.mu > 0 else 0
    spin = 1 if spec.type in SOFT_FINGERS and spec.mu_s > 0 else 0
    return 1 + friction + spin


def closure_count_problem(specs: Sequence[ContactSpec]) -> str | None:
    """Why these contacts can never give force closure of a 3-D part, or ``None`` if they may."""
    dims = [wrench_dimensions(s) for s in specs]
    if sum(dims) <= WRENCH_SPACE:
        return _dimension_problem(specs, dims)
    if len(specs) == 3 and sorted(dims) == [1, 3, 3]:  # dimension 3: no spin
        # Two point contacts make no moment about the line through them; one frictionless
        # contact makes it of one sign only.
        return (
            f"these 3 contacts ({', '.join(s.type.value for s in specs)}) can never give force "
            "closure of a 3-D part: two point contacts make no moment about the line through "
            "them and a frictionless third contact makes it of one sign only"
        )
    return None


def _dimension_problem(specs, dims) -> str:
    kinds = sorted({s.type for s in specs}, key=list(ContactType).index)
    if len(kinds) == 1 and len(set(dims)) == 1:
        d = dims[0]
        need = WRENCH_SPACE // d + 1
        what = NAMES[kinds[0]] if d == wrench_dimensions(ContactSpec(kinds[0])) else None
        label = f"{what} ({kinds[0].value})" if what else f"{kinds[0].value} contacts"
        detail = "" if what else f" with these parameters (each spans {d} wrench dimensions)"
        return (
            f"{len(specs)} {label}{detail} can never give force closure of a 3-D part: "
            f"at least {need} are needed"
        )
    spans = " + ".join(str(d) for d in dims)
    return (
        f"these {len(specs)} contacts ({', '.join(s.type.value for s in specs)}) can never give "
        f"force closure of a 3-D part: their wrench cones span {spans} = {sum(dims)} dimensions "
        f"and force closure needs at least {WRENCH_SPACE + 1} (a frictionless contact spans 1, "
        "a point contact with friction 3, a soft finger 4)"
    )


def require_closure_count(specs: Sequence[ContactSpec], field: str = "contacts") -> None:
    """Raise ``ValueError`` (naming ``field``) when the specs can never give force closure."""
    problem = closure_count_problem(specs)
    if problem is not None:
        raise ValueError(f"{field}: {problem}")


__all__ = ["closure_count_problem", "require_closure_count", "wrench_dimensions"]
