"""The shipped Doppler pipeline (configs/pipelines/corner_doppler.toml) end to end: the hidden
car's un-mirrored velocity in results.jsonl matches its trajectory along the observed direction, and
static walls measure ≈ 0 m/s."""
import json
import math
from pathlib import Path

import numpy as np

from xnlos_core.config import load_pipeline, parse_pipeline
from xnlos_core.files import load_toml
from xnlos_core.pipeline import Pipeline
from xnlos_core.app.runner import run_to_dir
from xnlos_core.testing import small_pipeline_table

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "pipelines" / "corner_doppler.toml"
FACADE_N = np.array([1.0, 1.0]) / math.sqrt(2)  # the relay facade x + y = 25 (corner scene)


def test_corner_doppler_records_the_hidden_cars_velocity(tmp_path):
    config = load_pipeline(CONFIG)
    config = config.model_copy(update={"run": config.run.model_copy(update={"frames": 2, "figure": False})})
    run_to_dir(config, tmp_path, source=str(CONFIG), progress=False)
    records = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in records] == [0, 1]

    car = load_toml(CONFIG)["scene"]["objects"][0]
    v_true = np.array(car["trajectory"]["velocity"])  # constant velocity [m/s]
    mirror = np.eye(2) - 2.0 * np.outer(FACADE_N, FACADE_N)
    for rec in records:
        det, hid = rec["detection_doppler"], rec["hidden_velocity"]
        label, v_r = np.array(det["label"]), np.array(det["velocity"])
        # static walls: LOS echoes at rest, far below the car's 5 m/s (a Doppler bin is ≈ 2.3 m/s)
        assert (label == 0).sum() >= 5
        assert np.all(np.abs(v_r[label == 0]) < 0.25), v_r[label == 0]
        centre = np.array(car["center"]) + rec["timestamp"] * v_true
        on_car = 0
        for o, w, cov, src in zip(rec["hidden_points"], hid["velocity"], hid["velocity_cov"], hid["source_index"]):
            if np.linalg.norm(np.array(o) - centre) > 3.0:  # not a point of the car's box (4.5 m × 1.8 m)
                continue
            on_car += 1
            r, a = det["range"][src], det["azimuth"][src]
            g = mirror @ np.array([math.cos(a), math.sin(a)])  # the observed direction (I − 2nnᵀ) r̂'
            sigma = math.sqrt(g @ np.array(cov) @ g)
            assert abs(g @ np.array(w) - g @ v_true) < 3.0 * sigma + 1e-9, (o, w, g @ v_true, sigma)
            assert abs(g @ v_true) > 4.0  # the car's motion is mostly along the observed direction
        assert on_car >= 1


def test_without_doppler_the_record_has_no_velocity_keys():
    (result,) = Pipeline(parse_pipeline(small_pipeline_table(), "small.toml")).run()
    assert result.detections.velocity is None and result.hidden.velocity is None
    rec = result.record()
    assert "detection_doppler" not in rec and "hidden_velocity" not in rec
    assert {"frame", "detections", "walls", "hidden_points", "tracks", "metrics"} <= set(rec)
