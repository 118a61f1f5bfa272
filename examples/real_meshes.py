"""Characterize and plan on the meshes a robotics package ships (pybullet_data), default options.

The meshes are in metres, some open (the mug's handle), some in overlapping convex pieces (the
teddy's VHACD hulls), some smooth (the duck). Each is characterized with default options
(reference point: centre of mass; spacing: 0.2 x the part's radius), then a 4-finger PCwF grasp
and a 7-locator FPC fixture are planned with default options (torque scale auto, mu 0.2).
The domino is also run scaled to millimetres: the same part must give the same numbers.

pybullet is not a dependency of closure_nlp; this script installs it (``pip install pybullet``)
when it is missing. Writes ``examples/out/real_meshes.md`` and ``.csv``.

    python examples/real_meshes.py [--meshes domino mug ...] [--seed 0]
"""

from __future__ import annotations

import argparse
import csv
import importlib
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import trimesh

from closure_nlp import (
    Eligibility,
    MethodError,
    characterize_mesh,
    contact_specs,
    drop_outward_as_read,
    plan,
)

OUT = Path(__file__).parent / "out"
MESHES = {
    "domino": "domino/domino.obj",
    "cylinder": "toys/cylinder.obj",
    "mug": "objects/mug.obj",
    "mug_col": "objects/mug_col.obj",
    "teddy": "teddy2_VHACD_CHs.obj",
    "duck": "duck.obj",
    "sphere": "sphere_smooth.obj",
    "lego": "lego/lego.obj",
}
GRASPS = {"4 pcwf": (4, "pcwf"), "7 fpc": (7, "fpc")}
# Convex decompositions whose hulls stay apart in places after their union: one rigid part by
# choice (`characterize --merge-bodies`).
MERGE_BODIES = {"teddy"}


def pybullet_data_path() -> Path:
    try:
        module = importlib.import_module("pybullet_data")
    except ImportError:
        print("installing pybullet (for its data files only) ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "pybullet"], check=True)
        module = importlib.import_module("pybullet_data")
    return Path(module.getDataPath())


def run_one(name: str, mesh, units: str, seed: int) -> list[dict]:
    t = time.perf_counter()
    try:
        found = characterize_mesh(
            mesh, units=units, name=name, merge_bodies=name in MERGE_BODIES, mesh_ref="m.stl"
        )
    except ValueError as exc:
        return [{"mesh": name, "units": units, "error": str(exc).split(": ", 1)[-1][:160]}]
    # As `closure-nlp characterize` writes it: the elements the model commands refuse against
    # the written mesh are dropped (plan and show would refuse the model otherwise).
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "m.stl").write_bytes(found.mesh.export(file_type="stl"))
        model, dropped = drop_outward_as_read(found.model, folder)
    model = replace(model, mesh=None)
    seconds = time.perf_counter() - t
    repairs = list(found.repairs) + [f"dropped {line.split(' (')[0]}" for line in found.dropped]
    if dropped:
        repairs.append(f"dropped {len(dropped)} element(s) whose normal points out of the mesh")
    rows = []
    for grasp, (m, kind) in GRASPS.items():
        row = {
            "mesh": name,
            "units": units,
            "radius": f"{model.radius:.4g}",
            "elements": "/".join(str(n) for n in model.counts().values()),
            "characterize_s": f"{seconds:.2f}",
            "repairs": "; ".join(repairs),
            "grasp": grasp,
        }
        # model=: the automatic mu_s; Eligibility's torque scale is automatic by default
        hand = Eligibility(model, contact_specs(m, type=kind, model=model))
        t = time.perf_counter()
        try:
            run = plan(hand, seeds=1, seed=seed)
            row.update(
                rho_hat=f"{run.iterative.rho_hat:.6g}",
                rho=f"{run.placement.rho:.9g}",
                force_closure=run.placement.force_closure,
            )
        except MethodError as exc:
            row.update(error=str(exc)[:160])
        row["plan_s"] = f"{time.perf_counter() - t:.1f}"
        rows.append(row)
        print(row, flush=True)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", nargs="+", choices=sorted(MESHES), default=list(MESHES))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    data = pybullet_data_path()
    rows = []
    for name in args.meshes:
        path = data / MESHES[name]
        if name != "domino":
            rows += run_one(name, path, "m", args.seed)
            continue
        # The same part in metres and in millimetres, from the same triangles in the same order.
        for units, factor in (("m", 1.0), ("mm", 1000.0)):
            mesh = trimesh.load(str(path), force="mesh")
            mesh.apply_scale(factor)
            rows += run_one(name, mesh, units, args.seed)
    keys = [
        "mesh",
        "units",
        "radius",
        "elements",
        "characterize_s",
        "grasp",
        "rho_hat",
        "rho",
        "force_closure",
        "plan_s",
        "repairs",
        "error",
    ]
    OUT.mkdir(exist_ok=True)
    if (OUT / "real_meshes.csv").exists():  # keep the rows of the meshes not run this time
        with open(OUT / "real_meshes.csv", newline="") as f:
            kept = [r for r in csv.DictReader(f) if r["mesh"] not in args.meshes]
        order = {name: k for k, name in enumerate(MESHES)}
        rows = sorted(kept + rows, key=lambda r: order.get(r["mesh"], len(order)))
    with open(OUT / "real_meshes.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, keys)
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(str(r.get(k, "")) for k in keys) + " |" for r in rows]
    (OUT / "real_meshes.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
