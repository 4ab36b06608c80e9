"""77 GHz radar: preset, rough-wall mirror attenuation and the diffuse NLOS path, through both forward
models, against closed forms (Friis λ² scaling, Rayleigh factor, lobe energy, three-bounce equation)."""
import math

import numpy as np
import pytest

from sims import diffuse_nlos
from sims.fresnel import fresnel
from sims.image import ImageForwardModel
from sims.materials import get_material
from sims.paths import MNLOS, OTHER
from sims.raytrace.model import RaytraceForwardModel
from sims.roughness import bistatic_sigma0, diffuse_fraction, specular_factor
from xnlos_core.signal.antenna import element_gain
from xnlos_core.radar import RadarConfig, load_radar

X = RadarConfig()
W = load_radar({"preset": "automotive_77ghz"}, "test", ".")
QUIET = {"noise": False, "random_phase": False}
IMG = ImageForwardModel({**QUIET, "diffuse": "off", "diffuse_nlos": "off"})
RAY = RaytraceForwardModel({**QUIET, "mixed_paths": False, "min_snr_db": -100.0})


def _scene(roughness=0.0, material="concrete"):
    from xnlos_core.scene import ObjectSpec, Scene, WallSpec
    wall = WallSpec(start=(20.0, 5.0), end=(20.0, -5.0), material=material, roughness=roughness)
    return Scene(walls=[wall], objects=[ObjectSpec(name="p", shape="point", center=(10.0, 0.0), rcs=10.0)])


def _image_mnlos(radar, scene):
    """Power [W] of the image model's mirror path (the rendering is common to both models)."""
    paths = IMG._paths(scene, scene.planar_walls(), radar, np.random.default_rng(0), 0.0,
                       {"diffuse": False, "transmission": False, "diffuse_nlos": False})
    return float(paths.power[paths.kind == MNLOS].sum())


def _ray_mnlos(radar, scene):
    _, paths, _, _ = RAY.trace(scene, radar)
    return float(paths.power[(paths.kind == MNLOS) & (paths.obj >= 0)].sum())


def test_preset_loads_by_name_with_1p6mw_and_the_xband_grids():
    assert W.carrier_frequency == 77e9 and W.transmit_power == 1.6e-3 and W.mimo
    diff = {k for k, v in W.model_dump().items() if X.model_dump()[k] != v}
    assert diff == {"carrier_frequency"}  # same aperture in wavelengths, same waveform
    np.testing.assert_array_equal(W.range_axis, X.range_axis)
    np.testing.assert_array_equal(W.azimuth_axis, X.azimuth_axis)
    assert W.n_channels == X.n_channels == 32


@pytest.mark.parametrize("measure", [_image_mnlos, _ray_mnlos], ids=["image", "raytrace"])
def test_smooth_wall_mnlos_ratio_77_over_10_is_friis_lambda2_times_reflectivity(measure):
    scene = _scene()
    g = {r.carrier_frequency: abs(fresnel(get_material("concrete").permittivity(r.carrier_frequency), 0.0, "s")[0])
         for r in (X, W)}
    want = (W.wavelength / X.wavelength) ** 2 * (g[77e9] / g[10e9]) ** 4
    assert 10 * math.log10((X.wavelength / W.wavelength) ** 2) == pytest.approx(17.7, abs=0.05)  # Fig. 2a
    assert measure(W, scene) / measure(X, scene) == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("measure", [_image_mnlos, _ray_mnlos], ids=["image", "raytrace"])
def test_1mm_roughness_attenuates_the_mirror_path_by_the_rayleigh_factor_per_bounce(measure):
    for radar in (X, W):
        ratio = measure(radar, _scene(1e-3)) / measure(radar, _scene(0.0))
        rho = math.exp(-(4 * math.pi * 1e-3 / radar.wavelength) ** 2)  # per bounce, normal incidence
        assert ratio == pytest.approx(rho**2, rel=1e-3)  # the round trip bounces twice (|α|⁴ in power)
    assert math.exp(-(4 * math.pi * 1e-3 / X.wavelength) ** 2) > 0.8  # barely at 10 GHz
    assert math.exp(-(4 * math.pi * 1e-3 / W.wavelength) ** 2) < 1e-4  # almost all diffuse at 77 GHz


@pytest.mark.parametrize("lobe,alpha_r", [("lambertian", 4), ("directive", 1), ("directive", 6)])
@pytest.mark.parametrize("f_c", [10e9, 77e9])
def test_energy_specular_plus_diffuse_equals_gamma2_at_most_incident(lobe, alpha_r, f_c):
    lam, th_i, sig = 299_792_458.0 / f_c, math.radians(35.0), 1e-3
    eps = get_material("concrete").permittivity(f_c)
    to_tx = np.array([math.sin(th_i), 0.0, math.cos(th_i)])
    # hemisphere midpoint grid: ∫ σ⁰/(4π cosθ_i) dΩ must equal F
    t = (np.arange(200) + 0.5) * (math.pi / 2) / 200
    p = (np.arange(400) + 0.5) * 2 * math.pi / 400
    T, P = np.meshgrid(t, p, indexing="ij")
    to_rx = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    s0 = bistatic_sigma0(eps, sig, lam, to_tx, to_rx, np.array([0.0, 0.0, 1.0]), lobe=lobe, alpha_r=alpha_r)
    diffuse = float(np.sum(s0 * np.sin(T)) * (math.pi / 2 / 200) * (2 * math.pi / 400)) / (4 * math.pi * math.cos(th_i))
    F = float(diffuse_fraction(eps, sig, th_i, lam))
    assert diffuse == pytest.approx(F, rel=2e-3)
    g2 = abs(fresnel(eps, th_i, "s")[0]) ** 2
    spec = float(specular_factor(sig, th_i, lam)) * g2
    assert spec + F == pytest.approx(g2, rel=1e-12) and spec + F <= 1.0


def test_auto_switch_follows_the_carrier_and_the_roughness():
    m = ImageForwardModel(QUIET)
    assert m.components(_scene(1e-3), X)["diffuse_nlos"].startswith("off")  # ρ_s(0) = 0.84 at 10 GHz
    assert m.components(_scene(1e-3), W)["diffuse_nlos"] == "on"  # ρ_s(0) = 3e-5 at 77 GHz
    assert m.components(_scene(0.0), W)["diffuse_nlos"].startswith("off")
    assert m.components(_scene(5e-3), X)["diffuse_nlos"] == "on"
    assert "diffuse_nlos" not in m.params.model_dump()  # default left out of config digests


def test_one_cell_diffuse_path_matches_the_three_bounce_radar_equation():
    """Wall x = 20 m, 10 m long, as ONE cell at (20, 0); point at (10, 0): normal incidence at both
    ends, Lambertian σ⁰ = 4F cosθ_i cosθ_s = 4F, dA = 10 m × 3 m."""
    model = ImageForwardModel({**QUIET, "diffuse": "off", "mirror_paths": False, "diffuse_nlos": "on",
                               "diffuse_nlos_cell": 10.0})
    paths = model._paths(_scene(1e-3), _scene(1e-3).planar_walls(), W, np.random.default_rng(0), 0.0,
                         {"diffuse": False, "transmission": False, "diffuse_nlos": True})
    diff = paths.kind == OTHER
    assert diff.sum() == 1
    eps = get_material("concrete").permittivity(W.carrier_frequency)
    F = float(diffuse_fraction(eps, 1e-3, 0.0, W.wavelength))
    sA = 4 * F * 30.0
    ge = float(element_gain(W, 0.0))
    want = (W.transmit_power * ge**2 * W.wavelength**2 * 10.0 * sA**2
            / ((4 * math.pi) ** 5 * 20.0**2 * 10.0**2 * 10.0**2 * 20.0**2 * 10 ** (W.system_loss_db / 10)))
    assert paths.power[diff][0] == pytest.approx(want, rel=1e-9)
    assert paths.length[diff][0] == pytest.approx(60.0)
    assert diffuse_nlos.mostly_diffuse(_scene(1e-3).walls[0], W)


def test_diffuse_paths_only_when_on_and_the_rng_stream_is_unchanged():
    scene = _scene(1e-3)
    on = ImageForwardModel({"diffuse_nlos": "on"}).simulate(scene, W, np.random.default_rng(3))
    off = ImageForwardModel({"diffuse_nlos": "off"}).simulate(scene, W, np.random.default_rng(3))
    assert on.meta["components"]["diffuse_nlos"] == "on" and on.meta["n_paths"] > off.meta["n_paths"]
    np.testing.assert_array_equal(on.ground_truth.mnlos_points, off.ground_truth.mnlos_points)
