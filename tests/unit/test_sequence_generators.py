"""Sequence scene families (issue 28): a hidden road user that moves, checked over the horizon.

For 50 seeds per family: the road user is hidden with a mirror path at t = 0, and over [0, horizon]
at 0.1 s steps its box never crosses a wall (core wall geometry: no box edge crosses a wall
segment at a step, no box corner's path crosses one between steps); its motion is the documented
model with values in the documented ranges, towards the junction.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sims.generators import FAMILIES, family_params, generate_scene
from sims.generators import geometry as g
from sims.generators.sequences import times
from xnlos_core.errors import InputError
from xnlos_core.geometry import segments_intersect
from xnlos_core.motion import Bicycle, ConstantAcceleration
from xnlos_core.scene import Scene
from xnlos_core.testing import check_component

SEQUENCE_FAMILIES = ("hidden_car_approach", "hidden_cyclist", "hidden_pedestrian")
SEEDS = range(50)


@pytest.fixture(scope="module")
def scenes() -> dict[str, list[Scene]]:
    """Default-parameter scenes of each sequence family for SEEDS, drawn once."""
    return {f: [generate_scene(f, s) for s in SEEDS] for f in SEQUENCE_FAMILIES}


def road_user(s: Scene):
    (o,) = [o for o in s.objects if o.name.startswith("hidden")]
    (rec,) = [r for r in s.meta["drawn"]["objects"] if r["name"] == o.name]
    return o, rec


def crosses_a_wall(a, b, walls) -> bool:
    """True if any segment a[i]→b[i] ((K, 2) each) crosses any wall segment (core rule)."""
    return any(segments_intersect(a, b, w.start, w.end).any() for w in walls)


@pytest.mark.parametrize("family", SEQUENCE_FAMILIES)
def test_conformance(family):
    check_component("scene_generator", family)
    assert family in FAMILIES and generate_scene(family, 7).meta["params"]["horizon"] == 3.0


@pytest.mark.parametrize("family", SEQUENCE_FAMILIES)
def test_hidden_with_a_mirror_path_at_t0_and_never_through_a_wall(family, scenes):
    for seed, s in zip(SEEDS, scenes[family]):
        o, rec = road_user(s)
        walls = s.planar_walls()
        starts, ends, _ = g.wall_arrays(s.walls)
        pts, nrm, _ = o.scatterers(0.0)
        assert g.is_hidden(pts, starts, ends) and g.mirror_candidates(pts, nrm, walls), (family, seed)
        ts = times(s.meta["params"]["horizon"])
        assert ts[0] == 0.0 and math.isclose(ts[-1], 3.0) and len(ts) == 31
        boxes = np.stack([g.footprint(o, float(t)) for t in ts])  # (T, 4, 2)
        edges_a, edges_b = boxes.reshape(-1, 2), np.roll(boxes, -1, axis=1).reshape(-1, 2)
        assert not crosses_a_wall(edges_a, edges_b, walls), (family, seed, "box straddles a wall")
        assert not crosses_a_wall(boxes[:-1].reshape(-1, 2), boxes[1:].reshape(-1, 2), walls), (family, seed)
        # it moves, towards the junction (against the arm, which runs away from the ego street)
        v0 = o.motion([0.0]).velocity[0]
        assert np.linalg.norm(v0) > 0.5 and v0 @ np.asarray(rec["arm_direction"]) < 0, (family, seed)


def test_the_car_drives_or_brakes_within_its_ranges(scenes):
    braking = 0
    for s in scenes["hidden_car_approach"]:
        o, _ = road_user(s)
        if o.trajectory is None:
            assert 5.0 <= np.hypot(*o.velocity) <= 14.0
            assert math.isclose(math.atan2(o.velocity[1], o.velocity[0]), o.heading, abs_tol=1e-9)
        else:
            braking += 1
            assert isinstance(o.trajectory, ConstantAcceleration)
            assert 5.0 <= o.trajectory.speed <= 14.0 and -6.0 <= o.trajectory.acceleration <= -2.0
    assert 10 <= braking <= 40  # braking_probability 0.5 over 50 seeds


def test_the_cyclist_rides_a_mildly_steered_bicycle(scenes):
    for s in scenes["hidden_cyclist"]:
        o, _ = road_user(s)
        assert o.kind == "bicycle" and isinstance(o.trajectory, Bicycle)
        assert 3.0 <= o.trajectory.speed <= 7.0 and abs(o.trajectory.steering) <= 0.03
        assert o.trajectory.wheelbase == 1.1


def test_the_pedestrian_walks_towards_the_road(scenes):
    for s in scenes["hidden_pedestrian"]:
        o, rec = road_user(s)
        v = np.asarray(o.velocity)
        assert o.kind == "pedestrian" and o.trajectory is None and 0.8 <= np.linalg.norm(v) <= 1.8
        towards = -np.asarray(rec["arm_direction"])
        assert v @ towards / np.linalg.norm(v) >= math.cos(1.0) - 1e-9  # within ±1 rad of the junction


def test_a_longer_horizon_is_honoured_and_same_seed_same_sequence():
    s = generate_scene("hidden_car_approach", 5, horizon=6.0, braking_probability=0.0)
    o, _ = road_user(s)
    assert o.trajectory is None and s.meta["params"]["horizon"] == 6.0
    boxes = np.stack([g.footprint(o, float(t)) for t in times(6.0)])
    assert not crosses_a_wall(boxes[:-1].reshape(-1, 2), boxes[1:].reshape(-1, 2), s.planar_walls())
    assert generate_scene("hidden_car_approach", 5, horizon=6.0, braking_probability=0.0) == s


@pytest.mark.parametrize("family, overrides, pattern", [
    ("hidden_car_approach", {"object_kinds": ["bicycle"]}, "object_kinds"),
    ("hidden_cyclist", {"steering": [-0.5, 0.5]}, "steering"),
    ("hidden_pedestrian", {"speed": [0.0, 1.0]}, "speed"),
    ("hidden_car_approach", {"horizon": 0.0}, "horizon"),
])
def test_bad_parameters_name_the_key(family, overrides, pattern):
    with pytest.raises(InputError, match=pattern):
        generate_scene(family, 0, **overrides)
    assert family_params(family)().horizon == 3.0


def test_the_sequences_dataset_config_stays_within_the_horizon():
    from pathlib import Path

    from sims.dataset import load_dataset_config, resolve

    path = Path(__file__).resolve().parents[2] / "configs/datasets/sequences.toml"
    cfg = load_dataset_config(path)
    resolve(cfg, str(path))  # registered families, valid parameters
    assert set(cfg.weights()) == set(SEQUENCE_FAMILIES) and cfg.frames_per_scene == 60
    assert cfg.shard_size % cfg.frames_per_scene == 0
    last = (cfg.frames_per_scene - 1) * cfg.frame_interval
    assert last >= 3.0 + 2.0  # 3 s-ahead predictions scored after a track is established
    assert all(last <= family_params(f)(**cfg.generator_kwargs(f)).horizon for f in SEQUENCE_FAMILIES)
