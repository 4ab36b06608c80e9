"""Writes the small example meshes the tests load (run once: `python tests/data/meshes/make_meshes.py`).

* box_tagged.obj + box_tagged.mtl: a 2 × 1 × 1 m box whose faces carry two usemtl groups,
  "concrete_part" (bottom, top, front) and "glass_part" (the other three sides);
* box.stl (binary), box.ply (ASCII): a 1 m cube centred at the origin;
* parts.glb: two boxes, geometries "concrete_part" and "glass_part";
* open_box.stl: the cube with its top face removed (not watertight: 4 open edges).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).parent

# a 2 × 1 × 1 m box: vertices (x, y, z) 1-based in OBJ order
VERTS = [(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0), (0, 0, 1), (2, 0, 1), (2, 1, 1), (0, 1, 1)]
CONCRETE = [(1, 3, 2), (1, 4, 3), (5, 6, 7), (5, 7, 8), (1, 2, 6), (1, 6, 5)]  # bottom, top, y = 0 side
GLASS = [(2, 3, 7), (2, 7, 6), (3, 4, 8), (3, 8, 7), (4, 1, 5), (4, 5, 8)]  # x = 2, y = 1, x = 0 sides


def write_obj() -> None:
    lines = ["# 2 x 1 x 1 m box with two material groups", "mtllib box_tagged.mtl"]
    lines += [f"v {x} {y} {z}" for x, y, z in VERTS]
    for name, faces in (("concrete_part", CONCRETE), ("glass_part", GLASS)):
        lines.append(f"usemtl {name}")
        lines += [f"f {a} {b} {c}" for a, b, c in faces]
    (HERE / "box_tagged.obj").write_text("\n".join(lines) + "\n")
    (HERE / "box_tagged.mtl").write_text("newmtl concrete_part\nKd 0.6 0.6 0.6\n\nnewmtl glass_part\n"
                                         "Kd 0.3 0.5 0.8\n")


def main() -> None:
    write_obj()
    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    cube.export(HERE / "box.stl")
    cube.export(HERE / "box.ply", encoding="ascii")
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(4.0, 1.0, 3.0)), geom_name="concrete_part",
                       node_name="concrete_part")
    glass = trimesh.creation.box(extents=(1.0, 0.5, 1.0))
    glass.apply_translation((0.0, 0.0, 2.5))
    scene.add_geometry(glass, geom_name="glass_part", node_name="glass_part")
    (HERE / "parts.glb").write_bytes(scene.export(file_type="glb"))
    top = np.flatnonzero(cube.face_normals[:, 2] > 0.5)
    open_box = trimesh.Trimesh(cube.vertices, np.delete(cube.faces, top, axis=0), process=False)
    open_box.export(HERE / "open_box.stl")


if __name__ == "__main__":
    main()
