"""Antenna model against closed forms (uniform linear array, patch element)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from xnlos_core.signal.antenna import array_factor, beam_metrics, element_gain, steering_vector
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import dechirp

RADAR = RadarConfig()  # 4 TX × 8 RX → 32 virtual elements at λ/2
N = RADAR.n_tx * RADAR.n_rx
D = 0.5  # element spacing [λ]


def test_virtual_array_is_filled_half_wavelength_ula():
    y = np.sort(RADAR.virtual_positions)
    assert len(y) == N == 32
    np.testing.assert_allclose(np.diff(y), D * RADAR.wavelength, rtol=1e-12)


def test_boxcar_first_null_closed_form():
    null = math.asin(1 / (N * D))  # sin θ = λ/(N d)
    m = beam_metrics(RADAR, "boxcar", step=1e-5)
    assert m["first_null"] == pytest.approx(null, abs=2e-5)
    assert array_factor(RADAR, null) < 1e-20
    assert m["peak_sidelobe_db"] == pytest.approx(-13.26, abs=0.1)  # uniform-array first sidelobe


def test_boxcar_3db_beamwidth_closed_form():
    m = beam_metrics(RADAR, "boxcar")
    assert m["beamwidth_3db"] == pytest.approx(0.886 / (N * D), rel=0.02)


def test_default_beam_is_about_four_degrees():
    m = beam_metrics(RADAR)  # Taylor-windowed, as the RA map uses
    assert 3.6 < m["beamwidth_3db_deg"] < 4.5
    assert m["peak_sidelobe_db"] < -25
    assert m["first_null"] > math.asin(1 / (N * D))  # tapering widens the main lobe


def test_element_pattern():
    th = np.linspace(-np.pi, np.pi, 721)
    g = element_gain(RADAR, th)
    np.testing.assert_allclose(g, g[::-1], rtol=1e-12, atol=0)  # symmetric
    assert np.all(g[np.abs(th) >= np.pi / 2] == 0)  # zero beyond ±90°
    assert element_gain(RADAR, 0.0) == pytest.approx(10 ** (RADAR.element_gain_dbi / 10))
    q = RADAR.element_pattern_exponent
    assert element_gain(RADAR, 0.7) / element_gain(RADAR, 0.0) == pytest.approx(math.cos(0.7) ** q)
    assert np.all(np.isfinite(element_gain(RadarConfig(element_pattern_exponent=1.5), th)))


def test_steering_vector_shape_and_convention():
    th = np.radians([-30.0, 0.0, 12.5])
    a = steering_vector(RADAR, th)
    assert a.shape == (N, 3) and a.dtype == np.complex128
    np.testing.assert_allclose(np.abs(a), 1.0)
    # same phase convention as the synthetic cube: a path from θ has per-channel phase a_k(θ)
    cube = dechirp(RADAR, [20.0], [th[2]], [1.0])
    ratio = cube[5] / cube[5, 0]
    np.testing.assert_allclose(ratio, a[:, 2] / a[0, 2], atol=1e-9)


@pytest.mark.parametrize("window", ["boxcar", "taylor", "hann"])
def test_array_factor_normalised_at_steering_angle(window):
    assert array_factor(RADAR, 0.3, steer_to=0.3, window=window) == pytest.approx(1.0, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(steer=st.floats(-RADAR.field_of_view, RADAR.field_of_view),
       window=st.sampled_from(["boxcar", "taylor"]))
def test_steering_peaks_array_factor_at_steered_angle(steer, window):
    step = 1e-3
    grid = np.arange(-RADAR.field_of_view - 0.05, RADAR.field_of_view + 0.05, step)
    af = array_factor(RADAR, grid, steer_to=steer, window=window)
    assert abs(grid[np.argmax(af)] - steer) <= step
    assert af.max() <= 1.0 + 1e-12
