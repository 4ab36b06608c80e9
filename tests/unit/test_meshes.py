"""User meshes (sims.meshes): every loader format, material tags, placement, and every bad input."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sims.meshes import check_scene_geometry, load_user_mesh
from xnlos_core.errors import InputError
from xnlos_core.scene import MeshSpec, ObjectSpec, Scene, WallSpec

DATA = Path(__file__).parents[1] / "data" / "meshes"
TAGS = {"concrete_part": "concrete", "glass_part": "glass"}


def test_example_meshes_are_small():
    files = sorted(p for p in DATA.iterdir() if p.suffix in {".obj", ".mtl", ".stl", ".ply", ".glb"})
    assert len(files) >= 6
    assert all(p.stat().st_size < 50_000 for p in files)


def test_obj_usemtl_groups_become_tags():
    parts = load_user_mesh(MeshSpec(file="box_tagged.obj", materials=TAGS), DATA)
    assert [(t, m) for _, m, t in parts] == [("concrete_part", "concrete"), ("glass_part", "glass")]
    assert [len(mesh.faces) for mesh, _, _ in parts] == [6, 6]  # each half of the box


@pytest.mark.parametrize("name", ["box.stl", "box.ply"])
def test_single_mesh_formats_load_as_one_closed_part(name):
    ((mesh, material, tag),) = load_user_mesh(MeshSpec(file=name, material="brick"), DATA)
    assert (material, tag) == ("brick", name)
    assert mesh.is_watertight and len(mesh.faces) == 12
    np.testing.assert_allclose(mesh.bounds, [[-0.5] * 3, [0.5] * 3], atol=1e-6)


def test_glb_geometry_names_are_tags():
    parts = load_user_mesh(MeshSpec(file="parts.glb", materials={"glass_part": "glass"}, material="concrete"), DATA)
    assert [(t, m) for _, m, t in parts] == [("concrete_part", "concrete"), ("glass_part", "glass")]


def test_default_material_covers_untagged_parts_and_constants_give_none():
    parts = load_user_mesh(MeshSpec(file="box_tagged.obj", materials={"glass_part": "Glass"}, material="wood"), DATA)
    assert [m for _, m, _ in parts] == ["wood", "glass"]  # names are normalised by sims.materials
    parts = load_user_mesh(MeshSpec(file="box.stl", reflectivity=0.5), DATA)
    assert parts[0][1] is None


def test_placement_scales_then_turns_then_moves():
    spec = MeshSpec(file="box_tagged.obj", material="concrete", scale=2.0, yaw=math.pi / 2,
                    translation=(10.0, -1.0, 0.5))
    lo, hi = np.min([m.bounds[0] for m, _, _ in load_user_mesh(spec, DATA)], axis=0), \
        np.max([m.bounds[1] for m, _, _ in load_user_mesh(spec, DATA)], axis=0)
    # box [0, 2]×[0, 1]×[0, 1] → ×2 → turned +90° about z: x ∈ [−2, 0], y ∈ [0, 4] → moved
    np.testing.assert_allclose(lo, [8.0, -1.0, 0.5], atol=1e-9)
    np.testing.assert_allclose(hi, [10.0, 3.0, 2.5], atol=1e-9)


def test_absolute_paths_ignore_base_dir():
    parts = load_user_mesh(MeshSpec(file=str(DATA / "box.stl"), material="metal"), "/nonexistent")
    assert parts[0][1] == "metal"


# ---- bad input --------------------------------------------------------------------------------
def test_non_watertight_mesh_names_file_and_open_edges():
    with pytest.raises(InputError, match=r"open_box\.stl.*not watertight: 4 open edge"):
        load_user_mesh(MeshSpec(file="open_box.stl", material="concrete"), DATA)
    ((mesh, _, _),) = load_user_mesh(MeshSpec(file="open_box.stl", material="concrete"), DATA,
                                     require_watertight=False)
    assert len(mesh.faces) == 10


@pytest.mark.parametrize("content, name", [(b"", "empty.stl"), (b"v 0 0 0\nv 1 0 0\n", "points.obj"),
                                           (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty "
                                            b"float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n", "cloud.ply")])
def test_empty_meshes_are_refused(tmp_path, content, name):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError, match="no triangles"):
        load_user_mesh(MeshSpec(file=name, material="concrete"), tmp_path)


def test_missing_unreadable_and_unsupported_files(tmp_path):
    with pytest.raises(InputError, match=r"missing\.stl not found"):
        load_user_mesh(MeshSpec(file="missing.stl"), tmp_path)
    (tmp_path / "junk.glb").write_bytes(bytes(range(256)))
    with pytest.raises(InputError, match=r"cannot read .*junk\.glb as GLB"):
        load_user_mesh(MeshSpec(file="junk.glb"), tmp_path)
    (tmp_path / "model.fbx").write_bytes(b"x")
    with pytest.raises(InputError, match=r"unsupported file type '\.fbx'.*\.obj, \.stl, \.ply, \.glb, \.gltf"):
        load_user_mesh(MeshSpec(file="model.fbx"), tmp_path)
    (tmp_path / "dir.stl").mkdir()
    with pytest.raises(InputError, match="is a directory"):
        load_user_mesh(MeshSpec(file="dir.stl"), tmp_path)


def test_unknown_material_has_did_you_mean():
    with pytest.raises(InputError, match=r"materials\['glass_part'\]: unknown material 'glas' — did you mean 'glass'"):
        load_user_mesh(MeshSpec(file="box_tagged.obj", materials={"concrete_part": "concrete",
                                                                 "glass_part": "glas"}), DATA)
    with pytest.raises(InputError, match=r"material: unknown material 'konkrete'"):
        load_user_mesh(MeshSpec(file="box.stl", material="konkrete"), DATA)


def test_unmapped_tag_without_default_material():
    with pytest.raises(InputError, match=r"part 'glass_part' has no entry in materials .* no default material"):
        load_user_mesh(MeshSpec(file="box_tagged.obj", materials={"concrete_part": "concrete"}), DATA)


def test_materials_key_that_is_no_part_of_the_file():
    with pytest.raises(InputError, match=r"'glass_prt' \(did you mean 'glass_part'\?\).*its parts: concrete_part, "
                                         r"glass_part"):
        load_user_mesh(MeshSpec(file="box_tagged.obj", materials={"concrete_part": "concrete",
                                                                 "glass_prt": "glass"}), DATA)


def test_obj_without_its_material_library_explains_the_missing_tags(tmp_path):
    shutil.copy(DATA / "box_tagged.obj", tmp_path / "box_tagged.obj")  # no .mtl beside it
    with pytest.raises(InputError, match=r"usemtl concrete_part, glass_part.*box_tagged\.mtl"):
        load_user_mesh(MeshSpec(file="box_tagged.obj", materials=TAGS), tmp_path)
    parts = load_user_mesh(MeshSpec(file="box_tagged.obj", material="concrete"), tmp_path)
    assert len(parts) == 2  # still split by usemtl, still closed together


# ---- scene checks -----------------------------------------------------------------------------
def _scene(**kw) -> Scene:
    base = dict(name="s", walls=[WallSpec(name="facade", start=(10.0, -5.0), end=(10.0, 5.0), material="concrete")],
                base_dir=str(DATA))
    return Scene(**{**base, **kw})


def test_valid_scene_passes():
    check_scene_geometry(_scene(objects=[ObjectSpec(center=(5.0, 0.0))],
                                meshes=[MeshSpec(file="box.stl", material="concrete", translation=(20.0, 0.0, 0.5))]))


def test_object_inside_or_against_a_wall():
    with pytest.raises(InputError, match=r"object 'car' .* inside or against wall\(s\) 'facade'"):
        check_scene_geometry(_scene(objects=[ObjectSpec(name="car", center=(10.5, 0.0), size=(4.5, 1.8))]))
    thick = WallSpec(name="slab", start=(10.0, -5.0), end=(10.0, 5.0), material="brick", thickness=2.0)
    with pytest.raises(InputError, match="'slab'"):  # 0.2 m clear of the segment but inside the 2 m slab
        check_scene_geometry(_scene(walls=[thick], objects=[ObjectSpec(shape="point", center=(9.2, 0.0))]))
    check_scene_geometry(_scene(walls=[thick.model_copy(update={"thickness": 0.3})],
                                objects=[ObjectSpec(shape="point", center=(9.2, 0.0))]))


def test_object_against_a_curved_wall_facet():
    arc = WallSpec(name="arc", start=(20.0, -8.0), end=(20.0, 8.0), radius=10.0, material="concrete")
    mid = arc.vertices()[len(arc.vertices()) // 2]
    with pytest.raises(InputError, match=r"wall\(s\) 'arc\["):
        check_scene_geometry(_scene(walls=[arc], objects=[ObjectSpec(shape="point", center=tuple(mid))]))


def test_radar_inside_a_wall_or_a_mesh():
    with pytest.raises(InputError, match="radar at .* inside wall 'through'"):
        check_scene_geometry(_scene(walls=[WallSpec(name="through", start=(-5.0, 0.0), end=(5.0, 0.0))]))
    # above a low wall the radar is not inside it
    check_scene_geometry(_scene(walls=[WallSpec(name="low", start=(-5.0, 0.0), end=(5.0, 0.0), height=0.5)]))
    with pytest.raises(InputError, match=r"radar at .* inside mesh 'hut'"):
        check_scene_geometry(_scene(meshes=[MeshSpec(name="hut", file="box.stl", material="concrete", scale=4.0)]))
    with pytest.raises(InputError, match=r"radar at \(3.0, 0.0, 1.0\) is inside mesh"):
        check_scene_geometry(_scene(meshes=[MeshSpec(file="box.stl", material="concrete", scale=3.0,
                                                     translation=(3.0, 0.0, 1.0))]), radar_position=(3.0, 0.0, 1.0))
    # an open mesh has no inside: not refused here
    check_scene_geometry(_scene(meshes=[MeshSpec(file="open_box.stl", material="concrete", scale=4.0)]))


def test_object_inside_a_mesh():
    with pytest.raises(InputError, match=r"object 'car' .* inside mesh 'garage'"):
        check_scene_geometry(_scene(objects=[ObjectSpec(name="car", center=(20.0, 0.0))],
                                    meshes=[MeshSpec(name="garage", file="parts.glb", material="concrete", scale=3.0,
                                                     translation=(20.0, 0.0, 4.0))]))


def test_bad_radar_position():
    with pytest.raises(InputError, match="radar_position"):
        check_scene_geometry(_scene(), radar_position=(0.0, 0.0))
