"""Mesh vertices are range-checked when a mesh is loaded (sims.meshes.load_user_mesh, the one loader
of `xnlos check` and of the forward models that `run` uses): finite and within the scene bound
±MAX_COORD (10 km) once placed. An OBJ with vertices at 1e308 used to pass `check` and `run`."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sims.meshes import check_scene_geometry, load_user_mesh
from xnlos_core.app.cli import check_file
from xnlos_core.errors import InputError
from xnlos_core.scene import MAX_COORD, MeshSpec, Scene

CUBE = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
FACES = [(1, 3, 2), (1, 4, 3), (5, 6, 7), (5, 7, 8), (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 4, 8),
         (3, 8, 7), (4, 1, 5), (4, 5, 8)]
PIPELINE = """\
seed = 1
[radar]
n_samples = 256
max_range = 60.0
n_azimuth_bins = 61
[scene]
builtin = "corner"
[[scene.meshes]]
file = "{file}"
material = "concrete"
translation = [20.0, -20.0, 0.0]
[forward_model]
name = "raytrace"
[detector]
name = "nlos_cfar"
[wall_estimator]
name = "lsq"
[reconstructor]
name = "mirror"
"""


def obj(path: Path, vertices) -> Path:
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices)
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in FACES))
    return path


def test_obj_with_1e308_vertices_is_refused_naming_the_vertex(tmp_path):
    obj(tmp_path / "big.obj", [(x * 1e308, y * 1e308, z) for x, y, z in CUBE])
    with pytest.raises(InputError, match=r"mesh 'm' .*big\.obj\): part .* has 6 of 8 vertices beyond ±10000 m in the "
                                         r"scene frame, e.g. vertex 1 at \[1e\+308, 0\.0, 0\.0\] in the file"):
        load_user_mesh(MeshSpec(name="m", file="big.obj", material="concrete"), tmp_path)


def test_no_non_finite_vertex_gets_through(tmp_path):
    """trimesh drops the faces of a NaN vertex (the mesh is then open); an inf one is refused."""
    obj(tmp_path / "nan.obj", [(float("nan"), 0.0, 0.0)] + CUBE[1:])
    for mesh, _, _ in load_user_mesh(MeshSpec(file="nan.obj", material="concrete"), tmp_path, require_watertight=False):
        assert np.isfinite(mesh.vertices).all()
    obj(tmp_path / "inf.obj", [(float("inf"), 0.0, 0.0)] + CUBE[1:])
    try:
        parts = load_user_mesh(MeshSpec(file="inf.obj", material="concrete"), tmp_path, require_watertight=False)
    except InputError as exc:
        assert "beyond ±10000 m" in str(exc) or "cannot read" in str(exc), exc
    else:
        assert all(np.isfinite(m.vertices).all() for m, _, _ in parts)


def test_the_bound_applies_after_placement(tmp_path):
    obj(tmp_path / "cube.obj", CUBE)
    inside = MeshSpec(file="cube.obj", material="concrete", scale=1000.0, translation=(MAX_COORD - 1000.0, 0.0, 0.0))
    ((mesh, _, _),) = load_user_mesh(inside, tmp_path)
    assert mesh.bounds[1][0] == pytest.approx(MAX_COORD)
    beyond = inside.model_copy(update={"translation": (MAX_COORD - 999.0, 0.0, 0.0)})
    with pytest.raises(InputError, match=r"4 of 8 vertices beyond ±10000 m .* \[10001\.0, 0\.0, 0\.0\] m placed "
                                         r"\(scale 1000"):
        load_user_mesh(beyond, tmp_path)


def test_check_and_the_scene_check_refuse_it(tmp_path):
    """`xnlos check` (check_file → the raytrace model's check → build_world) and the geometry check
    that `run` also goes through refuse it with the same message."""
    obj(tmp_path / "big.obj", [(x * 1e308, y * 1e308, z) for x, y, z in CUBE])
    (tmp_path / "p.toml").write_text(PIPELINE.format(file="big.obj"))
    with pytest.raises(InputError, match=r"vertices beyond ±10000 m in the scene frame"):
        check_file(tmp_path / "p.toml")
    scene = Scene(meshes=[MeshSpec(file="big.obj", material="concrete", translation=(20.0, -20.0, 0.0))],
                  base_dir=str(tmp_path))
    with pytest.raises(InputError, match=r"vertices beyond ±10000 m in the scene frame"):
        check_scene_geometry(scene)
    from sims.raytrace.world import build_world

    with pytest.raises(InputError, match=r"vertices beyond ±10000 m in the scene frame"):
        build_world(scene)
    obj(tmp_path / "ok.obj", CUBE)
    (tmp_path / "ok.toml").write_text(PIPELINE.format(file="ok.obj"))
    check_file(tmp_path / "ok.toml")
