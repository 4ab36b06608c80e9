"""Signal chain (Sec. 3.2, Eq. 6) against closed forms."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from xnlos_core.errors import InputError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.chain import (add_noise, adc_to_ra_map, beat_frequency, chirp, dechirp, noise_floor,
                                     processing_gain, ra_map_from_cube, range_fft)

RADAR = RadarConfig()
DR = RADAR.range_resolution


def _single(radar, R, theta, a=1.0):
    return dechirp(radar, [2 * R], [theta], [a])


def _peak(ra):
    return np.unravel_index(np.argmax(ra.power), ra.shape)


def test_chirp_instantaneous_frequency():
    # g(t) = exp(j(2π f_c t + π S t²)): phase derivative / 2π = f_c + S t (float64 phases)
    t = np.array([0.0, 10e-6, 50e-6])
    dt = 1e-12
    dphi = np.angle(chirp(RADAR, t + dt) * np.conj(chirp(RADAR, t)))
    f_inst = dphi / (2 * np.pi * dt)
    np.testing.assert_allclose(f_inst, RADAR.carrier_frequency + RADAR.chirp_slope * t, rtol=1e-3)


def test_dechirp_equals_conjugate_product_of_chirps():
    # one channel at boresight: s[n] = g(t_n) · g*(t_n − τ) (Eq. 6 before the LPF, carrier removed)
    R = 17.3
    tau = 2 * R / SPEED_OF_LIGHT
    t = np.arange(RADAR.n_samples) / RADAR.sample_rate
    ref = chirp(RADAR, t) * np.conj(chirp(RADAR, t - tau))
    np.testing.assert_allclose(_single(RADAR, R, 0.0)[:, 0], ref, atol=1e-6)


@pytest.mark.parametrize("R", [0.5, 12.34, 50.0, 99.9])
def test_beat_frequency_closed_form(R):
    fb = beat_frequency(RADAR, R)
    assert fb == pytest.approx(2 * R * RADAR.bandwidth / (SPEED_OF_LIGHT * RADAR.chirp_duration), rel=1e-12)
    assert fb * RADAR.chirp_duration == pytest.approx(R / DR, rel=1e-12)  # bin index = R/ΔR


@pytest.mark.parametrize("R", [3.1, 20.07, 47.77, 88.8])
def test_fft_peak_at_beat_frequency(R):
    # Hann-windowed FFT + log-parabolic interpolation: bias ≤ 0.02 bin; tolerance 0.03 bin.
    s = _single(RADAR, R, 0.0)[:, 0]
    X = np.abs(np.fft.fft(s * np.hanning(RADAR.n_samples)))
    k = int(np.argmax(X))
    a, b, c = np.log(X[k - 1:k + 2])
    f_hat = (k + 0.5 * (a - c) / (a - 2 * b + c)) / RADAR.chirp_duration  # bin spacing 1/T
    assert abs(f_hat - beat_frequency(RADAR, R)) * RADAR.chirp_duration < 0.03


def test_range_resolution_is_rayleigh_width():
    assert DR == pytest.approx(SPEED_OF_LIGHT / (2 * RADAR.bandwidth), rel=1e-12)
    np.testing.assert_allclose(np.diff(RADAR.range_axis), DR)
    # unwindowed range response of a target (16× zero padding): first null at ±c/2B
    s = _single(RADAR, 40 * DR, 0.0)[:, 0]
    pad = 16
    X = np.abs(np.fft.fft(s, pad * RADAR.n_samples))
    k = int(np.argmax(X))
    assert k == 40 * pad
    first_null = k + int(np.argmax(np.diff(X[k:k + 2 * pad]) > 0))
    assert (first_null - k) / pad * DR == pytest.approx(DR, rel=1.5 / pad)


@pytest.mark.parametrize("R, theta_deg", [(10.0, 0.0), (37.3, 20.2), (80.05, -45.3), (55.5, 50.2),
                                          (5.2, -59.8)])
def test_point_target_lands_in_its_ra_cell(R, theta_deg):
    ra = ra_map_from_cube(_single(RADAR, R, np.radians(theta_deg)), RADAR)
    i, j = _peak(ra)
    assert i == int(np.round(R / DR))
    assert j == int(np.argmin(np.abs(RADAR.azimuth_axis - np.radians(theta_deg))))


def test_grid_centred_target_peak_equals_amplitude():
    # documented scaling: |κ| at a bin-centred, grid-angle target = path amplitude [√W]
    R, th = 123 * DR, RADAR.azimuth_axis[97]
    ra = ra_map_from_cube(_single(RADAR, R, th, 3e-6), RADAR)
    assert _peak(ra) == (123, 97)
    assert abs(ra.data[123, 97]) == pytest.approx(3e-6, rel=1e-5)


def test_processing_gain_boxcar_is_nm():
    radar = RadarConfig(range_window="boxcar", azimuth_window="boxcar")
    assert processing_gain(radar) == pytest.approx(radar.n_samples * radar.n_tx * radar.n_rx, rel=1e-12)


def test_noise_only_map_power_matches_expectation():
    # E|κ|² = σ²/G_p per cell; 4 maps × ~10⁴ independent cells → ±1 %; tolerance 4 %
    zero = np.zeros((RADAR.n_samples, RADAR.n_tx * RADAR.n_rx), complex)
    rng = np.random.default_rng(1)
    p = np.mean([ra_map_from_cube(add_noise(zero, RADAR, rng), RADAR).power.mean() for _ in range(4)])
    assert p == pytest.approx(noise_floor(RADAR), rel=0.04)


def test_noise_power_per_sample():
    zero = np.zeros((4096, 32), complex)
    n = add_noise(zero, RADAR, np.random.default_rng(2))
    assert np.mean(np.abs(n) ** 2) == pytest.approx(RADAR.noise_power, rel=0.02)
    assert abs(np.mean(n**2)) < 0.02 * RADAR.noise_power  # circular: E[n²] = 0


def test_adc_to_ra_map_validates_input():
    good = np.zeros((RADAR.n_samples, RADAR.n_tx * RADAR.n_rx), complex)
    assert adc_to_ra_map(good, RADAR).shape == (RADAR.n_range_bins, RADAR.n_azimuth_bins)
    with pytest.raises(InputError, match="n_channels"):
        adc_to_ra_map(good[:, :8], RADAR)
    with pytest.raises(InputError, match="n_samples"):
        adc_to_ra_map(good.T, RADAR)
    bad = good.copy()
    bad[3, 4] = np.nan
    with pytest.raises(InputError, match="NaN"):
        adc_to_ra_map(bad, RADAR)
    with pytest.raises(InputError):
        adc_to_ra_map(np.full(good.shape, "x"), RADAR)


def test_dechirp_rejects_mismatched_paths():
    with pytest.raises(InputError):
        dechirp(RADAR, [10.0, 20.0], [0.0], [1.0])


def test_range_fft_shape_and_dtype():
    X = range_fft(np.zeros((RADAR.n_samples, 32), complex), RADAR)
    assert X.shape == (RADAR.n_range_bins, 32)


@settings(max_examples=25, deadline=None)
@given(log_amp=st.floats(-10, 10), R=st.floats(0.5, 2000.0), theta=st.floats(-1.0, 1.0))
def test_linear_in_amplitude_and_unaliased(log_amp, R, theta):
    # amplitudes across 200 dB scale the map linearly; paths past the unambiguous range are
    # removed by the anti-aliasing low-pass instead of folding back to short range.
    a = 10.0**log_amp
    cube = _single(RADAR, R, theta, a)
    if R >= RADAR.max_unambiguous_range:
        assert not np.any(cube)
        return
    ra = ra_map_from_cube(cube, RADAR)
    ref = ra_map_from_cube(_single(RADAR, R, theta, 1.0), RADAR)
    peak = np.abs(ref.data).max()
    np.testing.assert_allclose(np.abs(ra.data) / a, np.abs(ref.data), rtol=1e-4, atol=1e-6 * peak)


def test_averaging_chirps_divides_the_noise_power_explicitly():
    """noise_power with n_chirps = N equals the measured noise of the mean of N single-chirp cubes."""
    one = RADAR.model_copy(update={"n_chirps": 1})
    eight = RADAR.model_copy(update={"n_chirps": 8})
    assert eight.noise_power == pytest.approx(one.noise_power / 8, rel=1e-12)
    zero = np.zeros((1024, 32), complex)
    rng = np.random.default_rng(3)
    mean = np.mean([add_noise(zero, one, rng) for _ in range(8)], axis=0)  # 8 chirps averaged
    assert np.mean(np.abs(mean) ** 2) == pytest.approx(eight.noise_power, rel=0.03)
    # kT·f_s·NF for one chirp, independent of the code under test
    assert one.noise_power == pytest.approx(1.380649e-23 * one.temperature * one.n_samples / one.chirp_duration
                                            * 10 ** (one.noise_figure_db / 10), rel=1e-9)
