"""Sequence scene families: a hidden road user that moves, checked over the horizon.

For SEEDS per family: the road user is hidden with a mirror path at t = 0, and over [0, horizon]
at 0.1 s steps its box never crosses a wall (core wall geometry: no box edge crosses a wall
segment at a step, no box corner's path crosses one between steps); it has a mirror path above
min_snr_db at ≥ visible_share of those steps (recomputed here from the image method and the radar
equation); its motion is the documented model with values in the documented ranges, towards the
junction, and every motion kind of the family occurs.
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
from xnlos_core.motion import Bicycle, ConstantAcceleration, ConstantTurn
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import Scene
from sims.scene_truth import motion_kind
from xnlos_core.testing import check_component

SEQUENCE_FAMILIES = ("hidden_car_approach", "hidden_cyclist", "hidden_pedestrian")
SEEDS = range(15)


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


def mirror_snr_db(o, s: Scene, t: float, radar: RadarConfig) -> float:
    """Best RA-map SNR [dB] over the road user's single-bounce mirror paths at t [s] (−inf: none in
    the field of view and range), from the image method and the radar equation (sims.propagation)."""
    from sims import walls as wall_em
    from sims.propagation import ra_snr_db, received_power

    planar = s.planar_walls()
    pts, nrm, rcs = o.scatterers(t)
    best = -math.inf
    for i, idx, img, inc in g.mirror_candidates(pts, nrm, planar):
        r, th = np.hypot(img[:, 0], img[:, 1]), np.arctan2(img[:, 1], img[:, 0])
        ok = (np.abs(th) <= radar.field_of_view) & (r <= radar.max_range)
        if ok.any():
            alpha = wall_em.specular_alpha(planar[i], radar, inc[ok])
            best = max(best, float(ra_snr_db(radar, received_power(radar, r[ok], th[ok], rcs[idx][ok], alpha)).max()))
    return best


@pytest.mark.parametrize("family", SEQUENCE_FAMILIES)
def test_the_road_user_is_seen_through_the_mirror_over_most_of_the_horizon(family, scenes):
    radar = RadarConfig()
    for seed, s in zip(SEEDS[:5], scenes[family]):
        o, rec = road_user(s)
        p = s.meta["params"]
        ts = times(p["horizon"])
        seen = np.array([mirror_snr_db(o, s, float(t), radar) >= p["min_snr_db"] for t in ts])
        assert seen[0] and seen.mean() >= p["visible_share"] == 0.8, (family, seed, seen.mean())
        assert math.isclose(rec["visible_share"], seen.mean(), abs_tol=1e-6), (family, seed)
        hidden = np.mean([g.is_hidden(o.scatterers(float(t))[0], *g.wall_arrays(s.walls)[:2]) for t in ts])
        assert math.isclose(rec["hidden_share"], hidden, abs_tol=1e-6)  # meta rounds to 1e-6


def test_a_dataset_radar_in_the_generator_params_is_the_one_the_visibility_check_uses():
    light = {"n_samples": 256, "max_range": 60.0, "n_chirps": 16}
    radar = RadarConfig(**light)
    s = generate_scene("hidden_car_approach", 3, horizon=6.0, radar=light)
    o, rec = road_user(s)
    seen = np.array([mirror_snr_db(o, s, float(t), radar) >= s.meta["params"]["min_snr_db"] for t in times(6.0)])
    assert len(seen) == 61 and seen.mean() >= 0.8 and math.isclose(rec["visible_share"], seen.mean(), abs_tol=1e-6)


def test_hidden_share_keeps_the_road_user_out_of_line_of_sight():
    s = generate_scene("hidden_pedestrian", 1, hidden_share=0.9)
    o, rec = road_user(s)
    starts, ends, _ = g.wall_arrays(s.walls)
    hidden = np.mean([g.is_hidden(o.scatterers(float(t))[0], starts, ends) for t in times(3.0)])
    assert hidden >= 0.9 and math.isclose(rec["hidden_share"], hidden, abs_tol=1e-6)


def test_the_car_drives_brakes_or_turns_within_its_ranges(scenes):
    kinds = []
    for s in scenes["hidden_car_approach"]:
        o, _ = road_user(s)
        kind = s.meta["drawn"]["per_scene"]["motion"]
        kinds.append(kind)
        assert motion_kind(o, 3.0) == kind
        if kind == "straight":
            assert o.trajectory is None and 4.0 <= np.hypot(*o.velocity) <= 10.0
            assert math.isclose(math.atan2(o.velocity[1], o.velocity[0]), o.heading, abs_tol=1e-9)
        elif kind == "braking":
            ca = o.trajectory
            assert isinstance(ca, ConstantAcceleration) and 4.0 <= ca.speed <= 10.0
            assert -4.0 <= ca.acceleration < 0 and ca.speed / -ca.acceleration >= 3.0 - 1e-9  # brakes ≥ 3 s
        else:
            ct = o.trajectory
            assert isinstance(ct, ConstantTurn) and 4.0 <= ct.speed <= 10.0 and 0.1 <= abs(ct.yaw_rate) <= 0.4
    assert set(kinds) == {"straight", "braking", "turning"}


def test_the_motion_kind_is_drawn_once_per_scene_not_per_draw():
    """Re-draws keep the kind: the first draw of default_rng(seed) picks it, however many draws fail."""
    for seed in (0, 1, 2):
        s = generate_scene("hidden_cyclist", seed)
        first = int(np.random.default_rng(seed).integers(2))
        assert s.meta["drawn"]["per_scene"]["motion"] == ("straight", "turning")[first]


def test_the_cyclist_rides_straight_or_turns_at_a_yaw_rate_that_matters(scenes):
    kinds = set()
    for s in scenes["hidden_cyclist"]:
        o, _ = road_user(s)
        b = o.trajectory
        assert o.kind == "bicycle" and isinstance(b, Bicycle) and b.wheelbase == 1.1 and 3.0 <= b.speed <= 6.0
        omega = b.speed * math.tan(b.steering) / b.wheelbase  # ω = v tan δ / L
        kind = s.meta["drawn"]["per_scene"]["motion"]
        kinds.add(kind)
        assert (b.steering == 0.0) if kind == "straight" else (0.1 - 1e-9 <= abs(omega) <= 0.4 + 1e-9)
        assert motion_kind(o, 3.0) == kind
    assert kinds == {"straight", "turning"}


def test_the_pedestrian_walks_towards_the_road(scenes):
    for s in scenes["hidden_pedestrian"]:
        o, rec = road_user(s)
        v = np.asarray(o.velocity)
        assert o.kind == "pedestrian" and o.trajectory is None and 0.8 <= np.linalg.norm(v) <= 1.8
        towards = -np.asarray(rec["arm_direction"])
        assert v @ towards / np.linalg.norm(v) >= math.cos(1.0) - 1e-9  # within ±1 rad of the junction


def test_a_longer_horizon_is_honoured_and_same_seed_same_sequence():
    s = generate_scene("hidden_car_approach", 5, horizon=6.0, motions=["straight"])
    o, _ = road_user(s)
    assert o.trajectory is None and s.meta["params"]["horizon"] == 6.0
    boxes = np.stack([g.footprint(o, float(t)) for t in times(6.0)])
    assert not crosses_a_wall(boxes[:-1].reshape(-1, 2), boxes[1:].reshape(-1, 2), s.planar_walls())
    assert generate_scene("hidden_car_approach", 5, horizon=6.0, motions=["straight"]) == s


@pytest.mark.parametrize("family, overrides, pattern", [
    ("hidden_car_approach", {"object_kinds": ["bicycle"]}, "object_kinds"),
    ("hidden_cyclist", {"yaw_rate": [-0.5, 0.5]}, "yaw_rate"),
    ("hidden_car_approach", {"motions": ["reversing"]}, "motions"),
    ("hidden_pedestrian", {"visible_share": 1.5}, "visible_share"),
    ("hidden_pedestrian", {"speed": [0.0, 1.0]}, "speed"),
    ("hidden_car_approach", {"horizon": 0.0}, "horizon"),
])
def test_bad_parameters_name_the_key(family, overrides, pattern):
    with pytest.raises(InputError, match=pattern):
        generate_scene(family, 0, **overrides)
    assert family_params(family)().horizon == 3.0


@pytest.mark.parametrize("name", ["sequences", "sequences_large"])
def test_the_sequences_dataset_config_stays_within_the_horizon(name):
    from pathlib import Path

    from sims.dataset import load_dataset_config, resolve

    path = Path(__file__).resolve().parents[2] / f"configs/datasets/{name}.toml"
    cfg = load_dataset_config(path)
    resolve(cfg, str(path))  # registered families, valid parameters
    assert set(cfg.weights()) == set(SEQUENCE_FAMILIES) and cfg.frames_per_scene == 60
    assert cfg.shard_size % cfg.frames_per_scene == 0
    last = (cfg.frames_per_scene - 1) * cfg.frame_interval
    assert last >= 3.0 + 2.0  # 3 s-ahead predictions scored after a track is established
    assert all(last <= family_params(f)(**cfg.generator_kwargs(f)).horizon for f in SEQUENCE_FAMILIES)


@pytest.mark.parametrize("name", ["sequences", "sequences_large"])
def test_the_sequences_dataset_checks_visibility_with_its_own_radar_and_tests_every_car_motion(name):
    from pathlib import Path

    from sims.dataset.config import load_dataset_config, resolve
    from sims.dataset.plan import make_plan

    path = Path(__file__).resolve().parents[2] / f"configs/datasets/{name}.toml"
    cfg = load_dataset_config(path)
    radar = resolve(cfg, str(path)).radar
    for f in SEQUENCE_FAMILIES:
        params = family_params(f)(**cfg.generator_kwargs(f))
        assert params.radar_config().model_dump(mode="json") == radar, f
        assert params.visible_share >= 0.8
    plan = make_plan(cfg)
    # the motion kind is the first draw of the scene's generator (per_scene), so no scene is drawn here
    kinds = {("straight", "braking", "turning")[int(np.random.default_rng(int(seed)).integers(3))]
             for seed, fam, split in zip(plan.scene_seed, plan.family, plan.split)
             if fam == "hidden_car_approach" and split == "test"}
    assert kinds == {"straight", "braking", "turning"}


@pytest.mark.parametrize(("base", "twin"), [("sequences", "sequences_64chirps"),
                                            ("sequences_large", "sequences_large_64chirps")])
def test_the_64_chirp_sequence_datasets_render_the_same_scenes(base, twin):
    """The tracking ablation's datasets (64 chirps per transmitter, the radar preset's own) are their
    16-chirp bases with only [radar].n_chirps changed: the same name, seed, generators and the generators'
    visibility radar, hence the same scenes and splits (the 16-chirp figures of earlier sessions compare)."""
    from pathlib import Path

    from sims.dataset.config import load_dataset_config
    from sims.dataset.plan import make_plan
    from xnlos_core.config import load_toml

    folder = Path(__file__).resolve().parents[2] / "configs" / "datasets"
    a, b = load_toml(folder / f"{base}.toml"), load_toml(folder / f"{twin}.toml")
    assert (a["radar"].pop("n_chirps"), b["radar"].pop("n_chirps")) == (16, 64)
    assert a == b
    pa, pb = make_plan(load_dataset_config(folder / f"{base}.toml")), make_plan(load_dataset_config(folder / f"{twin}.toml"))
    assert np.array_equal(pa.scene_seed, pb.scene_seed) and list(pa.split) == list(pb.split)
