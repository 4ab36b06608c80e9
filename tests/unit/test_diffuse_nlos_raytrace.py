"""Diffuse three-bounce NLOS path in the ray tracer (sims.raytrace.diffuse) against the image model,
the shared importance cut (sims.diffuse_nlos.wall_paths) against brute force over every cell pair,
the auto rule in both models, and configs unchanged at defaults."""
import math

import numpy as np
import pytest

from sims import diffuse_nlos
from sims.image import ImageForwardModel
from sims.params import LATE_DEFAULTS
from sims.paths import OTHER
from sims.raytrace.model import RaytraceForwardModel
from xnlos_core.radar import RadarConfig, load_radar
from xnlos_core.scene import ObjectSpec, Scene, WallSpec

X = RadarConfig()
W = load_radar({"preset": "automotive_77ghz"}, "test", ".")
ALL = {"noise": False, "random_phase": False, "diffuse": "off", "diffuse_nlos": "on", "diffuse_nlos_cell": 0.5,
       "diffuse_nlos_floor_db": -300.0}
ON = {"diffuse": False, "transmission": False, "diffuse_nlos": True}


def _scene(roughness=1e-3, extra_walls=(), objects=None):
    wall = WallSpec(name="relay", start=(20.0, 6.0), end=(20.0, -6.0), material="concrete", roughness=roughness)
    objects = objects or [ObjectSpec(name="p", shape="point", center=(10.0, 2.0), rcs=10.0),
                          ObjectSpec(name="q", shape="point", center=(14.0, -3.0), rcs=3.0)]
    return Scene(walls=[wall, *extra_walls], objects=objects)


def _image(scene, radar=W, **kw):
    cut = {}
    paths = ImageForwardModel({**ALL, "mirror_paths": False, **kw})._paths(
        scene, scene.planar_walls(), radar, np.random.default_rng(0), 0.0, ON, cut)
    return paths, cut


def _ray(scene, radar=W, **kw):
    model = RaytraceForwardModel({**ALL, "mixed_paths": False, "min_snr_db": -100.0, **kw})
    _, paths, tr, use = model.trace(scene, radar)
    return paths, tr, use


def _diffuse(paths):
    m = (paths.kind == OTHER) & (paths.obj >= 0)
    key = np.lexsort((paths.power[m], paths.length[m], paths.obj[m]))
    return paths.length[m][key], paths.power[m][key], paths.azimuth[m][key], paths.obj[m][key]


def test_raytrace_diffuse_paths_equal_the_image_model_without_occluders():
    """Same cells, same geometry (centres at the radar height): every path agrees to 1e-9 relative."""
    img, cut = _image(_scene())
    ray, tr, use = _ray(_scene())
    a, b = _diffuse(img), _diffuse(ray)
    assert len(a[0]) == len(b[0]) == 2 * 24**2  # two centres, 24 cells of 0.5 m, every pair
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=0)
    assert use["diffuse_nlos_cut"] == cut["diffuse_nlos_cut"]
    assert len(tr.diffuse_cells) == len(a[0]) and tr.n_cells == 24
    np.testing.assert_array_equal(ray.obj[-len(tr.diffuse_cells):] >= 0, True)  # the diffuse paths are last


def test_both_models_drop_the_pairs_an_occluding_screen_blocks():
    """A screen between the object and the lower half of the relay wall: both models lose those legs."""
    screen = WallSpec(name="screen", start=(17.0, -0.5), end=(17.0, -6.0))
    img, _ = _image(_scene(extra_walls=[screen]))
    ray, _, _ = _ray(_scene(extra_walls=[screen]))
    full = len(_diffuse(_image(_scene())[0])[0])
    n_img, n_ray = len(_diffuse(img)[0]), len(_diffuse(ray)[0])
    assert 0 < n_img < full and 0 < n_ray < full
    assert n_ray == n_img  # 2-D segment tests and 3-D ray casts agree on this scene


def test_auto_rule_is_the_same_in_both_models():
    for radar, rough, want in ((X, 1e-3, "off"), (W, 1e-3, "on"), (W, 0.0, "off"), (X, 5e-3, "on")):
        for model in (ImageForwardModel({}), RaytraceForwardModel({})):
            assert model.components(_scene(rough), radar)["diffuse_nlos"].split(":")[0] == want
    assert RaytraceForwardModel({}).components(Scene(walls=_scene().walls, objects=[]), W)["diffuse_nlos"] \
        == "off: no object"


def test_configs_leave_out_the_diffuse_nlos_keys_at_their_defaults():
    for model in (ImageForwardModel({}), RaytraceForwardModel({})):
        dump = model.params.model_dump()
        late = set(LATE_DEFAULTS) - type(model.params).dump_always  # raytrace always had radar_height
        assert not late & set(dump)  # serialised configs (dataset digests) as before
        assert set(dump) == set(type(model.params).model_fields) - late
        assert type(model)({"diffuse_nlos": "on", "diffuse_nlos_max_paths": 7}).params.model_dump()[
            "diffuse_nlos_max_paths"] == 7


def test_raytrace_frame_unchanged_when_auto_leaves_the_path_off():
    scene = _scene(roughness=0.0)
    a = RaytraceForwardModel({}).simulate(scene, W, np.random.default_rng(5))
    b = RaytraceForwardModel({"diffuse_nlos": "off"}).simulate(scene, W, np.random.default_rng(5))
    np.testing.assert_array_equal(a.ra_map.data, b.ra_map.data)
    assert a.meta["components"]["diffuse_nlos"].startswith("off") and "diffuse_nlos_cut" not in a.meta["components"]


def _brute(scene, radar):
    """Every pair (a, b) of every centre: power from three_bounce_power, one pair at a time (no cut)."""
    from sims.walls import bistatic_sigma0

    spec = scene.walls[0]
    cells, ds = diffuse_nlos.cells(spec, 0.5)
    n = np.array([-1.0, 0.0, 0.0])
    out = []
    for obj in scene.objects:
        po = np.asarray(obj.center)
        for a in cells:
            for b in cells:
                ta, tb = np.append(po - a, 0.0), np.append(po - b, 0.0)
                sa = float(bistatic_sigma0(spec, radar, np.append(-a, 0.0), ta, n)) * ds * spec.height
                sb = float(bistatic_sigma0(spec, radar, tb, np.append(-b, 0.0), n)) * ds * spec.height
                out.append(float(diffuse_nlos.three_bounce_power(
                    radar, np.linalg.norm(a), math.atan2(a[1], a[0]), np.linalg.norm(b), math.atan2(b[1], b[0]),
                    np.linalg.norm(po - a), np.linalg.norm(po - b), sa, sb, obj.rcs)))
    return np.sort(np.array(out))


@pytest.mark.parametrize("quantile", [None, 0.5, 0.9])
def test_importance_cut_keeps_the_strongest_pairs_and_bounds_what_it_leaves_out(quantile):
    """Floor -300 dB keeps every pair; a floor whose per-pair threshold budget / pairs sits at a quantile
    of the brute-force pair powers drops exactly the pairs below it, their sum below the budget."""
    scene = _scene(objects=[ObjectSpec(name="p", shape="point", center=(10.0, 2.0), rcs=0.01),
                            ObjectSpec(name="q", shape="point", center=(14.0, -3.0), rcs=0.003)])
    brute = _brute(scene, W)
    pn = diffuse_nlos.noise_equivalent_power(W)
    floor_db = -300.0 if quantile is None else 10 * math.log10(np.quantile(brute, quantile) * len(brute) / pn)
    assert floor_db <= 0
    paths, cut = _image(scene, diffuse_nlos_floor_db=floor_db)
    kept = np.sort(_diffuse(paths)[1])
    budget = pn * 10 ** (floor_db / 10)
    dropped = brute[: len(brute) - len(kept)]
    np.testing.assert_allclose(kept, brute[len(brute) - len(kept):], rtol=1e-9)  # the strongest, exactly
    assert dropped.sum() <= budget
    assert (dropped < budget / len(brute) * (1 + 1e-9)).all() and (kept >= budget / len(brute) * (1 - 1e-9)).all()
    text = cut["diffuse_nlos_cut"].split("neglected ")[1].split(" (")[0].replace(" W", "").split(" of ")
    assert float(text[0]) == pytest.approx(dropped.sum(), rel=1e-2, abs=1e-300)  # 3 significant digits
    assert float(text[1]) == pytest.approx(brute.sum(), rel=1e-2)
    if quantile is None:
        assert len(kept) == len(brute)
    else:
        assert len(kept) == pytest.approx((1 - quantile) * len(brute), abs=2)


def test_path_cap_keeps_the_strongest_pairs():
    scene = _scene()
    brute = _brute(scene, W)
    paths, cut = _image(scene, diffuse_nlos_max_paths=100)
    kept = np.sort(_diffuse(paths)[1])
    assert 0 < len(kept) <= 100 and f"kept {len(kept)} of {len(brute)} pairs" in cut["diffuse_nlos_cut"]
    assert cut["diffuse_nlos_cut"].endswith("path cap reached")
    np.testing.assert_allclose(kept, brute[len(brute) - len(kept):], rtol=1e-9)
    ray, _, _ = _ray(scene, diffuse_nlos_max_paths=100)
    np.testing.assert_allclose(np.sort(_diffuse(ray)[1]), kept, rtol=1e-9)


def test_raytrace_cell_phases_are_drawn_per_cell_and_differ_between_pairs():
    scene = _scene()
    model = RaytraceForwardModel({"noise": False, "diffuse": "off", "diffuse_nlos": "on", "mixed_paths": False})
    frame = model.simulate(scene, W, np.random.default_rng(1))
    assert frame.meta["components"]["diffuse_nlos"] == "on" and frame.meta["n_other_paths"] > 0
    again = model.simulate(scene, W, np.random.default_rng(1))
    np.testing.assert_array_equal(frame.ra_map.data, again.ra_map.data)  # seeded
