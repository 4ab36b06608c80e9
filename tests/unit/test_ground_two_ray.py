"""3-D propagation (sims.ground): two-ray nulls against the closed form, ground reflection, twins, auto."""
import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from sims.fresnel import fresnel
from sims.ground import ground_reflection, null_ranges, sweep_wavelength, twins
from sims.image import ImageForwardModel
from sims.materials import get_material
from sims.paths import PathList
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import GroundSpec, ObjectSpec, Scene, WallSpec

RADAR = RadarConfig()
DR = RADAR.range_resolution
MIRROR = GroundSpec(reflection=-1.0)
MID = RADAR.azimuth_axis.size // 2


def _point(d: float, h_t: float) -> ObjectSpec:
    return ObjectSpec(name="p", shape="point", center=(d, 0.0), centre_height=h_t)


def _boresight_power(d: float, h_r: float, h_t: float) -> float:
    """Peak |RA|² [W] near boresight of one point at (d, 0), height h_t, radar at h_r over Γ = −1."""
    model = ImageForwardModel({"noise": False, "random_phase": False, "dimensions": "3d", "radar_height": h_r})
    frame = model.simulate(Scene(objects=[_point(d, h_t)], ground=MIRROR), RADAR, np.random.default_rng(0))
    return float(np.max(np.abs(frame.ra_map.data[:, MID - 2:MID + 3]) ** 2))


def test_null_ranges_solve_the_exact_path_difference():
    lam, h_r, h_t = 0.03, 0.75, 0.6
    d = null_ranges(lam, h_r, h_t, 5)
    diff = np.hypot(d, h_t + h_r) - np.hypot(d, h_t - h_r)
    np.testing.assert_allclose(diff, lam * np.arange(1, len(d) + 1), rtol=1e-12)
    assert d[0] == pytest.approx(2 * h_r * h_t / lam, rel=1e-3)  # far-field 2 h_r h_t / λ


@pytest.mark.parametrize("h_r", [0.5, 0.75, 1.2])
def test_two_ray_nulls_within_one_range_bin_of_the_closed_form(h_r):
    """A range sweep of one point over a perfect reflector: each power minimum near a predicted null
    (R_G − R_D = nλ at the sweep's mean wavelength) lies within one range bin of it, and is deep."""
    h_t = 0.6
    predicted = null_ranges(sweep_wavelength(RADAR), h_r, h_t, 3)
    predicted = predicted[predicted > 5.0]
    assert len(predicted) >= 2
    for d_n in predicted:
        found = minimize_scalar(lambda d: math.log(_boresight_power(d, h_r, h_t) + 1e-40),
                                bounds=(d_n - 4 * DR, d_n + 4 * DR), method="bounded", options={"xatol": 0.01}).x
        assert abs(found - d_n) <= DR, (h_r, d_n, found)
        # the null is deep: ≥ 20 dB below the peak of the lobe half-way to the next null outwards
        peak = _boresight_power(d_n * 1.5 if d_n == predicted[0] else d_n * 1.25, h_r, h_t)
        assert _boresight_power(found, h_r, h_t) < peak / 100


def test_ground_reflection_is_fresnel_at_the_grazing_angle_with_the_radar_polarisation():
    psi = np.radians([1.0, 10.0, 45.0])
    eps = get_material("concrete").permittivity(RADAR.carrier_frequency)
    got = ground_reflection(GroundSpec(material="concrete"), RADAR, psi)
    np.testing.assert_allclose(got, fresnel(eps, np.pi / 2 - psi, "p")[0])  # V is TM on the ground
    h = RADAR.model_copy(update={"polarization": "H"})
    np.testing.assert_allclose(ground_reflection(GroundSpec(material="concrete"), h, psi),
                               fresnel(eps, np.pi / 2 - psi, "s")[0])
    assert abs(ground_reflection(GroundSpec(material="concrete"), RADAR, 1e-4) + 1) < 0.01  # grazing → −1
    np.testing.assert_array_equal(ground_reflection(MIRROR, RADAR, psi), -1.0)


def test_twins_lengths_amplitudes_and_elevations():
    d, h_r, h_t = 20.0, 0.75, 0.3
    r_d = math.hypot(d, h_t - h_r)
    out = PathList()
    out.add(length=2 * r_d, azimuth=0.0, power=1.0, kind=0, order=0, pos=[[d, 0.0]], hidden=[[d, 0.0]], obj=0,
            centre=0, height=h_t)
    tw = twins(out.paths(), RADAR, h_r, 0.0, MIRROR)
    r_g = math.hypot(d, h_t + h_r)
    np.testing.assert_allclose(tw.paths.length, [2 * r_d, r_d + r_g, r_g + r_d, 2 * r_g], rtol=1e-14)
    eps_d, eps_g = math.atan2(h_t - h_r, d), -math.atan2(h_t + h_r, d)
    np.testing.assert_allclose(tw.elevation, [eps_d, eps_g, eps_d, eps_g])
    pat = lambda e: math.cos(e) ** RADAR.element_pattern_exponent_el  # noqa: E731  (one patch per column)
    expect = [pat(eps_d), -math.sqrt(pat(eps_d) * pat(eps_g)) * r_d / r_g,
              -math.sqrt(pat(eps_d) * pat(eps_g)) * r_d / r_g, pat(eps_g) * (r_d / r_g) ** 2]
    np.testing.assert_allclose(tw.paths.amp, expect, rtol=1e-12)
    assert np.all(tw.source == 0)


def test_tilt_shifts_the_elevation_pattern():
    out = PathList()
    out.add(length=40.0, azimuth=0.0, power=1.0, kind=0, order=0, pos=[[20.0, 0.0]], hidden=[[20.0, 0.0]], obj=0,
            centre=0)
    tilt = math.radians(20)
    tw = twins(out.paths(), RADAR, 0.75, tilt)
    # the 2-D power was computed on boresight; at the same height the path now sits 20° below it
    assert tw.gain[0] == pytest.approx(math.cos(-tilt) ** (2 * RADAR.element_pattern_exponent_el), rel=1e-12)


def test_auto_picks_3d_with_a_ground_and_says_why():
    scene = Scene(walls=[WallSpec(start=(30.0, 10.0), end=(30.0, -10.0), reflectivity=0.6)],
                  objects=[_point(15.0, 0.6)], ground=GroundSpec(material="concrete"))
    model = ImageForwardModel({"noise": False, "random_phase": False})
    use = model.simulate(scene, RADAR, np.random.default_rng(0)).meta["components"]["dimensions"]
    assert use.startswith("3d:") and "dB" in use and "ground" in use
    flat = model.simulate(scene.model_copy(update={"ground": None, "objects": [_point(15.0, 0.75)]}), RADAR,
                          np.random.default_rng(0)).meta["components"]["dimensions"]
    assert flat.startswith("2d:") and "no ground" in flat


def test_ground_spec_wants_exactly_one_of_material_and_reflection():
    with pytest.raises(ValueError, match="exactly one"):
        GroundSpec()
    with pytest.raises(ValueError, match="exactly one"):
        GroundSpec(material="concrete", reflection=-1.0)
    assert "ground" not in Scene().model_dump()  # scene digests without a ground stay what they were
    assert "centre_height" not in _point(1.0, 0.5).model_copy(update={"centre_height": None}).model_dump()
