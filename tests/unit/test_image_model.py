"""Image-method forward model (Eq. 3–5): visibility, mirror geometry, radar-equation amplitudes."""
import numpy as np
import pytest

from sims.image import ImageForwardModel, received_power
from xnlos_core.errors import ConfigError
from xnlos_core.geometry import cartesian_to_polar, mirror_reflect
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import PluginManager
from xnlos_core.scene import ObjectSpec, Scene, WallSpec, load_scene
from xnlos_core.signal.chain import noise_floor, processing_gain

RADAR = RadarConfig()
DR = RADAR.range_resolution
CLEAN = ImageForwardModel({"noise": False, "random_phase": False})


def _cell(point):
    r, th = cartesian_to_polar(np.asarray(point, float))
    return int(np.round(r / DR)), int(np.argmin(np.abs(RADAR.azimuth_axis - th)))


def _point(x, y, **kw):
    return ObjectSpec(name=kw.pop("name", "p"), shape="point", center=(x, y), **kw)


def _occluded_scene():
    """Relay wall x = 20; a point hidden behind a short occluder at x = 6 (see geometry below)."""
    relay = WallSpec(name="relay", start=(20.0, 15.0), end=(20.0, -15.0), backscatter_db=-80.0)
    occluder = WallSpec(name="occluder", start=(6.0, -3.0), end=(6.0, -7.0), relay=False)
    # origin→(12,−10) crosses x = 6 at y = −5 (blocked); its image (28,−10) is reached via
    # w = (20,−7.14): origin→w crosses x = 6 at y = −2.14 (open), w→o stays at x ≥ 12 (open).
    return Scene(name="occluded", walls=[relay, occluder], objects=[_point(12.0, -10.0, name="hidden")])


def test_empty_scene_is_noise_only():
    f = ImageForwardModel().simulate(Scene(), RADAR, np.random.default_rng(0))
    gt = f.ground_truth
    assert len(gt.los_points) == len(gt.mnlos_points) == len(gt.hidden_points) == 0
    assert f.meta["n_paths"] == 0 and f.meta["scene"] == "scene"
    assert f.ra_map.power.mean() == pytest.approx(noise_floor(RADAR), rel=0.06)


def test_free_space_point_matches_radar_equation():
    # grid-centred: |κ|² equals the radar-equation power exactly (documented scaling)
    r, th = 100 * DR, RADAR.azimuth_axis[75]
    f = CLEAN.simulate(Scene(objects=[_point(r * np.cos(th), r * np.sin(th), rcs=5.0)]), RADAR,
                       np.random.default_rng(0))
    p_r = received_power(RADAR, r, th, 5.0)
    assert np.unravel_index(np.argmax(f.ra_map.power), f.ra_map.shape) == (100, 75)
    assert f.ra_map.power[100, 75] == pytest.approx(p_r, rel=1e-4)
    np.testing.assert_allclose(f.ground_truth.los_points, [[r * np.cos(th), r * np.sin(th)]])


@pytest.mark.parametrize("r, th_deg", [(30.1, -23.4), (62.37, 41.7)])
def test_off_grid_point_snr_within_scalloping(r, th_deg):
    th = np.radians(th_deg)
    pos = (r * np.cos(th), r * np.sin(th))
    f = CLEAN.simulate(Scene(objects=[_point(*pos)]), RADAR, np.random.default_rng(0))
    i, j = np.unravel_index(np.argmax(f.ra_map.power), f.ra_map.shape)
    assert (i, j) == _cell(pos)
    snr_meas = 10 * np.log10(f.ra_map.power[i, j] / noise_floor(RADAR))
    snr_pred = 10 * np.log10(received_power(RADAR, r, th, 10.0) * processing_gain(RADAR) / RADAR.noise_power)
    assert snr_pred - 1.5 < snr_meas <= snr_pred + 0.01  # only scalloping loss, never a gain


def test_box_back_faces_are_culled():
    box = ObjectSpec(name="box", center=(20.0, 0.0), size=(4.0, 2.0), heading=0.0, spacing=0.25)
    gt = CLEAN.simulate(Scene(objects=[box]), RADAR, np.random.default_rng(0)).ground_truth
    assert len(gt.los_points) > 0
    np.testing.assert_allclose(gt.los_points[:, 0], 18.0)  # only the face towards the radar


def test_hidden_object_seen_only_through_mirror():
    scene = _occluded_scene()
    relay = scene.wall_segments()[0]
    f = CLEAN.simulate(scene, RADAR, np.random.default_rng(0))
    gt = f.ground_truth
    assert not np.any(np.all(np.isclose(gt.los_points, [12.0, -10.0]), axis=1))  # no direct return
    assert len(gt.mnlos_points) == 1 and f.meta["n_mnlos_paths"] == 1
    np.testing.assert_array_equal(gt.hidden_points, [[12.0, -10.0]])
    np.testing.assert_allclose(gt.mnlos_points, mirror_reflect(gt.hidden_points, relay.normal, relay.offset),
                               atol=1e-12)
    np.testing.assert_allclose(gt.mnlos_points, [[28.0, -10.0]], atol=1e-12)
    assert gt.object_names == ("hidden",) and gt.mnlos_object.tolist() == [0]
    # the image is in the map: its cell is far brighter than without mirror paths
    off = ImageForwardModel({"noise": False, "random_phase": False, "mirror_paths": False})
    cell = _cell(gt.mnlos_points[0])
    assert f.ra_map.power[cell] > 100 * off.simulate(scene, RADAR, np.random.default_rng(0)).ra_map.power[cell]


def test_object_beyond_relay_wall_has_no_mirror_path():
    wall = WallSpec(start=(20.0, 15.0), end=(20.0, -15.0))
    f = CLEAN.simulate(Scene(walls=[wall], objects=[_point(25.0, 3.0)]), RADAR, np.random.default_rng(0))
    gt = f.ground_truth
    assert len(gt.mnlos_points) == 0 and f.meta["n_mnlos_paths"] == 0
    assert np.all(gt.los_points[:, 0] == pytest.approx(20.0))  # only wall cells; the object is blocked


def test_specular_point_must_lie_on_the_wall():
    short = WallSpec(start=(20.0, 15.0), end=(20.0, 5.0))  # the image (28,−10) is reached via y = −7.1
    scene = _occluded_scene().model_copy(update={"walls": [short]})
    assert len(CLEAN.simulate(scene, RADAR, np.random.default_rng(0)).ground_truth.mnlos_points) == 0


def test_no_walls_means_no_mirror_and_no_wall_returns():
    f = CLEAN.simulate(Scene(objects=[_point(10.0, 2.0)]), RADAR, np.random.default_rng(0))
    assert f.meta["n_paths"] == 1 and len(f.ground_truth.mnlos_points) == 0


def _mirror_peak(x_obj, alpha):
    b = 80 * DR  # wall x = b: image of (x_obj, 0) at (2b − x_obj, 0), both bin-centred on boresight
    wall = WallSpec(start=(b, 5.0), end=(b, -5.0), reflectivity=alpha, backscatter_db=-80.0)
    f = CLEAN.simulate(Scene(walls=[wall], objects=[_point(x_obj, 0.0)]), RADAR, np.random.default_rng(0))
    return f.ra_map.power[_cell((2 * b - x_obj, 0.0))]


def test_mirror_power_scales_with_alpha_squared_and_image_range():
    p = _mirror_peak(40 * DR, 0.6)
    assert p == pytest.approx(received_power(RADAR, 120 * DR, 0.0, 10.0, 0.6), rel=1e-3)
    assert _mirror_peak(40 * DR, 0.3) / p == pytest.approx((0.3 / 0.6) ** 4, rel=1e-3)  # |α²|² in power
    assert _mirror_peak(20 * DR, 0.6) / p == pytest.approx((120 / 140) ** 4, rel=1e-3)  # 1/|o'|⁴


def test_same_seed_same_map():
    scene = load_scene({"builtin": "corner"}, "test")
    model = ImageForwardModel()
    a = model.simulate(scene, RADAR, np.random.default_rng(7))
    b = model.simulate(scene, RADAR, np.random.default_rng(7))
    c = model.simulate(scene, RADAR, np.random.default_rng(8))
    np.testing.assert_array_equal(a.ra_map.data, b.ra_map.data)
    assert not np.array_equal(a.ra_map.data, c.ra_map.data)


def test_corner_scene_car_is_hidden_but_mirrored():
    scene = load_scene({"builtin": "corner"}, "test")
    # Its time per frame at this radar size (budget 1 s) is the `source` row of
    # benchmarks/pipeline_speed.py: wall-clock time is measured there, not asserted here.
    f = ImageForwardModel().simulate(scene, RADAR, np.random.default_rng(0), timestamp=0.0)
    assert f.ra_map.data.shape == (RADAR.n_range_bins, RADAR.n_azimuth_bins) and f.ra_map.data.dtype == np.complex64
    gt = f.ground_truth
    car = np.array(scene.objects[0].center)
    assert np.all(np.hypot(*(gt.los_points - car).T) > 3.0)  # no direct car return
    assert len(gt.mnlos_points) > 5 and set(gt.mnlos_object.tolist()) == {0}
    chamfer = scene.wall_segments()[0]
    np.testing.assert_allclose(gt.mnlos_points, mirror_reflect(gt.hidden_points, chamfer.normal, chamfer.offset),
                               atol=1e-12)
    assert np.all(np.abs(gt.hidden_points - car) <= [0.9 + 1e-9, 2.25 + 1e-9])  # on the car outline
    snr = f.ra_map.power / noise_floor(RADAR)
    car_snr = max(snr[_cell(p)] for p in gt.mnlos_points)
    assert 10 * np.log10(car_snr) > 6.0


def test_registered_through_plugin_hook():
    pm = PluginManager(autoload=False)
    pm.load_module("sims.plugin")
    model = pm.registry.create("forward_model", "image", {"noise": False})
    assert isinstance(model, ImageForwardModel) and model.params.noise is False
    with pytest.raises(ConfigError, match="min_snr_db"):
        pm.registry.create("forward_model", "image", {"min_snr_db": 1e6})
    with pytest.raises(ConfigError):
        pm.registry.create("forward_model", "image", {"bogus": 1})
