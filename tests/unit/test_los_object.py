"""Owner of each LOS ground-truth point (``GroundTruth.los_object``,  follow-up):
both forward models fill it through the render path; the run summary tells an object in plain
view ("in line of sight") from one nothing shows to the radar ("not observable"), and records
written without ``los_points`` still summarise as before."""
import tomllib

import numpy as np
import pytest

from sims.image import ImageForwardModel
from sims.raytrace.model import RaytraceForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.app.runner import object_verdict, summarise, summarise_objects
from xnlos_core.scene import BUILTIN_DIR, Scene

RADAR = RadarConfig(n_samples=256, max_range=60.0, n_azimuth_bins=121)
QUIET = {"noise": False, "random_phase": False}
# In plain view on the street, left of the radar: no relay wall's mirror path reaches it.
KIOSK = {"name": "kiosk", "shape": "box", "center": [8.0, 6.0], "size": [1.5, 1.5], "heading": 0.0}


def _scene() -> Scene:
    table = tomllib.loads((BUILTIN_DIR / "corner.toml").read_text())
    table["objects"].append(KIOSK)
    return Scene.model_validate(table)


@pytest.mark.parametrize("model", [ImageForwardModel(QUIET), RaytraceForwardModel(QUIET)], ids=["image", "raytrace"])
def test_render_path_records_the_owner_of_each_los_point(model):
    gt = model.simulate(_scene(), RADAR, np.random.default_rng(0)).ground_truth
    assert gt.los_object is not None and gt.los_object.shape == (len(gt.los_points),)
    car, kiosk = gt.object_names.index("car"), gt.object_names.index("kiosk")
    own = gt.los_object == kiosk
    assert own.sum() > 0 and set(gt.los_object.tolist()) == {-1, kiosk}  # walls −1; the car is hidden
    np.testing.assert_array_less(np.abs(gt.los_points[own] - KIOSK["center"]), 0.75 + 1e-9)  # on its box
    assert np.all(np.abs(gt.los_points[~own] - KIOSK["center"]).max(1) > 0.75)  # walls are not the kiosk's
    assert np.sum(gt.mnlos_object == kiosk) == 0 and np.sum(gt.mnlos_object == car) > 0


@pytest.mark.parametrize("model", [ImageForwardModel(QUIET), RaytraceForwardModel(QUIET)], ids=["image", "raytrace"])
def test_a_moving_object_in_line_of_sight_carries_its_range_rate(model):
    # GroundTruth.los_radial_velocity: r̂ᵀv on the kiosk's LOS points when it moves, 0 on the walls.
    table = tomllib.loads((BUILTIN_DIR / "corner.toml").read_text())
    table["objects"].append({**KIOSK, "trajectory": {"model": "constant_velocity", "velocity": [3.0, -1.0]}})
    gt = model.simulate(Scene.model_validate(table), RADAR, np.random.default_rng(0)).ground_truth
    own = gt.los_object == gt.object_names.index("kiosk")
    assert gt.los_radial_velocity is not None and own.sum() > 0
    p = gt.los_points[own]
    np.testing.assert_allclose(gt.los_radial_velocity[own], p @ [3.0, -1.0] / np.linalg.norm(p, axis=1), atol=1e-6)
    np.testing.assert_array_equal(gt.los_radial_velocity[~own], 0.0)
    assert np.array_equal(gt.above_snr(-np.inf).los_radial_velocity, gt.los_radial_velocity)


def _record(mirror, los=None, errors=None):
    m = {"mirror_paths": mirror}
    if los is not None:
        m["los_points"] = los
    if errors is not None:
        m["reconstruction"] = {"object_error_m": errors}
    return {"frame": 0, "metrics": m, "timings_s": {"detector": 0.001}}


def test_summary_tells_line_of_sight_from_not_observable():
    recs = [_record({"car": 5, "kiosk": 0, "van": 0}, {"car": 0, "kiosk": 12, "van": 0},
                    {"car": 0.3, "kiosk": float("nan"), "van": float("nan")}),
            _record({"car": 4, "kiosk": 0, "van": 0}, {"car": 0, "kiosk": 0, "van": 0},
                    {"car": 0.5, "kiosk": float("nan"), "van": float("nan")})]
    objs = summarise_objects(recs)
    assert objs["car"] == {"frames": 2, "observable_frames": 2, "los_frames": 0, "error_m": 0.4,
                           "status": "reconstructed"}
    assert objs["kiosk"]["status"] == "in line of sight" and objs["kiosk"]["los_frames"] == 1
    assert objs["van"]["status"] == "not observable" and objs["van"]["los_frames"] == 0
    assert object_verdict(objs["kiosk"]).startswith("in line of sight (seen directly in 1 of 2 frame(s)")
    # Per-object counts stay out of the mean metrics, like mirror_paths.
    assert not any(k.startswith(("los_points", "mirror_paths")) for k in summarise(recs)["metrics"])


def test_records_without_los_points_summarise_as_before():
    # Records of dataset frames (no los_object) or written before los_points existed.
    recs = [_record({"car": 5, "kiosk": 0}, errors={"car": 0.3, "kiosk": float("nan")})]
    objs = summarise_objects(recs)
    assert objs["kiosk"] == {"frames": 1, "observable_frames": 0, "los_frames": None, "error_m": None,
                             "status": "not observable"}
    assert objs["car"]["status"] == "reconstructed" and objs["car"]["los_frames"] is None
    # A mix counts only the frames that recorded it; a mirror path outranks being seen directly.
    mixed = summarise_objects(recs + [_record({"car": 0, "kiosk": 0}, {"car": 3, "kiosk": 2})])
    assert mixed["kiosk"]["los_frames"] == 1 and mixed["kiosk"]["status"] == "in line of sight"
    assert mixed["car"]["los_frames"] == 1 and mixed["car"]["status"] == "reconstructed"
