"""Fixture-design and grasp studies at scale, on Dask (closure_nlp.study).

    python examples/fixture_study.py [--small] [--seeds N] [--out examples/out/studies]
                                     [--workers N] [--scheduler ADDRESS] [--serial]
                                     [--study fixtures,grasps]

Two studies, from ``examples/studies/``:

- ``fixtures.toml``: 7-locator layouts (FPC, and PCwF with mu 0.1, 0.2, 0.3) on the pistol and on
  two machined-part look-alikes, an L-bracket and a stepped shaft with wrench flats, 20 seeds;
- ``grasps.toml``: 3 and 4 PCwFs, SFCls and SFCes on the lamp and the cup, 20 seeds.

The two machined parts are meshes made here with trimesh and described by
:func:`closure_nlp.characterize`; their STL and model files are written to
``examples/studies/models/`` if missing. ``--small`` runs a CI-sized version of both studies
(FPC fixtures and 3-finger PCwF/SFCe grasps, one seed, one placement start; under a minute on 2
workers); ``--seeds N`` keeps the whole grid with N seeds. Run it again and finished tasks are
skipped. Each study writes ``summary.md``, ``summary.csv``,
``results.csv``, ``rho.png`` and ``seconds.png`` in its own folder under ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from closure_nlp import (
    Study,
    characterize,
    load_study,
    local_cluster,
    run_study,
    save_model,
    study_from_dict,
)

HERE = Path(__file__).resolve().parent
STUDIES = HERE / "studies"
MODELS = STUDIES / "models"

# --small: these keys of each study are replaced (same models, contact types and counts).
FAST = {"starts": 1, "max_rounds": 20}  # one placement start (more only while not closed)
SMALL = {
    "fixtures": {"type": "fpc", "seeds": 1, "placement": FAST},
    "grasps": {"type": ["pcwf", "sfce"], "contacts": 3, "seeds": 1, "placement": FAST},
}

RING = 18  # vertices per cross-section of the shaft (3 per side of its hexagon)


# --- the machined parts ----------------------------------------------------------------------


def l_bracket() -> trimesh.Trimesh:
    """An L-bracket (mm): legs 60 and 45 long, 8 thick, 30 wide; the L in the x-z plane."""
    outline = np.array([[0, 0], [60, 0], [60, 8], [8, 8], [8, 45], [0, 45]], dtype=float)
    width = 30.0
    n = len(outline)
    vertices = np.vstack(
        [
            np.column_stack([outline[:, 0], np.zeros(n), outline[:, 1]]),
            np.column_stack([outline[:, 0], np.full(n, width), outline[:, 1]]),
        ]
    )
    faces = []
    for a, b, c in [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)]:  # the L, fanned from a corner
        faces += [(a, c, b), (a + n, b + n, c + n)]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, j + n), (i, j + n, i + n)]
    return _closed(vertices, faces)


def _circle(radius: float) -> np.ndarray:
    t = 2 * np.pi * np.arange(RING) / RING
    return np.column_stack([radius * np.cos(t), radius * np.sin(t)])


def _hexagon(across_flats: float) -> np.ndarray:
    """A hexagon sampled with ``RING`` points, so it joins a circle's ring."""
    r = across_flats / 2 / np.cos(np.pi / 6)
    corners = [r * np.array([np.cos(k * np.pi / 3), np.sin(k * np.pi / 3)]) for k in range(7)]
    per = RING // 6
    return np.array(
        [corners[k] + (corners[k + 1] - corners[k]) * j / per for k in range(6) for j in range(per)]
    )


def stepped_shaft() -> trimesh.Trimesh:
    """A stepped shaft (mm) along z: a chamfered dia. 32 journal, 22 mm wrench flats, a dia. 18
    end. The flats let frictionless locators stop the rotation about the axis."""
    rings = [
        (0.0, _circle(14.0)),
        (2.0, _circle(16.0)),
        (40.0, _circle(16.0)),
        (40.0, _hexagon(22.0)),
        (70.0, _hexagon(22.0)),
        (70.0, _circle(9.0)),
        (110.0, _circle(9.0)),
    ]
    vertices = [np.column_stack([ring, np.full(RING, z)]) for z, ring in rings]
    faces = []
    for a in range(len(rings) - 1):
        for i in range(RING):
            j = (i + 1) % RING
            p, q, r, s = a * RING + i, a * RING + j, (a + 1) * RING + j, (a + 1) * RING + i
            faces += [(p, q, r), (p, r, s)]
    centre = len(rings) * RING
    last = (len(rings) - 1) * RING
    for i in range(RING):
        j = (i + 1) % RING
        faces += [(centre, j, i), (centre + 1, last + i, last + j)]
    ends = [[0.0, 0.0, rings[0][0]], [0.0, 0.0, rings[-1][0]]]
    return _closed(np.vstack(vertices + [ends]), faces)


def _closed(vertices, faces) -> trimesh.Trimesh:
    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    if not mesh.is_volume:
        raise RuntimeError("the part's mesh is not a closed volume")
    return mesh


PARTS = {"l_bracket": l_bracket, "stepped_shaft": stepped_shaft}


def build_models(folder: Path = MODELS) -> list[Path]:
    """Write ``<part>.stl`` and ``<part>.model.json`` for each machined part, if missing."""
    written = []
    for name, make in PARTS.items():
        model_path = folder / f"{name}.model.json"
        if model_path.exists():
            continue
        folder.mkdir(parents=True, exist_ok=True)
        mesh = make()
        (folder / f"{name}.stl").write_bytes(mesh.export(file_type="stl"))
        # The options the committed models were made with (before spacing and reference
        # point had defaults of their own): every ruling kept, torques about the origin.
        model = characterize(
            mesh,
            name=name,
            units="mm",
            mesh_ref=f"{name}.stl",
            segment_spacing=0,
            point_spacing=0,
            reference_point=(0.0, 0.0, 0.0),
        )
        save_model(model, model_path)
        counts = ", ".join(f"{n} {kind}s" for kind, n in model.counts().items())
        print(f"{model_path}: {counts}")
        written.append(model_path)
    return written


# --- running ---------------------------------------------------------------------------------


def study(name: str, small: bool, seeds: int | None = None) -> Study:
    """The study ``name`` (``fixtures`` or ``grasps``), or its ``--small`` version; ``seeds``
    replaces the study's number of seeds."""
    path = STUDIES / f"{name}.toml"
    if not small and seeds is None:
        return load_study(path)
    data = tomllib.loads(path.read_text())
    changes = dict(SMALL[name]) if small else {}
    if seeds is not None:
        changes["seeds"] = seeds
    overrides = dict(changes)
    data["placement"] = {**data.get("placement", {}), **overrides.pop("placement", {})}
    label = f"{name}-small" if small else f"{name}-{seeds}seeds"
    changed = ", ".join(f"{k} = {v!r}" for k, v in changes.items())
    description = f"{'CI-sized' if small else 'Reduced'} version ({changed}) of: "
    data.update(overrides, name=label, description=description + data.get("description", name))
    return study_from_dict(data, STUDIES, default_name=label, source=path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="CI-sized studies")
    parser.add_argument("--out", type=Path, default=HERE / "out" / "studies")
    parser.add_argument("--study", default="fixtures,grasps", help="comma list of studies")
    parser.add_argument("--seeds", type=int, help="replace the studies' number of seeds")
    parser.add_argument("--workers", type=int, help="local worker processes (default: cores)")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler to use")
    parser.add_argument("--serial", action="store_true", help="no Dask: one task after another")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.study.split(",") if n.strip()]
    unknown = sorted(set(names) - set(SMALL))
    if unknown:
        parser.error(f"--study: unknown study {unknown[0]!r} (known: {', '.join(SMALL)})")
    build_models()
    if args.seeds is not None and args.seeds < 1:
        parser.error(f"--seeds: expected an integer >= 1, got {args.seeds}")
    # every study is validated before any runs
    studies = [study(name, args.small, args.seeds) for name in names]
    client = cluster = None
    if not args.serial:
        from distributed import Client

        if args.scheduler:
            client = Client(args.scheduler)
        else:
            cluster = local_cluster(args.workers)
            client = Client(cluster)
    try:
        for s in studies:
            t0 = time.perf_counter()
            result = run_study(
                s,
                args.out / s.name,
                client=client,
                serial=args.serial,
                progress=_progress(s.name),
            )
            print(
                f"{s.name}: {result.total} tasks ({result.run} run, {result.failed} failed, "
                f"{result.skipped} done before) in {time.perf_counter() - t0:.1f} s on "
                f"{result.workers} worker(s): {result.tasks_per_second:.3f} tasks/s"
            )
            print(Path(result.paths["summary.md"]).read_text())
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    return 0


def _progress(name: str):
    def report(done: int, total: int, row) -> None:
        if row is not None:
            rho = "error" if row["status"] != "ok" else f"rho {row['rho']:+.4f}"
            if row.get("gap") is not None:
                rho += f" (gap {100 * row['gap']:.2g}%)"
            print(
                f"  {name} {done}/{total}: {row['model']} {row['type']} x{row['contacts']} "
                f"seed {row['seed']}: {rho}",
                file=sys.stderr,
            )

    return report


if __name__ == "__main__":
    sys.exit(main())
