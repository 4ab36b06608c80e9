"""A braking car behind the corner through the pipeline: trajectory from the scene table to the
ground truth's velocities and the reconstructed hidden points."""
import numpy as np

from xnlos_core.config import parse_pipeline
from xnlos_core.files import load_toml
from xnlos_core.pipeline import Pipeline
from xnlos_core.scene import BUILTIN_DIR
from xnlos_core.testing import small_pipeline_table


def test_braking_car_behind_the_corner_moves_in_the_ground_truth_and_stops():
    scene = load_toml(BUILTIN_DIR / "corner.toml")
    car = scene["objects"][0]
    car.pop("velocity", None)
    car["trajectory"] = {"model": "constant_acceleration", "speed": 4.0, "acceleration": -8.0}  # stops at 0.5 s
    table = small_pipeline_table(scene=scene, run={"frames": 8, "figure": False, "frame_interval": 0.1})
    results = list(Pipeline(parse_pipeline(table, "motion.toml")).run())
    speeds = []
    for r in results:
        gt = r.frame.ground_truth
        car_rows = gt.mnlos_object == gt.object_names.index("car")
        assert car_rows.any()
        v = gt.hidden_velocity[car_rows]
        np.testing.assert_allclose(v[:, 0], 0.0, atol=1e-12)  # heading +y: driving along y only
        speeds.append(float(v[0, 1]))
        # the virtual points move with the velocity mirrored across the chamfer facade
        n = np.array([-1.0, -1.0]) / np.sqrt(2)
        np.testing.assert_allclose(gt.mnlos_velocity[car_rows], v - 2 * (v @ n)[:, None] * n, atol=1e-9)
        assert r.hidden.velocity is None  # no detector here measures Doppler
    np.testing.assert_allclose(speeds, np.maximum(4.0 - 8.0 * 0.1 * np.arange(8), 0.0), atol=1e-12)
