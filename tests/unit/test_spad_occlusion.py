"""SPAD scene (sims.spad.scene) from the full scene description: user meshes as hidden surfaces and
occlusion by other walls, objects and meshes, against closed forms and the built-in box."""
import numpy as np
import pytest
import trimesh

from sims.spad.occlusion import blocked_by_segments
from sims.spad.scene import SpadParams, expected_signal, hidden_patches, visible_patches
from xnlos_core.errors import InputError
from xnlos_core.scene import Scene

# relay wall along y at x = 10 (u = −y, n = −x toward the sensor); grid_offset −1 puts the grid
# centre at world (10, 1), 0.75 m up; a 0.5 × 0.5 × 1.5 m crate 2 m in front of it at (7.75, 1).
P = dict(grid_points=(5, 5), n_bins=512, bin_width=32e-12, grid_width=1.0, grid_height=1.0, grid_elevation=0.75,
         grid_offset=-1.0, dark_count_rate=0.0, ambient_rate=0.0, patch_size=0.1)
FACADE = {"name": "facade", "start": [10.0, 5.0], "end": [10.0, -5.0]}
CRATE = {"name": "crate", "center": [7.75, 1.0], "size": [0.5, 0.5], "heading": 0.0, "height": 1.5}


def _scene(walls=(), objects=(CRATE,), meshes=(), base_dir="."):
    return Scene.model_validate({"walls": [FACADE, *walls], "objects": list(objects), "meshes": list(meshes),
                                 "base_dir": str(base_dir)})


def test_segment_test_closed_form():
    c = np.array([0.0, 0.0, 1.0])
    p = np.array([[4.0, 0.0, 1.0], [4.0, 0.0, 5.0], [1.0, 0.0, 1.0], [4.0, 3.0, 1.0]])
    # a wall x = 2, y ∈ [−1, 1], 2 m high: the first segment crosses it at z = 1, the second at
    # z = 3 (over it), the third ends before it, the fourth passes beside it (y = 1.5 at x = 2)
    hit = blocked_by_segments(c, p, np.array([[2.0, -1.0]]), np.array([[2.0, 1.0]]), np.array([2.0]))
    assert hit.tolist() == [True, False, False, False]


def test_screen_wall_removes_exactly_the_patches_below_its_shadow_line():
    h = 0.9
    screen = {"name": "screen", "start": [9.0, -1.0], "end": [9.0, 3.0], "relay": False, "height": h}
    params = SpadParams(**P)
    free = hidden_patches(_scene(), params.model_copy(update={"occlusion": False}))
    seen = hidden_patches(_scene([screen]), params)
    # closed form in wall coordinates: the grid centre is the origin, the screen the plane z = 1;
    # the segment to a patch (x, y, z) meets it at height 0.75 + y/z above the ground
    c = free.centers
    blocked = 0.75 + c[:, 1] / c[:, 2] < h
    assert 0 < blocked.sum() < len(c)
    np.testing.assert_allclose(seen.centers, c[~blocked])
    full = {**screen, "height": 3.0}  # a full-height screen: no photons at all
    assert expected_signal(_scene([full]), params).sum() == 0.0
    assert expected_signal(_scene(), params).sum() > 0.0


def test_box_object_shadows_another_but_not_itself():
    params = SpadParams(**P)
    alone = hidden_patches(_scene(), params)
    assert len(alone.areas) == len(hidden_patches(_scene(), params.model_copy(update={"occlusion": False})).areas)
    shield = {"name": "shield", "center": [9.0, 1.0], "size": [0.2, 3.0], "heading": 0.0, "height": 3.0}
    both = hidden_patches(_scene(objects=(CRATE, shield)), params)
    # only the shield's own patches remain (all at wall depth z ≤ 1.1 m); the crate at z ≥ 2 m is gone
    assert len(both.areas) > 0 and both.centers[:, 2].max() < 1.2


def _write_box(tmp_path, name, extents, centre):
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(centre)
    mesh.export(tmp_path / name)
    return {"name": name.split(".")[0], "file": name, "material": "concrete"}


def test_mesh_box_equals_builtin_box(tmp_path):
    params = SpadParams(**P)
    spec = _write_box(tmp_path, "crate.stl", (0.5, 0.5, 1.5), (7.75, 1.0, 0.75))
    built = expected_signal(_scene(), params)
    meshed = expected_signal(_scene(objects=(), meshes=[spec], base_dir=tmp_path), params)
    # same surfaces cut differently (triangles ≤ 0.1 m vs 0.1 m squares): photons per scan point
    # within 2 %, and the transients alike on 0.5 ns bins (16 × 32 ps: the patch centres of the two
    # cuts lie up to 5 cm apart in range, so 32 ps bins differ)
    np.testing.assert_allclose(meshed.sum(axis=0), built.sum(axis=0), rtol=0.02)
    coarse = lambda v: v.reshape(32, 16, 5, 5).sum(axis=1)  # noqa: E731
    assert np.abs(coarse(meshed) - coarse(built)).sum() / built.sum() < 0.05
    # the mesh's bottom face never faces the grid: its visible area is the built-in box's
    vm = visible_patches(_scene(objects=(), meshes=[spec], base_dir=tmp_path), params)
    vb = visible_patches(_scene(), params)
    assert vm.areas.sum() == pytest.approx(vb.areas.sum(), rel=1e-9)


def test_mesh_screen_occludes_and_patch_budget_is_an_error(tmp_path):
    params = SpadParams(**P)
    spec = _write_box(tmp_path, "screen.stl", (0.1, 4.0, 3.0), (9.0, 1.0, 1.5))
    sc = _scene(meshes=[spec], base_dir=tmp_path)
    pt = hidden_patches(sc, params)
    assert pt.centers[:, 2].max() < 1.1  # only the screen's own face toward the grid (z = 0.95 m)
    assert expected_signal(sc, params).sum() > 0
    with pytest.raises(InputError, match="max_patches"):
        hidden_patches(sc, params.model_copy(update={"max_patches": 100}))
