"""``closure-nlp characterize MESH --out MODEL``: an element model from a mesh."""

from __future__ import annotations

import dataclasses
import os
import sys

from closure_nlp.base.files import (
    check_output_file,
)
from closure_nlp.cli import arguments, output


def add_characterize(sub, common) -> None:
    p = sub.add_parser(
        "characterize", parents=[common], help="element model (facets, segments, points) of a mesh"
    )
    p.add_argument("mesh", metavar="MESH", help="mesh file (STL, OBJ, PLY, GLB, OFF...)")
    p.add_argument("--out", required=True, metavar="MODEL", help="*.model.json to write")
    spacing = "(default auto: 0.2 x the part's radius; 0 keeps all)"
    for flag, metavar, what in (
        ("--segment-spacing", "X", "ruling"),
        ("--point-spacing", "Y", "point"),
    ):
        p.add_argument(
            flag,
            type=arguments.spacing_value,
            default="auto",
            metavar=metavar,
            help=f"{what} spacing {spacing}",
        )
    p.add_argument(
        "--sharp-angle",
        type=arguments.length_value,
        default=30.0,
        metavar="DEG",
        help="edges sharper than this separate surfaces (default 30)",
    )
    p.add_argument("--name", help="model name (default: the mesh file's stem)")
    p.add_argument(
        "--units",
        choices=["m", "cm", "mm", "in"],
        help="length unit of the mesh (default m; the unit used is printed)",
    )
    p.add_argument(
        "--merge-bodies",
        action="store_true",
        help="hold a mesh of several separate bodies as one rigid part (default: refuse it)",
    )
    p.add_argument(
        "--close-holes",
        action="store_true",
        help="cap openings too: holes whose boundary is longer than the part's radius, such as "
        "a cup's mouth (default: refuse such a mesh; smaller holes are always filled)",
    )
    p.add_argument(
        "--reference-point",
        type=arguments.point3_value,
        metavar="X,Y,Z",
        help="point torques are taken about (default: the part's centre of mass)",
    )
    p.add_argument("--up", default="z", choices=["x", "y", "z"], help="up axis for pictures")
    p.set_defaults(run=cmd_characterize)


# The flags of ``characterize`` passed to :func:`characterize_mesh` under their own names.
CHARACTERIZE_FLAGS = (
    "segment_spacing",
    "point_spacing",
    "sharp_angle",
    "name",
    "units",
    "reference_point",
    "up",
    "merge_bodies",
    "close_holes",
)


def cmd_characterize(args) -> None:
    from pathlib import Path

    from closure_nlp.base.files import write_atomic
    from closure_nlp.model.characterize import (
        characterize_mesh,
        drop_outward_as_read,
        worst_tolerance,
    )
    from closure_nlp.model.elements import save_model
    from closure_nlp.model.meshes import bodies_held, holes_filled
    from closure_nlp.model.scale import units_warning

    with output.reading(args.out):
        out = check_output_file(args.out)
    mesh_ref = Path(os.path.relpath(Path(args.mesh).resolve(), out.resolve().parent)).as_posix()
    copy = None
    if mesh_ref.startswith("../"):  # models read only meshes in their folder: write one there
        copy = out.parent / (out.name.removesuffix(".json").removesuffix(".model") + ".mesh.stl")
        mesh_ref = copy.name
    try:
        found = characterize_mesh(
            args.mesh, mesh_ref=mesh_ref, **{k: getattr(args, k) for k in CHARACTERIZE_FLAGS}
        )
    except ValueError as exc:
        text, prefix = str(exc), f"{args.mesh}: "
        raise output.InputError(args.mesh, text.removeprefix(prefix)) from None
    model, dropped = found.model, list(found.dropped)
    model = dataclasses.replace(model, tolerance=arguments.model_tolerance(args, model.tolerance))
    try:
        if copy is not None:  # the repaired mesh, beside the model (pictures draw it)
            write_atomic(copy, found.mesh.export(file_type="stl"))
        # The model commands judge normals against the mesh file as they read it (an STL holds
        # 32-bit coordinates): judged here the same way, so they never refuse what is written.
        model, more = drop_outward_as_read(model, out.parent)
        dropped += more
        save_model(model, out)
    except OSError as exc:
        raise output.OutputFault(args.out, f"cannot write: {exc.strerror or exc}") from None
    for line in dropped:
        sys.stderr.write(f"warning: {output.shown(args.mesh)}: dropped {line}\n")
    holes, bodies = holes_filled(found.repairs), bodies_held(found.repairs)
    if holes:  # the part is not the file's surface: say so where warnings go, as one line
        sys.stderr.write(
            f"warning: {output.shown(args.mesh)}: "
            + next(r for r in found.repairs if getattr(r, "holes", ()))
            + "\n"
        )
    warning = units_warning(model.radius, model.units)
    if warning:
        sys.stderr.write(f"warning: {output.shown(args.mesh)}: {warning}\n")
    counts = model.counts()
    summary = ", ".join(f"{n} {kind}s" for kind, n in counts.items())
    worst = worst_tolerance(e.tolerance for e in model.elements)
    exact = sum(not e.tolerance for e in model.elements)
    payload = {
        "file": args.mesh,
        "elements": counts,
        "adjacency": len(model.adjacency),
        "out": str(out),
        "units": model.units,
        "reference_point": model.reference_point.tolist(),
        "radius": model.radius,
        "segment_spacing": found.segment_spacing,
        "point_spacing": found.point_spacing,
        "repairs": list(found.repairs),
        "holes_filled": holes,
        "merged_bodies": bodies,
        "dropped": dropped,
        "tolerance": model.tolerance.to_dict(),
        "element_tolerance": {
            **worst.to_dict(),
            "exact": exact,
        },
    }
    tol, name = model.tolerance or worst, output.shown(args.mesh)
    held = (
        f"\n{name}: {bodies} separate bodies held as one rigid part (--merge-bodies)"
        if bodies
        else ""
    )
    # Verdicts are judged robust only within a tolerance: none set and every element exact
    # claims nothing.
    robust = "; verdicts are robust within it" if tol else ""
    output.emit(
        args,
        payload,
        f"{name}: {found.text()}{held}\n{name}: {summary}, "
        f"{len(model.adjacency)} neighbour pairs -> {output.shown(out)}"
        f"\n{name}: model accuracy: positions within "
        f"{tol.position:.3g}{' ' + model.units if model.units else ''}, normals within "
        f"{tol.normal_deg:.3g} degrees of the mesh"
        + (
            " (every element)"
            if model.tolerance
            else f" at worst; each element has its own, {exact} of {len(model)} exact"
        )
        + robust,
    )
