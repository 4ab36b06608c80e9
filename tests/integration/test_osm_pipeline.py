"""The shipped map-based pipeline: an intersection read from OpenStreetMap XML, a car hidden behind
the near corner, reconstructed through the far building's chamfer."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from xnlos_core.config import load_pipeline
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.pipeline import Pipeline

CONFIGS = Path(__file__).parents[2] / "configs"
CONFIG = CONFIGS / "pipelines" / "osm_intersection.toml"


def test_the_hidden_car_behind_the_corner_is_reconstructed():
    pipe = Pipeline(load_pipeline(CONFIG), source=str(CONFIG))
    scene = pipe.scene
    assert scene.meta["buildings"] == 4 and len(scene.walls) == 19
    (car,) = scene.objects
    assert car.center == pytest.approx((14.5, -12.0), abs=0.02)  # placed by lat/lon on the map
    # hidden: the line of sight to its nearest corner passes behind the near-right block's corner (10, −5)
    near = max(car.footprint(), key=lambda p: math.atan2(p[1], p[0]))
    assert near[1] * 10.0 / near[0] < -5.0
    errors = []
    for frame in pipe.frames():
        if frame.index >= 3:
            break
        assert len(frame.ground_truth.mnlos_points) > 0  # the chamfer relays the car
        errors.append(pipe.process(frame).metrics["reconstruction"]["object_error_m"]["car"])
    assert np.all(np.isfinite(errors)) and float(np.median(errors)) < 1.5, errors


def test_the_map_path_is_relative_to_the_config_and_bounded_by_its_roots(tmp_path):
    text = CONFIG.read_text()
    (tmp_path / "p.toml").write_text(text.replace('map = "../maps/intersection.osm"', 'map = "intersection.osm"'))
    with pytest.raises(InputError, match=r"map file .*/intersection.osm: cannot read"):  # looked up beside p.toml
        Pipeline(load_pipeline(tmp_path / "p.toml"), source="p")
    shutil.copy(CONFIGS / "maps" / "intersection.osm", tmp_path)
    assert len(Pipeline(load_pipeline(tmp_path / "p.toml"), source="p").scene.walls) == 19
    (tmp_path / "out.toml").write_text(text.replace('map = "../maps/intersection.osm"', 'map = "../../etc/x.osm"'))
    with pytest.raises(ConfigError, match=r"\[scene.overrides.map\] .*outside the config roots"):
        Pipeline(load_pipeline(tmp_path / "out.toml"), source="out")
