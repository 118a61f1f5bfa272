"""What the commands that take a MODEL build from their flags: the model, the contact specs,
the eligibility, the placement options and margins."""

from __future__ import annotations

import sys

from closure_nlp.base.formatting import certain, lengths
from closure_nlp.base.validation import (
    MAX_ELEMENT_CONTACTS,
    as_count,
    as_torque_scale,
)
from closure_nlp.cli.arguments import float_value, model_tolerance, value_list
from closure_nlp.cli.output import (
    InputError,
    bounds_text,
    joined_ids,
    load_each,
    progress_bar,
    reading,
    shown,
    verdict_text,
)
from closure_nlp.contact.contact_set import SOFT_FINGERS, load_contact_set
from closure_nlp.contact.count import require_closure_count
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.model.elements import load_model
from closure_nlp.model.fixed_contacts import fixed_contacts
from closure_nlp.model.scale import contact_specs, is_auto, scale_warnings
from closure_nlp.model.scale import resolve as resolve_scale
from closure_nlp.placement.ceiling import gap_text
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.spacing import check_fixed_spacing


def model_eligibility(args, m: int, field: str = "--contacts", closure: bool = False):
    """The model of ``args.model`` with ``m`` contacts of the requested specs (with
    ``closure``: only when such contacts can ever hold a 3-D part, else exit 2)."""
    with reading(args.model):
        as_count(m, field, MAX_ELEMENT_CONTACTS, "contacts")  # the limit, before any work
    model = read_model(args)
    with reading(args.model):
        specs, scale = model_specs(args, m, model)
    for line in scale_warnings(scale, [s.type.value for s in specs]):
        sys.stderr.write(f"warning: {shown(args.model)}: {line}\n")
    args.scale = scale
    args.soft_fingers = any(s.type in SOFT_FINGERS for s in specs)  # mu_s plays a part
    fixed = None
    if getattr(args, "fixed", None):
        [(_, fixed)] = load_each([args.fixed], load_contact_set)
        with reading(args.fixed):  # a fixed contact off the part is that file's fault
            fixed = fixed_contacts(model, fixed)
    if closure:
        with reading(args.model):  # the fixed contacts count too
            require_closure_count((fixed.specs if fixed else ()) + tuple(specs), field)
    only, exclude = getattr(args, "only", None), getattr(args, "exclude", None)
    # the tolerance flags hold for every element, even at 0 (the model is then the part)
    flagged = args.position_tolerance is not None or args.normal_tolerance is not None
    with reading(args.model):
        eligibility = Eligibility(
            model,
            specs,
            scale.torque_scale,
            tolerance=model.tolerance if flagged else None,
            only=only,
            exclude=exclude,
            fixed=fixed,
        )
    if fixed and getattr(args, "min_spacing", 0):
        with reading(args.fixed):
            check_fixed_spacing(eligibility, args.min_spacing)
    left = int(eligibility.model.usable.sum())
    if left == 0 or left < m <= int(model.usable.sum()):
        flag = "--exclude" if exclude else "--only"
        raise InputError(flag, f"{left} element(s) left where contacts may go, for {m} contacts")
    return eligibility


def intent_keys(args, eligibility) -> dict:
    """The JSON keys of the engineer's intent the command was given: ``excluded`` ids (with
    ``--only``/``--exclude``), ``fixed`` (the fixed contacts' count and elements) and
    ``min_spacing``."""
    out = {}
    if getattr(args, "only", None) or getattr(args, "exclude", None):
        out["excluded"] = list(eligibility.excluded)
    if len(eligibility.fixed):
        out["fixed"] = {"count": len(eligibility.fixed), "elements": list(eligibility.fixed.on)}
    if getattr(args, "min_spacing", None):
        out["min_spacing"] = args.min_spacing
    return out


def read_model(args, marked: list | None = None):
    """``args.model`` with its mesh checked: inside the model's folder (unless
    ``--allow-outside-mesh``), facet and segment normals pointing into it; a missing or broken
    mesh is one warning (it only serves pictures). With ``marked`` (a picture), elements whose
    normal points out of the mesh are put there, with one warning, instead of refused."""
    from dataclasses import replace

    from closure_nlp.model.elements import ElementKind
    from closure_nlp.model.model_mesh import check_normals, outward_elements, read_model_mesh

    [(_, model)] = load_each([args.model], load_model)
    tolerance = model_tolerance(args, model.tolerance)
    if tolerance != model.tolerance:  # a copy checks the whole model again
        model = replace(model, tolerance=tolerance)
    if getattr(args, "allow_outside_mesh", False):
        model = replace(model, allow_outside_mesh=True)
    with reading(args.model):
        model.mesh_path  # noqa: B018 - refuses a path outside the model's folder, before work
        judged = any(e.kind is not ElementKind.POINT for e in model.elements)
        if judged and not getattr(args, "no_mesh", False):  # points have nothing to check
            if marked is None:
                check_normals(model, read_model_mesh(model))
            else:
                marked += outward_elements(model, read_model_mesh(model))
    if marked:
        ids = ", ".join(str(i) for i in marked[:10]) + (", ..." if len(marked) > 10 else "")
        sys.stderr.write(
            f"warning: {args.model}: {len(marked)} element(s) with an inward normal pointing out "
            f"of the model's mesh, drawn marked (plan and the other commands refuse the model): "
            f"{ids}\n"
        )
    return model


def model_specs(args, m: int, model):
    """The ``m`` contact specs of the contact options, and the scale (torque scale, mu_s)."""
    torque_scale = args.torque_scale
    if not is_auto(torque_scale):
        torque_scale = as_torque_scale(
            value_list(torque_scale, "--torque-scale", 1, float_value), "--torque-scale"
        )
    mu_s = args.mu_s if is_auto(args.mu_s) else value_list(args.mu_s, "--mu-s", m, float_value)
    types = value_list(args.type, "--type", m, str)
    scale = resolve_scale(model, torque_scale, mu_s)
    try:
        specs = contact_specs(
            m,
            type=types,
            mu=value_list(args.mu, "--mu", m, float_value),
            mu_s=list(scale.mu_s) if isinstance(scale.mu_s, tuple) else scale.mu_s,
            f_max=value_list(args.f_max, "--f-max", m, float_value),
        )
    except ValueError as exc:
        raise ValueError(f"contact options: {exc}") from None
    return specs, scale


def with_margin(args, eligibility: Eligibility, ids=()) -> Eligibility:
    """``eligibility`` on the model shrunk by ``--margin`` (itself when the margin is 0);
    ``ids``: elements the command names, refused when too small for the margin."""
    from closure_nlp.placement.margin import with_margin

    if not args.margin:
        return eligibility
    model, dropped = with_margin(eligibility.model, args.margin)
    small = sorted(set(ids) & set(dropped))
    if small:
        raise InputError(
            "--margin",
            f"element(s) {joined_ids(small)} too small for a margin of {args.margin:g}: "
            "no point of them is that far from their boundary",
        )
    if len(model.unusable) == len(model):
        raise InputError("--margin", f"every element is too small for a margin of {args.margin:g}")
    specs, scale = eligibility.specs, eligibility.torque_scale
    return Eligibility(
        model, specs, scale, tolerance=eligibility.tolerance, fixed=eligibility.fixed
    )


def margin_text(args, model) -> str:
    """The margin's line of a command's text (empty without a margin)."""
    if not args.margin:
        return ""
    text = f"\n  every contact at least {args.margin:g} from its element's boundary"
    left = model.unusable
    if left:
        listed = joined_ids(left) if len(left) <= 12 else f"{joined_ids(left[:12])},..."
        text += f"; {len(left)} element(s) too small for it left out ({listed})"
    return text


def placement_options(args, seeded: bool) -> PlacementOptions:
    """``--starts`` (and ``--seed`` when it seeds the placement, as in ``place``; in ``plan`` it
    seeds the heuristic only, as in the API's ``plan(seed=...)``)."""
    bound = {
        "bound": not args.no_bound,
        "target_gap": args.gap,
        "bound_cells": args.bound_cells,
        "bound_neighbours": args.bound_neighbours,
        "time_budget": args.time_budget,
    }
    try:
        spacing = {"min_spacing": args.min_spacing} if getattr(args, "min_spacing", None) else {}
        return PlacementOptions(
            starts=args.starts, **bound, **spacing, **({"seed": args.seed} if seeded else {})
        )
    except ValueError as exc:
        raise ValueError(f"--{exc}") from None


def placement_setup(args, seeded: bool, check_out):
    """``(options, progress, close)`` of a command that places contacts, its ``--out`` checked
    by ``check_out`` before any work."""
    with reading(args.model):
        options = placement_options(args, seeded)
    if args.out:
        with reading(args.out):
            check_out(args.out)
    progress, close = progress_bar(args, options.starts)
    return options, progress, close


def placement_text(result, model) -> str:
    verdict = verdict_text(result, result.force_closure)
    bounds = bounds_text(result, "rho")
    lines = [
        f"rho = {certain(result.rho, result.bounds)} ({verdict}){bounds}; "
        f"centroids gave {certain(result.start_rho)}; {result.seconds:.2f} s"
    ]
    if result.capacity_bound is not None:
        lines.append(f"  {gap_text(result)}")
    fixed = result.contact_set.contacts[: len(result.contact_set) - len(result.contacts)]
    for i, c in enumerate(fixed):
        lines.append(f"  fixed contact {i}: at [{lengths(c.position, model)}]")
    for i, c in enumerate(result.contacts):
        pos = lengths(c.position, model)  # to the model's accuracy (numbers.model_accuracy)
        lines.append(f"  contact {i}: element {c.element} at [{pos}]")
    return "\n".join(lines)
