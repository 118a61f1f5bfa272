"""Build the machined block: a 60 x 40 x 20 mm box with a 10 mm through hole (along z, at its
centre), as ``block.stl`` and its element model ``block.model.json`` (``characterize``).

Run ``python examples/block/build_block.py [OUT_DIR]`` (default: this script's folder). The box
spans x in [-30, 30], y in [-20, 20], z in [0, 20]: its bottom face (z = 0) holds the base
locators of a 3-2-1 layout, its top face (z = 20) is the machined one.
"""

from __future__ import annotations

import sys
from pathlib import Path

import trimesh

from closure_nlp import characterize, save_model

HERE = Path(__file__).resolve().parent
SIZE = (60.0, 40.0, 20.0)  # mm
HOLE_DIAMETER = 10.0
HOLE_SECTIONS = 32


def block_mesh() -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=SIZE)
    hole = trimesh.creation.cylinder(
        radius=HOLE_DIAMETER / 2, height=2 * SIZE[2], sections=HOLE_SECTIONS
    )
    block = box.difference(hole)
    block.apply_translation([0.0, 0.0, SIZE[2] / 2])  # the bottom face at z = 0
    return block


def build(out_dir: Path = HERE) -> Path:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    mesh_path = out_dir / "block.stl"
    block_mesh().export(mesh_path)
    model = characterize(mesh_path, name="block", units="mm", mesh_ref="block.stl")
    path = out_dir / "block.model.json"
    save_model(model, path)
    return path


if __name__ == "__main__":
    print(build(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE))
