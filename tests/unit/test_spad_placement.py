"""SPAD scan-patch placement (sims/spad/placement.py) and the collection leg at the sensor's real view
angle (sims/spad/scene.py view_geometry), against closed forms of simple geometry."""
import math

import numpy as np
import pytest

from sims.spad.placement import facing_offset
from sims.spad.scene import SpadParams, expected_signal, view_geometry, wall_frame
from xnlos_core.scene import load_scene


def _scene(objects, walls=()):
    return load_scene({"name": "t", "walls": [{"name": "relay", "start": [10.0, 10.0], "end": [10.0, -10.0]},
                                              *walls], "objects": objects}, "test scene")


def test_patch_faces_the_target_head_on_in_an_open_scene():
    # wall x = 10 from y = 10 to −10 (u = (0, −1)); target at (4, −3): the foot (10, −3) is 3 m along u
    sc = _scene([{"name": "car", "kind": "car", "center": [4.0, -3.0], "size": [4.5, 1.8]}])
    pl = facing_offset(sc, SpadParams(wall="relay"), [4.0, -3.0, 0.75], exclude="car")
    assert pl.offset == pytest.approx(3.0) and pl.facing == pytest.approx(3.0) and not pl.clipped


def test_patch_stays_where_the_sensor_sees_the_wall_and_the_wall_sees_the_car():
    """The study's corner: facade x + y = 25, building front y = −1 (x 5 … 22) and side x = 22. The
    sensor at the origin sees the facade only where y ≥ −25/21 (the line over the corner (22, −1)),
    i.e. up to offset √2·25/21 along u = (1, −1)/√2: the 2 m patch's far end ends there."""
    from xnlos_core.app.crossmodal.study import _scene as study_scene
    from xnlos_core.app.crossmodal.study import load_study
    from pathlib import Path

    cfg, base = load_study(Path(__file__).resolve().parents[2] / "configs" / "ablations" / "crossmodal.toml")
    limit = math.sqrt(2) * 25 / 21 - 1.0
    for d in (1.0, 20.0):
        sc = study_scene(cfg, d, base)
        car = next(o for o in sc.objects if o.name == "car")
        target = [*car.center_at(0.0), car.height / 2]
        p = SpadParams(wall="facade", grid_width=2.0)
        pl = facing_offset(sc, p, target, exclude="car")
        assert pl.clipped and pl.facing > limit  # the head-on point is out of the sensor's sight
        assert limit - 0.011 <= pl.offset <= limit + 1e-9
        # the patch centre sees the car (on the hidden side, nothing in between)
        c, u, n = wall_frame(sc.walls[0], p.model_copy(update={"grid_offset": pl.offset}))
        assert np.dot(np.asarray(target[:2]) - c, n) > 0


def test_no_patch_when_the_sensor_sees_no_part_of_the_wall():
    blocker = {"name": "screen", "start": [5.0, 20.0], "end": [5.0, -20.0], "relay": False}
    sc = _scene([{"name": "car", "kind": "car", "center": [4.0, -3.0], "size": [4.5, 1.8]}], [blocker])
    pl = facing_offset(sc, SpadParams(wall="relay"), [4.0, -3.0, 0.75], exclude="car")
    assert pl.offset is None and pl.interval is None


def test_collection_at_the_real_view_angle():
    # grid centre (10, −5) at the sensor's height: D = √125, cosθ_v = 10/√125 (normal along −x)
    sc = _scene([{"name": "car", "kind": "car", "center": [4.0, -5.0], "size": [4.5, 1.8]}])
    p = SpadParams(wall="relay", grid_offset=5.0, grid_elevation=1.0, sensor_height=1.0, grid_points=(4, 4),
                   n_bins=256, bin_width=1e-10)
    d, cos = view_geometry(sc, p)
    assert d == pytest.approx(math.sqrt(125)) and cos == pytest.approx(10 / math.sqrt(125))
    seen = expected_signal(sc, p)
    head_on = expected_signal(sc, p.model_copy(update={"view_cosine": 1.0}))
    assert seen.sum() > 0 and seen.sum() == pytest.approx(cos * head_on.sum(), rel=1e-12)
