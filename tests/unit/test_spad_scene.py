"""SPAD scan of a project Scene (sims.spad.scene): wall-coordinate mapping and the simulated volume."""
import numpy as np
import pytest
from pydantic import ValidationError

from sims.spad.scene import SpadParams, expected_volume, hidden_patches, relay_wall, simulate
from xnlos_core.errors import InputError
from xnlos_core.scene import Scene
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume

SMALL = dict(grid_points=(5, 5), n_bins=512, bin_width=32e-12, grid_width=1.0, grid_height=1.0,
             grid_elevation=0.75)


def scene(depth=2.0, obj="box"):
    # relay wall along y at x = 10 (start (10, 5) → end (10, −5): u = −y); sensor at the origin,
    # so n = −x; an object `depth` in front of it, toward the sensor.
    o = {"name": "crate", "shape": obj, "center": [10.0 - depth - 0.25, 1.0], "size": [0.5, 0.5],
         "heading": 0.0, "height": 1.5}
    return Scene.model_validate({"walls": [{"name": "w0", "start": [10.0, 5.0], "end": [10.0, -5.0], "relay": False},
                                           {"name": "facade", "start": [10.0, 5.0], "end": [10.0, -5.0]}],
                                 "objects": [o]})


def test_first_relay_wall_and_named_wall():
    s = Scene.model_validate({"walls": [{"name": "a", "start": [0, 1], "end": [1, 1], "relay": False},
                                        {"name": "b", "start": [0, 2], "end": [1, 2]}]})
    assert relay_wall(s).name == "b"
    assert relay_wall(s, "a").name == "a"
    with pytest.raises(InputError, match="no wall named 'c'"):
        relay_wall(s, "c")


def test_patches_in_wall_coordinates():
    p = SpadParams(**SMALL, patch_size=0.25)
    pt = hidden_patches(scene(2.0), p)
    # the face toward the wall: world x = 10 − depth, normal +x → wall z = depth, normal (0, 0, −1)
    front = np.isclose(pt.normals[:, 2], -1.0)
    assert np.allclose(pt.centers[front, 2], 2.0)
    # along the wall u = −y: world y ∈ [0.75, 1.25] → wall x ∈ [−1.25, −0.75]
    assert pt.centers[front, 0].min() == pytest.approx(-1.125) and pt.centers[front, 0].max() == pytest.approx(-0.875)
    # heights 0 … 1.5 m, grid centre at 0.75 m
    assert pt.centers[front, 1].min() == pytest.approx(-0.75 + 0.125)
    assert pt.areas.sum() == pytest.approx(4 * 0.5 * 1.5 + 0.25)  # 4 sides + roof
    assert np.allclose(pt.albedo, p.object_albedo)


def test_simulated_volume_peak_depth_and_determinism():
    # grid_offset −1 along u = −y puts the grid centre at world y = 1, in front of the crate
    p = SpadParams(**SMALL, grid_offset=-1.0, dark_count_rate=0.0, ambient_rate=0.0, exposure=0.1)
    ev = expected_volume(scene(2.0), p)
    assert isinstance(ev, TransientVolume) and ev.shape == (512, 5, 5)
    centre = ev.data[:, 2, 2]
    # an extended face: returns from its nearest point (2z/c, on-axis) to its far corners, blurred by σ
    sig_bins = 33e-12 / p.bin_width * 3
    first = int(np.flatnonzero(centre > 1e-3 * centre.max())[0])
    last = int(np.flatnonzero(centre > 1e-3 * centre.max())[-1])
    k_near = 2 * 2.0 / SPEED_OF_LIGHT / p.bin_width
    k_far = 2 * np.sqrt(2.5**2 + 0.25**2 + 0.75**2) / SPEED_OF_LIGHT / p.bin_width  # back corner of a side face
    assert k_near - sig_bins - 1 <= first <= k_near
    assert last <= k_far + sig_bins + 1
    pv = expected_volume(scene(2.0, "point"), p)
    assert int(np.argmax(pv.data[:, 2, 2])) == int(np.floor(2 * 2.25 / SPEED_OF_LIGHT / p.bin_width))
    a, b = simulate(scene(2.0), p), simulate(scene(2.0), p)
    assert np.array_equal(a.data, b.data)
    assert a.data.sum() == pytest.approx(ev.data.sum(), rel=5 * ev.data.sum() ** -0.5 + 1e-3)


def test_counts_fall_as_inverse_fourth_power_of_depth():
    p = SpadParams(**SMALL, grid_offset=-1.0, dark_count_rate=0.0, ambient_rate=0.0, object_albedo=1.0)
    near = expected_volume(scene(1.0, "point"), p)
    far = expected_volume(scene(2.0, "point"), p)
    # point objects sit at grid height, facing the grid centre; the centre scan point sees them on-axis
    assert near.data[:, 2, 2].sum() / far.data[:, 2, 2].sum() == pytest.approx(
        ((2.0 + 0.25) / (1.0 + 0.25)) ** 4, rel=1e-6)


def test_params_forbid_unknown_and_check_ranges():
    with pytest.raises(ValidationError):
        SpadParams(powr=1.0)
    with pytest.raises(ValidationError):
        SpadParams(efficiency=1.5)
    assert SpadParams().power == 1.6e-3 and SpadParams().wavelength == 850e-9
