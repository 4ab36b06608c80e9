"""Propagation against closed forms and an independent P.676 implementation; numerical extremes."""
import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sims.atmosphere import attenuation_db, specific_attenuation
from sims.propagation import free_space_path_loss_db, ra_snr_db, received_power
from xnlos_core.errors import InputError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.chain import dechirp, sample_times

RADAR = RadarConfig()


def test_fspl_closed_form_and_the_77_vs_10_ghz_gap():
    assert free_space_path_loss_db(10e9, 1000.0) == pytest.approx(
        20 * math.log10(4 * math.pi * 1000.0 * 10e9 / SPEED_OF_LIGHT), abs=1e-12)
    for d in (10.0, 100.0, 1000.0):
        gap = free_space_path_loss_db(77e9, d) - free_space_path_loss_db(10e9, d)
        assert gap == pytest.approx(20 * math.log10(7.7), abs=1e-12)
    with pytest.raises(InputError, match="> 0"):
        free_space_path_loss_db(10e9, 0.0)


# ITU-R P.676-12 Annex 1 computed independently with ITU-Rpy 0.4.0 (itur.models.itu676
# gamma0_exact / gammaw_exact, dry pressure 1013.25 − e hPa, 288.15 K, 7.5 g/m³).
ITUR = {1e9: (0.005310287930885314, 5.0485836273565244e-05),
        10e9: (0.008064582959602093, 0.005925341970066755),
        60e9: (14.502093274175401, 0.15359070013487197),
        77e9: (0.09560605820614237, 0.24849832792931908),
        300e9: (0.02525544659027808, 5.177867962391051)}


@pytest.mark.parametrize("f", sorted(ITUR))
def test_gaseous_attenuation_matches_itu_rpy(f):
    g_o, g_w = specific_attenuation(f)
    assert g_o == pytest.approx(ITUR[f][0], rel=1e-9)
    assert g_w == pytest.approx(ITUR[f][1], rel=1e-9)


def test_gaseous_loss_is_negligible_at_10ghz_and_small_at_77ghz_over_radar_ranges():
    assert attenuation_db(10e9, 200.0) < 0.005  # 100 m round trip
    assert 0.05 < attenuation_db(77e9, 200.0) < 0.1
    dry = specific_attenuation(77e9, water_density=0.0)
    assert dry[1] == 0.0 and dry[0] > 0


@pytest.mark.parametrize("kw, match", [({"f_hz": 0.5e9}, "1–1000 GHz"), ({"f_hz": 2e12}, "1–1000 GHz"),
                                       ({"f_hz": 10e9, "temperature_k": 10.0}, "temperature_k")])
def test_atmosphere_refuses_to_extrapolate(kw, match):
    with pytest.raises(InputError, match=match):
        specific_attenuation(**kw)


def test_radar_equation_closed_form():
    r, sigma = 37.0, 4.0
    g = 10 ** (RADAR.element_gain_dbi / 10)
    expect = (RADAR.transmit_power * g * g * RADAR.wavelength**2 * sigma * 0.6**4
              / ((4 * math.pi) ** 3 * r**4 * 10 ** (RADAR.system_loss_db / 10)))
    assert received_power(RADAR, r, 0.0, sigma, 0.6) == pytest.approx(expect, rel=1e-12)
    # an extra 3 dB of atmosphere halves it; the SNR is power × G_p / kTB·NF
    assert received_power(RADAR, r, 0.0, sigma, 0.6, atmosphere_loss_db=3.0) == pytest.approx(
        expect * 10 ** -0.3, rel=1e-12)
    assert ra_snr_db(RADAR, RADAR.noise_power) == pytest.approx(10 * math.log10(512 * 32 / (1.5 * 1.2)), abs=0.5)


@settings(max_examples=60, deadline=None)
@given(r=st.floats(0.5, 2000.0), log_sigma=st.floats(-10.0, 10.0), theta=st.floats(-1.5, 1.5),
       f32=st.booleans())
def test_radar_equation_extremes(r, log_sigma, theta, f32):
    """0.5 m–2 km and σ across 200 dB, float32 or float64 inputs: finite, ≥ 0, exact r⁻⁴ law."""
    dt = np.float32 if f32 else np.float64
    rr, sig = np.array([r, 2 * r], dt), np.array([10**log_sigma] * 2, dt)
    p = received_power(RADAR, rr, np.array([theta] * 2, dt), sig)
    assert np.all(np.isfinite(p)) and np.all(p >= 0) and p.dtype == np.float64
    if p[0] > 0:
        assert p[0] / p[1] == pytest.approx(16.0, rel=1e-5 if f32 else 1e-12)


def _reference_cycles(radar, L: float) -> list[Decimal]:
    """Beat-signal phase in cycles per sample with 40-digit decimals (independent of numpy)."""
    getcontext().prec = 40
    c, f_c = Decimal(SPEED_OF_LIGHT), Decimal(radar.carrier_frequency)
    S = Decimal(radar.bandwidth) / Decimal(radar.chirp_duration)
    tau = Decimal(L) / c
    fs = Decimal(radar.n_samples) / Decimal(radar.chirp_duration)
    return [S * tau * (Decimal(n) / fs) + f_c * tau - S * tau * tau / 2 for n in range(radar.n_samples)]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_phase_is_exact_at_two_kilometres(dtype):
    """A 2 km target (4 km round trip, 1.3e5 carrier cycles): float64 phase reduction keeps every
    sample's phase within 1e-6 rad of a 40-digit reference, also for float32 path inputs."""
    radar = RadarConfig(bandwidth=75e6, n_samples=2048, max_range=2500.0, n_tx=1, n_rx=1)
    L = float(np.asarray(4000.123, dtype=dtype))  # the float32 case: its rounded value is the truth
    cube = dechirp(radar, np.array([L], dtype=dtype), np.array([0.0], dtype=dtype), np.array([1.0], dtype=dtype))
    assert cube.dtype == np.complex128
    ref = np.array([float(x % 1) for x in _reference_cycles(radar, L)])
    err = np.angle(cube[:, 0] * np.exp(-2j * np.pi * ref))
    assert np.abs(err).max() < 1e-6
    assert len(sample_times(radar)) == radar.n_samples


@settings(max_examples=25, deadline=None)
@given(log_amp=st.floats(-10.0, 0.0), r=st.floats(0.5, 90.0))
def test_ra_map_is_linear_across_200_db(log_amp, r):
    """Amplitudes from 1e-10 to 1 √W (200 dB in power): the RA peak scales exactly, stays finite."""
    radar = RadarConfig(n_samples=512, max_range=90.0, n_azimuth_bins=31, n_tx=1, n_rx=8)
    from xnlos_core.signal.chain import ra_map_from_cube

    a = 10.0**log_amp
    m1 = ra_map_from_cube(dechirp(radar, [2 * r], [0.1], [a]), radar).data
    m0 = ra_map_from_cube(dechirp(radar, [2 * r], [0.1], [1.0]), radar).data
    assert np.all(np.isfinite(m1))
    k = np.unravel_index(np.argmax(np.abs(m0)), m0.shape)
    assert abs(m1[k]) == pytest.approx(a * abs(m0[k]), rel=1e-5)


def test_detectability_threshold_is_albersheim():
    from sims.propagation import DETECTABLE_SNR_DB, detectable_snr_db

    # Textbook values (Richards, Fundamentals of Radar Signal Processing, Albersheim's equation):
    # pd 0.9, pfa 1e-6 → 13.1 dB; pd 0.5, pfa 1e-6 → 11.25 dB.
    a = math.log(0.62 / 1e-6)
    b = math.log(0.9 / 0.1)
    assert detectable_snr_db(0.9, 1e-6) == pytest.approx(10 * math.log10(a + 0.12 * a * b + 1.7 * b), abs=1e-9)
    assert detectable_snr_db(0.9, 1e-6) == pytest.approx(13.1, abs=0.1)
    assert detectable_snr_db(0.5, 1e-6) == pytest.approx(10 * math.log10(a), abs=1e-9)
    assert DETECTABLE_SNR_DB == pytest.approx(10 * math.log10(math.log(0.62e5)), abs=0.05)
    assert detectable_snr_db(0.9, 1e-5) > detectable_snr_db(0.5, 1e-5) > detectable_snr_db(0.5, 1e-4)
    with pytest.raises(InputError, match="pfa"):
        detectable_snr_db(0.5, 0.1)
    with pytest.raises(InputError, match="pd"):
        detectable_snr_db(0.99, 1e-5)
