"""Ray-trace forward model: cross-checks with the image method, physics acceptance, backends, depth."""
import math

import numpy as np
import pytest

from sims.image import ImageForwardModel
from sims.raytrace.caster import embree_available
from sims.raytrace.model import RaytraceForwardModel
from sims.raytrace.tracer import image_paths
from xnlos_core.errors import InputError
from xnlos_core.geometry import cartesian_to_polar, mirror_reflect, ray_segment_intersection
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import ObjectSpec, Scene, WallSpec, load_scene
from xnlos_core.signal.chain import noise_floor

RADAR = RadarConfig()
DR = RADAR.range_resolution
QUIET = {"noise": False, "random_phase": False}


def _cell(radar, point):
    r, th = cartesian_to_polar(np.asarray(point, float))
    return int(np.round(r / radar.range_resolution)), int(np.argmin(np.abs(radar.azimuth_axis - th)))


def _peak_near(frame, point, radius=2):
    i, j = _cell(frame.ra_map.radar if hasattr(frame.ra_map, "radar") else RADAR, point)
    p = frame.ra_map.power[max(i - radius, 0):i + radius + 1, max(j - radius, 0):j + radius + 1]
    k = np.unravel_index(np.argmax(p), p.shape)
    return (k[0] + max(i - radius, 0), k[1] + max(j - radius, 0)), float(p[k])


def _planar_scene():
    """Wall x = 80ΔR (20 m); a point in front at (40ΔR, 4 m): seen directly and in the mirror."""
    b = 80 * DR
    wall = WallSpec(start=(b, 12.0), end=(b, -12.0), reflectivity=0.6, backscatter_db=-80.0)
    return Scene(walls=[wall], objects=[ObjectSpec(shape="point", center=(40 * DR, 4.0), rcs=10.0)])


def test_raytrace_and_image_agree_on_a_planar_wall():
    scene = _planar_scene()
    img = ImageForwardModel(QUIET).simulate(scene, RADAR, np.random.default_rng(0))
    ray = RaytraceForwardModel({**QUIET, "mixed_paths": False}).simulate(scene, RADAR, np.random.default_rng(0))
    o = np.array([40 * DR, 4.0])
    o_img = mirror_reflect(o[None], np.array([-1.0, 0.0]), 80 * DR)[0]
    for point in (o, o_img):
        (ki, pi), (kr, pr) = _peak_near(img, point), _peak_near(ray, point)
        assert abs(ki[0] - kr[0]) <= 1 and abs(ki[1] - kr[1]) <= 1
        assert abs(10 * math.log10(pr / pi)) < 1.0
    np.testing.assert_allclose(ray.ground_truth.mnlos_points, img.ground_truth.mnlos_points, atol=1e-6)


def test_specular_points_match_the_analytic_image_method():
    scene = load_scene({"builtin": "corner"}, "test")
    model = RaytraceForwardModel(QUIET)
    world, _, tr, _ = model.trace(scene, RADAR)
    facade = scene.wall_segments()[0]
    pts2, nrm2, _ = scene.objects[0].scatterers(0.0)
    pts = np.column_stack([pts2, np.full(len(pts2), 0.75)])
    nrm = np.column_stack([nrm2, np.zeros(len(pts2))])
    chain = [c for c in tr.chains if len(c) == 1 and world.surfaces[world.plane_surface[c[0]]].name == facade.name]
    assert chain
    ok, virt, q, _ = image_paths(world, np.array([0.0, 0.0, 0.75]), pts, nrm, chain[0], None, model.params.az_step)
    assert ok.sum() >= 10
    img = mirror_reflect(pts2[ok], facade.normal, facade.offset)
    t, _ = ray_segment_intersection(img, facade.start, facade.end)
    np.testing.assert_allclose(virt[ok, :2], img, atol=1e-9)
    np.testing.assert_allclose(q[ok, 0, :2], t[:, None] * img, atol=1e-6)  # specular point w = t·o'
    # and the same set of the car's hidden points as the image model (the ray tracer also lists
    # wall strips seen in one mirror, owned by "wall:<name>" entries after the scene's objects)
    f = model.simulate(scene, RADAR, np.random.default_rng(0))
    g = ImageForwardModel(QUIET).simulate(scene, RADAR, np.random.default_rng(0))
    car = f.ground_truth.mnlos_object < len(scene.objects)
    assert {tuple(p) for p in np.round(f.ground_truth.hidden_points[car], 6)} == \
        {tuple(p) for p in np.round(g.ground_truth.hidden_points, 6)}
    walls = f.ground_truth.object_names[len(scene.objects):]
    assert walls and all(n.startswith("wall:") for n in walls)
    strip = ~car  # a wall strip seen in the facade: o' is its hit point o mirrored across the facade
    via_facade = np.abs(f.ground_truth.hidden_points[strip] @ facade.normal + facade.offset) > 1e-6
    o = f.ground_truth.hidden_points[strip][via_facade]
    np.testing.assert_allclose(f.ground_truth.mnlos_points[strip][via_facade],
                               mirror_reflect(o, facade.normal, facade.offset), atol=1e-6)


def _corner(distance_behind: float, carrier: float = 10e9, roughness: float = 1e-3):
    """A concrete street corner: a chamfered facade across the junction relays into the cross
    street, where a car waits ``distance_behind`` [m] behind the near building (no line of sight)."""
    c = dict(material="concrete", roughness=roughness)
    walls = [WallSpec(name="chamfer", start=(15.0, 10.0), end=(35.0, -10.0), **c),
             WallSpec(name="block_front", start=(5.0, -4.0), end=(18.0, -4.0), **c),
             WallSpec(name="block_side", start=(18.0, -4.0), end=(18.0, -70.0), **c),
             WallSpec(name="far_side", start=(35.0, -10.0), end=(35.0, -70.0), **c)]
    car = ObjectSpec(name="car", kind="car", center=(22.0, -4.0 - distance_behind), size=(4.5, 1.8),
                     heading=math.pi / 2, rcs=10.0)
    return Scene(walls=walls, objects=[car]), RadarConfig(carrier_frequency=carrier, max_range=100.0)


def test_hidden_car_40m_behind_a_concrete_corner_is_above_the_noise_floor():
    """Expected cell SNR ≥ 0 dB (ground truth lists it), and the car's own echo (the map minus the
    same map without the car) peaks above the noise floor on average over speckle draws (single
    draws fade, as Rayleigh speckle does)."""
    scene, radar = _corner(40.0)
    model = RaytraceForwardModel({"noise": False})
    snr = []
    for seed in range(1, 11):
        f = model.simulate(scene, radar, np.random.default_rng(seed))
        empty = model.simulate(scene.model_copy(update={"objects": []}), radar, np.random.default_rng(seed))
        gt = f.ground_truth
        mine = gt.mnlos_object == 0  # the car (walls seen in the mirror follow the objects)
        assert mine.any() and len(gt.los_points) > 0
        assert np.all(gt.hidden_points[mine, 1] < -40.0)  # really behind the corner
        car = np.abs(f.ra_map.data - empty.ra_map.data) ** 2
        i, j = _cell(radar, gt.mnlos_points[mine].mean(axis=0))
        snr.append(10 * math.log10(car[i - 3:i + 4, j - 2:j + 3].max() / noise_floor(radar)))
    lin = 10 ** (np.array(snr) / 10)
    assert np.mean(lin) > 1.4 and np.median(snr) > 0.0


def test_77ghz_with_5mm_roughness_relays_much_less_than_10ghz():
    peak = {}
    for f_c in (10e9, 77e9):
        scene, radar = _corner(20.0, f_c, roughness=5e-3)
        model = RaytraceForwardModel({"noise": False, "random_phase": False, "min_snr_db": -100.0})
        world, paths, _, _ = model.trace(scene, radar)
        peak[f_c] = float(paths.power[(paths.kind == 1) & (paths.obj >= 0)].sum())  # the car via the relay
    assert peak[10e9] > 0 and peak[77e9] < 1e-3 * peak[10e9]


@pytest.mark.skipif(not embree_available(), reason="embreex not installed")
def test_pure_numpy_backend_traces_the_same_paths():
    scene = load_scene({"builtin": "corner"}, "test")
    a = RaytraceForwardModel({**QUIET, "backend": "embree"}).simulate(scene, RADAR, np.random.default_rng(0))
    b = RaytraceForwardModel({**QUIET, "backend": "triangle"}).simulate(scene, RADAR, np.random.default_rng(0))
    assert a.meta["backend"] == "embree" and b.meta["backend"] == "triangle"
    assert a.meta["n_paths"] == b.meta["n_paths"]
    np.testing.assert_allclose(b.ra_map.data, a.ra_map.data, atol=1e-4 * np.abs(a.ra_map.data).max())


def test_bounce_depth_adapts_to_the_noise_floor():
    """Two facing mirrors: rays could bounce forever; they stop when nothing could be seen."""
    walls = [WallSpec(start=(2.0, 6.0), end=(90.0, 6.0), reflectivity=0.9),
             WallSpec(start=(2.0, -6.0), end=(90.0, -6.0), reflectivity=0.9)]
    scene = Scene(walls=walls, objects=[ObjectSpec(shape="point", center=(40.0, 0.0), rcs=1.0)])
    deep = RaytraceForwardModel({**QUIET, "max_bounces": 10, "min_snr_db": -100.0}).simulate(
        scene, RADAR, np.random.default_rng(0))
    strict = RaytraceForwardModel({**QUIET, "max_bounces": 10, "min_snr_db": 30.0}).simulate(
        scene, RADAR, np.random.default_rng(0))
    assert deep.meta["max_bounce"] == 10
    assert strict.meta["max_bounce"] < deep.meta["max_bounce"]


def test_curved_wall_and_corner_give_several_chains():
    arc = WallSpec(start=(25.0, -10.0), end=(25.0, 10.0), radius=25.0, reflectivity=0.6, backscatter_db=-80.0)
    scene = Scene(walls=[arc], objects=[ObjectSpec(shape="point", center=(10.0, -3.0), rcs=10.0)])
    f = RaytraceForwardModel(QUIET).simulate(scene, RADAR, np.random.default_rng(0))
    assert f.meta["chains"] >= 5 and f.meta["n_mnlos_paths"] >= 1
    assert len(f.ground_truth.walls) == len(arc.facets())


def test_radar_inside_a_wall_is_refused():
    scene = Scene(walls=[WallSpec(start=(-1.0, 0.0), end=(1.0, 0.0), thickness=0.5, material="concrete")])
    with pytest.raises(InputError, match="inside wall"):
        RaytraceForwardModel().simulate(scene, RADAR, np.random.default_rng(0))
    car_in_wall = Scene(walls=[WallSpec(start=(20.0, -5.0), end=(20.0, 5.0))],
                        objects=[ObjectSpec(center=(20.5, 0.0), size=(2.0, 1.0))])
    with pytest.raises(InputError, match="car|object"):
        RaytraceForwardModel().simulate(car_in_wall, RADAR, np.random.default_rng(0))


def test_user_meshes_are_traced(tmp_path):
    from pathlib import Path

    from xnlos_core.scene import MeshSpec

    meshes = Path(__file__).parents[1] / "data" / "meshes"
    spec = MeshSpec(name="kiosk", file="box.stl", material="concrete", roughness=2e-3, translation=(25.0, 0.0, 0.0),
                    scale=4.0)
    scene = Scene(meshes=[spec], base_dir=str(meshes),
                  objects=[ObjectSpec(shape="point", center=(10.0, 8.0), rcs=10.0)])
    f = RaytraceForwardModel(QUIET).simulate(scene, RADAR, np.random.default_rng(0))
    assert f.meta["faces"] >= 12 and f.meta["n_los_paths"] > 0
    inside = scene.model_copy(update={"meshes": [spec.model_copy(update={"translation": (0.0, 0.0, 0.0)})]})
    with pytest.raises(InputError, match="inside"):
        RaytraceForwardModel(QUIET).simulate(inside, RADAR, np.random.default_rng(0))


def test_same_seed_same_map_and_conformance():
    from xnlos_core.testing import check_component

    scene = load_scene({"builtin": "corner"}, "test")
    m = RaytraceForwardModel()
    a = m.simulate(scene, RADAR, np.random.default_rng(3))
    b = m.simulate(scene, RADAR, np.random.default_rng(3))
    np.testing.assert_array_equal(a.ra_map.data, b.ra_map.data)
    check_component("forward_model", "raytrace")


def test_picture_is_written(tmp_path):
    from sims.raytrace.picture import plot_trace

    out = plot_trace(load_scene({"builtin": "corner"}, "test"), RadarConfig(n_samples=256, max_range=60.0),
                     tmp_path / "rt.png", max_rays=50)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_picture_is_oriented_like_every_bev_and_ra_figure():
    import matplotlib.pyplot as plt

    from sims.raytrace.picture import trace_figure
    from xnlos_core.bev import AZIMUTH_LABEL

    fig = trace_figure(load_scene({"builtin": "corner"}, "test"), RadarConfig(n_samples=256, max_range=60.0),
                       max_rays=20)
    try:
        ax, ax2 = fig.axes[:2]
        assert ax.get_ylabel() == "x [m] (forward)" and ax.get_xlim()[0] < ax.get_xlim()[1]  # −y to the right
        assert ax2.get_xlabel() == AZIMUTH_LABEL and ax2.get_xlim()[0] > 0 > ax2.get_xlim()[1]
        ax.figure.canvas.draw()
        leg = ax.get_legend().get_window_extent()
        data = ax.get_window_extent()
        assert leg.y1 <= data.y0  # the legend is below the data area
    finally:
        plt.close(fig)


def _generated(family: str, seed: int):
    from sims.generators import generate_scene

    return generate_scene(family, seed)


@pytest.mark.parametrize("backend", ["embree", "triangle"])
def test_a_batched_cast_hits_what_one_ray_at_a_time_hits(backend):
    """One call with every ray gives each ray the triangle and distance it gets cast alone."""
    if backend == "embree" and not embree_available():
        pytest.skip("embreex not installed")
    from sims.raytrace.world import build_world

    world = build_world(_generated("crossroads", 3), 0.0, backend)
    rng = np.random.default_rng(5)
    n = 60
    az = rng.uniform(-math.pi / 3, math.pi / 3, n)
    d = np.column_stack([np.cos(az), np.sin(az), rng.normal(0, 0.02, n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.column_stack([rng.uniform(-1, 1, (n, 2)), np.full(n, 0.75)])
    tri, dist = world.caster.first_hit(o, d)
    one = [world.caster.first_hit(o[i:i + 1], d[i:i + 1]) for i in range(n)]
    assert (tri >= 0).sum() > n // 2
    np.testing.assert_array_equal(tri, np.concatenate([t for t, _ in one]))
    np.testing.assert_array_equal(dist, np.concatenate([x for _, x in one]))


@pytest.mark.parametrize("family, seed", [("crossroads", 1), ("corner_split", 2), ("curved_wall", 0),
                                          ("parking_lot", 4)])
def test_batched_image_paths_equal_one_chain_and_object_at_a_time(family, seed):
    """image_paths_chains (every centre through every chain, one cast per leg and chain length)
    gives bit for bit what image_paths gives per object and chain (the tracer's earlier loop)."""
    from sims.raytrace.tracer import image_paths_chains

    scene = _generated(family, seed)
    model = RaytraceForwardModel()
    world, _, tr, _ = model.trace(scene, RADAR)
    chains = {(): None, **tr.chains}
    origin = np.array([0.0, 0.0, model.params.radar_height])
    pts, nrm = [], []
    for o in scene.objects:
        p2, n2, _ = o.scatterers(0.0)
        pts.append(np.column_stack([p2, np.full(len(p2), min(model.params.radar_height, o.height))]))
        nrm.append(np.column_stack([n2, np.zeros(len(n2))]))
    assert len(pts) >= 1 and any(len(c) >= 2 for c in chains)
    before = world.caster.rays_cast
    got = image_paths_chains(world, origin, pts, nrm, chains, model.params.az_step)
    batched_rays = world.caster.rays_cast - before
    found = 0
    for j in range(len(pts)):
        for c, sector in chains.items():
            ok, virt, _, th = image_paths(world, origin, pts[j], nrm[j], c, sector, model.params.az_step)
            g_ok, g_virt, g_th = got[j, c]
            np.testing.assert_array_equal(g_ok, ok)
            np.testing.assert_array_equal(g_virt, virt)
            np.testing.assert_array_equal(g_th, th)
            found += int(ok.sum())
    assert found > 0 and world.caster.rays_cast - before == 2 * batched_rays  # the same rays, fewer calls
