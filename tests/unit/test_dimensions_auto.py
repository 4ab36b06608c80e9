"""``dimensions = "auto"`` (sims.dimensions): the closed-form decision, its record, and the maps it keeps."""
import math

import numpy as np
import pytest

from sims.dimensions import DECISION_TOL_DB, decide_dimensions, steering_keep
from sims.ground import null_ranges, power_factor, sweep_wavelength, twins
from sims.image import ImageForwardModel
from sims.paths import PathList
from sims.raytrace.model import RaytraceForwardModel
from xnlos_core.errors import ConfigError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.scene import GroundSpec, ObjectSpec, Scene, WallSpec, generated_scene, load_scene
from xnlos_core.signal.antenna import array_gain, azimuth_weights, channel_positions
from xnlos_core.signal.chain import noise_floor

RADAR = RadarConfig()
FAMILIES = ["corner_split", "crossroads", "curved_wall", "hidden_car_approach", "hidden_cyclist",
            "hidden_pedestrian", "parking_lot", "residential_street", "t_junction"]


def _scene(name: str):
    if name == "corner":
        return load_scene({"builtin": "corner"}, "test", ".")
    return generated_scene({"family": name, "seed": 0}, "test", ".", registry=get_registry())


def _frame(model, params: dict, scene):
    return model({"noise": False, **params}).simulate(scene, RADAR, np.random.default_rng(0))


def _low_radar_scene(ground):
    """A wall and a point at 0.3 m height, 4–30 m out, for a radar at 0.3 m: nulls at d ≈ 6 m / n."""
    return Scene(walls=[WallSpec(start=(30.0, 10.0), end=(30.0, -10.0), reflectivity=0.6)],
                 objects=[ObjectSpec(name="p", shape="point", center=(12.0, 2.0), centre_height=0.3)], ground=ground)


def test_power_factor_is_the_twins_gain():
    rng = np.random.default_rng(3)
    d, h_t, th = rng.uniform(2, 90, 40), rng.uniform(0.1, 2.5, 40), rng.uniform(-1.0, 1.0, 40)
    out = PathList()
    out.add(length=2 * np.hypot(d, h_t - 0.9), azimuth=th, power=np.ones(40), kind=0, order=0,
            pos=np.column_stack([d, 0 * d]), hidden=np.column_stack([d, 0 * d]), obj=0, centre=np.arange(40),
            height=h_t)
    for ground in (None, GroundSpec(material="concrete"), GroundSpec(reflection=-0.3)):
        tw = twins(out.paths(), RADAR, 0.9, 0.05, ground)
        np.testing.assert_allclose(power_factor(d, h_t, th, RADAR, 0.9, 0.05, ground), tw.gain, rtol=1e-9)


def test_steering_keep_is_the_array_gain_ratio():
    pos, w = channel_positions(RADAR), azimuth_weights(RADAR)
    th, el = np.radians([0.0, 20.0, -45.0, 60.0]), np.radians([5.0, 10.0, 15.0, 10.0])
    expect = [array_gain(pos, RADAR.wavelength, t, t, e, w) / array_gain(pos, RADAR.wavelength, t, t, 0.0, w)
              for t, e in zip(th, el)]
    np.testing.assert_allclose(steering_keep(RADAR, th, el), expect, rtol=1e-12)
    assert steering_keep(RADAR, 0.4, 0.0) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("name", ["corner", *FAMILIES])
def test_auto_picks_2d_and_keeps_the_2d_map_of_each_shipped_scene(name):
    scene = _scene(name)
    auto, flat = _frame(ImageForwardModel, {}, scene), _frame(ImageForwardModel, {"dimensions": "2d"}, scene)
    assert auto.meta["components"]["dimensions"].startswith("2d: no ground"), auto.meta["components"]
    np.testing.assert_allclose(np.abs(auto.ra_map.data), np.abs(flat.ra_map.data), rtol=1e-6, atol=0)
    decision = decide_dimensions(scene, RADAR, ImageForwardModel({}).params)
    assert not decision.use_3d and decision.estimate_db == 0.0


def test_auto_keeps_the_2d_map_of_the_raytraced_corner():
    scene = _scene("corner")
    auto = _frame(RaytraceForwardModel, {}, scene)
    flat = _frame(RaytraceForwardModel, {"dimensions": "2d"}, scene)
    assert auto.meta["components"]["dimensions"].startswith("2d:")
    np.testing.assert_allclose(np.abs(auto.ra_map.data), np.abs(flat.ra_map.data), rtol=1e-6, atol=0)


def test_auto_picks_3d_over_a_ground_with_two_ray_nulls_in_range():
    scene, params = _low_radar_scene(GroundSpec(material="medium_dry_ground")), {"radar_height": 0.3}
    nulls = null_ranges(sweep_wavelength(RADAR), 0.3, 0.3, 50)
    assert len(nulls) and 4.0 < nulls[0] < RADAR.max_range  # the first null lies inside the scene
    decision = decide_dimensions(scene, RADAR, ImageForwardModel(params).params)
    assert decision.use_3d and decision.estimate_db > 3.0 and "ground" in decision.reason
    frame = _frame(ImageForwardModel, params, scene)
    assert frame.meta["components"]["dimensions"] == decision.label  # what the frame records
    flat = _frame(ImageForwardModel, {**params, "dimensions": "2d"}, scene)
    assert not np.allclose(np.abs(frame.ra_map.data), np.abs(flat.ra_map.data), rtol=0.1)


def test_a_weak_ground_stays_2d_and_the_3d_map_is_within_the_tolerance():
    scene = _low_radar_scene(GroundSpec(reflection=-0.004))
    params = {"radar_height": 0.3}
    decision = decide_dimensions(scene, RADAR, ImageForwardModel(params).params)
    assert not decision.use_3d and 0.0 < decision.estimate_db <= 0.1, decision
    p2 = np.abs(_frame(ImageForwardModel, {**params, "dimensions": "2d"}, scene).ra_map.data).astype(float) ** 2
    p3 = np.abs(_frame(ImageForwardModel, {**params, "dimensions": "3d"}, scene).ra_map.data).astype(float) ** 2
    cells = (p2 >= noise_floor(RADAR)) | (p3 >= noise_floor(RADAR))
    delta = 10 * math.log10(1 + np.abs(p3 - p2)[cells].sum() / p2[cells].sum())  # (D1)
    assert delta <= decision.estimate_db


def test_the_choice_at_the_threshold_does_not_hinge_on_the_last_bit():
    scene = _low_radar_scene(GroundSpec(reflection=-0.02))
    est = decide_dimensions(scene, RADAR, ImageForwardModel({"radar_height": 0.3}).params).estimate_db
    for tol, use in ((est, False), (est - 0.5 * DECISION_TOL_DB, False), (est * (1 - 1e-15), False),
                     (est - 1e-3, True)):
        params = ImageForwardModel({"radar_height": 0.3, "tolerance_db": tol}).params
        assert decide_dimensions(scene, RADAR, params).use_3d is use, tol


def test_elevation_only_scene_decides_from_the_object_heights():
    low = Scene(objects=[ObjectSpec(name="kerb", shape="point", center=(2.0, 0.0), centre_height=0.1)])
    near = decide_dimensions(low, RADAR, ImageForwardModel({}).params)
    assert near.use_3d and "kerb" in near.reason and "off the radar's height" in near.reason
    far = low.model_copy(update={"objects": [low.objects[0].model_copy(update={"center": (60.0, 0.0)})]})
    assert not decide_dimensions(far, RADAR, ImageForwardModel({}).params).use_3d


@pytest.mark.parametrize("value", ["4d", "3D", 3, None])
def test_a_bad_dimensions_value_is_a_config_error(value):
    with pytest.raises(ConfigError, match="dimensions"):
        ImageForwardModel({"dimensions": value})
    with pytest.raises(ConfigError, match="dimensions"):
        RaytraceForwardModel({"dimensions": value})


def test_switched_values_are_recorded_as_switched():
    scene = _low_radar_scene(None)
    for value, use in (("2d", False), ("3d", True)):
        d = decide_dimensions(scene, RADAR, ImageForwardModel({"dimensions": value}).params)
        assert d.use_3d is use and d.label == f"{value}: switched {'on' if use else 'off'}"
