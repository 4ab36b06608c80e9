"""Image model with material walls: Fresnel/slab α, roughness, diffuse lobe, transmission,
atmosphere and coupling — each added only when the scene or radar needs it."""
import math

import numpy as np
import pytest

from sims.fresnel import fresnel, slab
from sims.image import ImageForwardModel
from sims.materials import get_material
from sims.propagation import received_power
from sims.roughness import backscatter_sigma0, specular_factor
from sims.walls import specular_alpha
from xnlos_core.errors import InputError
from xnlos_core.geometry import cartesian_to_polar
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.scene import AtmosphereSpec, ObjectSpec, Scene, WallSpec

RADAR = RadarConfig()
DR = RADAR.range_resolution
CLEAN = ImageForwardModel({"noise": False, "random_phase": False})


def _cell(radar, point):
    r, th = cartesian_to_polar(np.asarray(point, float))
    return int(np.round(r / radar.range_resolution)), int(np.argmin(np.abs(radar.azimuth_axis - th)))


def _point(x, y):
    return ObjectSpec(name="p", shape="point", center=(x, y), rcs=10.0)


def _mirror_scene(**wall):
    b = 80 * DR  # wall x = b, point at (40 ΔR, 0): image at 120 ΔR on boresight, normal incidence
    return Scene(walls=[WallSpec(start=(b, 5.0), end=(b, -5.0), **wall)], objects=[_point(40 * DR, 0.0)])


def test_constant_walls_need_no_optional_component():
    use = CLEAN.components(_mirror_scene(reflectivity=0.6), RADAR)
    assert all(v.startswith("off") for v in use.values())


def test_mirror_amplitude_uses_the_slab_reflection_and_the_roughness_field_factor():
    scene = _mirror_scene(material="concrete", thickness=0.25, roughness=0.5e-3)
    f = CLEAN.simulate(scene, RADAR, np.random.default_rng(0))
    eps = get_material("concrete").permittivity(RADAR.carrier_frequency)
    gamma = slab(eps, 0.25, 0.0, RADAR.carrier_frequency, "s")[0]
    alpha = abs(gamma) * math.sqrt(specular_factor(0.5e-3, 0.0, RADAR.wavelength))
    want = received_power(RADAR, 120 * DR, 0.0, 10.0, alpha)
    assert f.ra_map.power[_cell(RADAR, (120 * DR, 0.0))] == pytest.approx(want, rel=2e-3)
    half = abs(fresnel(eps, 0.0, "s")[0])
    assert half == pytest.approx(0.39, abs=0.01)  # the normal-incidence concrete value


def test_rough_5mm_wall_relays_far_less_at_77ghz_than_at_10ghz():
    """Grazing relay geometry (incidence 75°): a mirror at 10 GHz, diffuse at 77 GHz."""
    b = 10.0  # wall y = b along x; radar looks along it, object across
    wall = WallSpec(start=(5.0, b), end=(80.0, b), material="concrete", roughness=5e-3)
    scene = Scene(walls=[wall], objects=[_point(60.0, 2.0)])
    out = {}
    for f_c in (10e9, 77e9):
        radar = RadarConfig(carrier_frequency=f_c)
        a = specular_alpha(wall, radar, math.radians(75.0))
        out[f_c] = float(np.abs(a)) ** 4
        frame = CLEAN.simulate(scene, radar, np.random.default_rng(0))
        assert frame.meta["n_mnlos_paths"] == 1
    assert out[77e9] < 1e-3 * out[10e9]  # ≥ 30 dB weaker mirror path


def test_diffuse_lobe_gives_los_echoes_only_from_rough_material_walls():
    wall = dict(start=(20.0, 10.0), end=(20.0, -10.0), material="concrete")
    smooth = Scene(walls=[WallSpec(**wall)])
    rough = Scene(walls=[WallSpec(**wall, roughness=3e-3)])
    assert CLEAN.components(smooth, RADAR)["diffuse"].startswith("off")
    assert CLEAN.simulate(smooth, RADAR, np.random.default_rng(0)).meta["n_los_paths"] == 0
    f = CLEAN.simulate(rough, RADAR, np.random.default_rng(0))
    assert f.meta["components"]["diffuse"] == "on" and f.meta["n_los_paths"] > 50
    off = ImageForwardModel({"noise": False, "random_phase": False, "diffuse": "off"})
    assert off.simulate(rough, RADAR, np.random.default_rng(0)).meta["n_los_paths"] == 0
    # the cell on the wall normal has σ = σ⁰(0)·Δs·h with the lobe's σ⁰
    eps = get_material("concrete").permittivity(RADAR.carrier_frequency)
    s0 = float(backscatter_sigma0(eps, 3e-3, 0.0, RADAR.wavelength))
    assert 0 < s0 < 1


def test_transmission_through_a_glass_wall_only_when_modelled():
    glass = WallSpec(start=(10.0, 5.0), end=(10.0, -5.0), material="glass", thickness=0.01, relay=False)
    scene = Scene(walls=[glass], objects=[_point(30.0, 0.0)])
    f = CLEAN.simulate(scene, RADAR, np.random.default_rng(0))
    assert f.meta["components"]["transmission"] == "on"
    eps = get_material("glass").permittivity(RADAR.carrier_frequency)
    t = abs(slab(eps, 0.01, 0.0, RADAR.carrier_frequency, "s")[1])
    want = received_power(RADAR, 30.0, 0.0, 10.0) * t**4
    k = _cell(RADAR, (30.0, 0.0))
    assert f.ra_map.power[k] == pytest.approx(want, rel=0.05)  # 30 m is 120 ΔR: on the grid
    off = ImageForwardModel({"noise": False, "random_phase": False, "transmission": "off"})
    assert off.simulate(scene, RADAR, np.random.default_rng(0)).ra_map.power[k] < 1e-6 * want
    # a wall without thickness (half-space) or without material stays opaque
    opaque = Scene(walls=[glass.model_copy(update={"thickness": None})], objects=[_point(30.0, 0.0)])
    assert CLEAN.simulate(opaque, RADAR, np.random.default_rng(0)).meta["n_los_paths"] == 0


def test_atmosphere_is_added_only_when_it_matters():
    scene = _mirror_scene(reflectivity=0.6).model_copy(update={"atmosphere": AtmosphereSpec()})
    assert CLEAN.components(scene, RADAR)["atmosphere"].startswith("off: ≤")  # 0.003 dB at 10 GHz
    r77 = RadarConfig(carrier_frequency=77e9)
    fine = ImageForwardModel({"noise": False, "random_phase": False, "tolerance_db": 0.01})
    assert fine.components(scene, r77)["atmosphere"] == "on"  # 0.07 dB at 77 GHz over 200 m
    on = ImageForwardModel({"noise": False, "random_phase": False, "atmosphere": "on"})
    k = _cell(RADAR, (120 * DR, 0.0))
    p_on = on.simulate(scene, RADAR, np.random.default_rng(0)).ra_map.power[k]
    p_off = CLEAN.simulate(scene, RADAR, np.random.default_rng(0)).ra_map.power[k]
    loss = 10 * math.log10(p_off / p_on)
    from sims.atmosphere import attenuation_db

    assert loss == pytest.approx(float(attenuation_db(10e9, 2 * 120 * DR)), rel=0.02)


def test_coupling_follows_the_radar_and_can_be_switched_off():
    radar = RadarConfig(coupling_db=-12.0)
    scene = _mirror_scene(reflectivity=0.6)
    f = CLEAN.simulate(scene, radar, np.random.default_rng(0))
    assert f.meta["components"]["coupling"] == "on"
    off = ImageForwardModel({"noise": False, "random_phase": False, "coupling": "off"})
    g = off.simulate(scene, radar, np.random.default_rng(0))
    ref = CLEAN.simulate(scene, RADAR, np.random.default_rng(0))
    np.testing.assert_allclose(g.ra_map.data, ref.ra_map.data, rtol=0, atol=1e-6 * np.abs(ref.ra_map.data).max())
    assert np.abs(f.ra_map.data - ref.ra_map.data).max() > 1e-3 * np.abs(ref.ra_map.data).max()


def test_fdtd_reflection_agrees_with_analytic_in_the_simulator(tmp_path, monkeypatch):
    monkeypatch.setenv("XNLOS_CACHE_DIR", str(tmp_path))
    wall = WallSpec(start=(0.0, 5.0), end=(1.0, 5.0), material="glass", thickness=0.012)
    th = np.radians([0.0, 22.0, 47.0, 70.0])
    a = specular_alpha(wall, RADAR, th, "analytic")
    b = specular_alpha(wall, RADAR, th, "fdtd")
    assert np.abs(np.abs(a) - np.abs(b)).max() < 0.03
    assert any(tmp_path.iterdir())  # the FDTD results were cached on disk


def test_material_walls_validate_early():
    with pytest.raises(ValueError, match="not both"):
        WallSpec(start=(0, 0), end=(1, 0), material="concrete", reflectivity=0.5)
    with pytest.raises(ValueError, match="need a material"):
        WallSpec(start=(0, 0), end=(1, 0), roughness=1e-3)
    # the material table belongs to the forward model: its check names the wall and suggests the name
    concret = Scene(walls=[WallSpec(name="facade", start=(20.0, 5.0), end=(20.0, -5.0), material="concret")])
    for name in ("image", "raytrace"):
        fm = get_registry().create("forward_model", name)
        with pytest.raises(InputError, match=r"walls\[0\] \('facade'\): unknown material 'concret' — did you mean 'concrete'"):
            fm.check(concret, RadarConfig())
    brick = Scene(walls=[WallSpec(start=(20.0, 5.0), end=(20.0, -5.0), material="brick")], objects=[_point(10, 0)])
    # P.2040 brick is valid to 40 GHz only: a documented, warned fallback up to 100 GHz (sims.material_fallback)
    with pytest.raises(InputError, match="brick"):
        CLEAN.simulate(brick, RadarConfig(carrier_frequency=120e9), np.random.default_rng(0))


def test_both_amplitude_conventions_render_the_same_frame():
    """render_paths: paths with real amplitudes √P (image) and with complex amplitudes (raytrace)
    give the same ADC cube and ground truth, atmosphere and coupling included."""
    from sims.paths import LOS, MNLOS, PathList
    from sims.render import render_paths

    scene = _mirror_scene(reflectivity=0.6).model_copy(update={"atmosphere": AtmosphereSpec()})
    radar = RadarConfig(carrier_frequency=35e9, coupling_db=-20.0)
    pos = np.array([[10.0, 1.0], [30.0, -2.0]])
    r, th = cartesian_to_polar(pos)
    power = received_power(radar, r, th, 10.0)
    cols = dict(length=2 * r, azimuth=th, power=power, phase=np.array([0.3, 2.0]), kind=np.array([LOS, MNLOS]),
                order=np.array([0, 1]), pos=pos, hidden=pos, obj=0, centre=np.array([0, 1]))
    real, cplx = PathList(), PathList()
    real.add(**cols)
    cplx.add(**cols, amp=np.sqrt(power).astype(complex))
    with pytest.raises(ValueError, match="amp"):
        real.add(**cols, amp=np.sqrt(power))
    use = {"atmosphere": "on", "coupling": "on"}
    p = ImageForwardModel.Params(noise=False, min_snr_db=-100.0)
    out = [render_paths(pl.paths(), scene, radar, np.random.default_rng(0), p, use, forward_model="t", walls=())
           for pl in (real, cplx)]
    assert out[0][1].meta["n_paths"] == 2 and len(out[0][1].ground_truth.mnlos_points) == 1
    np.testing.assert_allclose(out[0][0], out[1][0], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(out[0][1].ground_truth.los_snr_db, out[1][1].ground_truth.los_snr_db)
    atm = render_paths(real.paths(), scene, radar, np.random.default_rng(0), p, {**use, "atmosphere": "off"},
                       forward_model="t", walls=())
    assert np.all(atm[1].ground_truth.los_snr_db > out[0][1].ground_truth.los_snr_db)  # the loss shows in the SNR
