"""Raw ADC layouts → RA maps through the shared signal chain (issue: raw data path)."""
from __future__ import annotations

import numpy as np
import pytest

from hardware.adc import AdcLayout, adc_cube_to_ra_map, canonical_cube, encode_adc_cube
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import add_noise, dechirp, ra_map_from_cube

RADAR = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)


def _cube(seed=0):
    rng = np.random.default_rng(seed)
    c = dechirp(RADAR, [24.0, 41.0], [0.2, -0.4], [1e-6, 3e-7 * np.exp(1j)])
    return add_noise(c, RADAR, rng)


@pytest.mark.parametrize("axes", [("sample", "chirp", "channel"), ("chirp", "channel", "sample"),
                                  ("channel", "sample"), ("sample", "channel")])
@pytest.mark.parametrize("order", ["tx_major", "rx_major"])
def test_complex_layouts_round_trip_to_the_same_map(axes, order):
    cube = _cube()
    layout = AdcLayout(axes=axes, channel_order=order, scale=1e-9)
    raw, clipped = encode_adc_cube(cube, layout, RADAR, n_chirps=3, dtype=np.complex128)
    assert clipped == 0
    np.testing.assert_allclose(canonical_cube(raw, layout, RADAR), cube, rtol=1e-12, atol=0)
    ref = ra_map_from_cube(cube, RADAR)
    np.testing.assert_allclose(adc_cube_to_ra_map(raw, layout, RADAR).data, ref.data, rtol=1e-5, atol=1e-12)


def test_rx_major_is_a_real_reordering():
    cube = _cube()
    raw, _ = encode_adc_cube(cube, AdcLayout(channel_order="rx_major"), RADAR, dtype=np.complex128)
    # channel (i_tx=1, j_rx=2): tx-major index 1·8+2 = 10, rx-major index 2·4+1 = 9
    np.testing.assert_array_equal(raw[:, 0, 9], cube[:, 10])


def test_int16_iq_quantisation_error_is_below_one_count():
    cube = _cube()
    scale = np.abs(cube).max() / 20000  # full scale ≈ 20000 counts
    layout = AdcLayout(sample_format="iq", scale=scale)
    raw, clipped = encode_adc_cube(cube, layout, RADAR, n_chirps=2)
    assert raw.dtype == np.int16 and raw.shape == (RADAR.n_samples, 2, RADAR.n_channels, 2) and clipped == 0
    err = np.abs(canonical_cube(raw, layout, RADAR) - cube) / scale
    assert err.max() <= np.sqrt(0.5) + 1e-9  # rounding I and Q: ≤ ½ count each


def test_int16_clipping_is_counted():
    cube = _cube()
    layout = AdcLayout(sample_format="iq", scale=np.abs(cube).max() / 40000)
    _, clipped = encode_adc_cube(cube, layout, RADAR)
    assert clipped > 0


def test_chirps_integrate_coherently_and_dc_removal():
    cube = _cube()
    raw, _ = encode_adc_cube(cube, AdcLayout(), RADAR, n_chirps=4, dtype=np.complex128)
    raw = raw + 5e-6  # a DC offset on every sample
    out = canonical_cube(raw, AdcLayout(remove_dc=True), RADAR)
    np.testing.assert_allclose(out, cube - cube.mean(axis=0), atol=1e-15)


@pytest.mark.parametrize("raw, layout, match", [
    (np.zeros((128, 32)), AdcLayout(axes=("sample", "channel")), "complex"),
    (np.zeros((128, 32), np.int16), AdcLayout(axes=("sample", "channel"), sample_format="iq"), "dimensions"),
    (np.zeros((128, 32, 3), np.int16), AdcLayout(axes=("sample", "channel"), sample_format="iq"), "trailing axis"),
    (np.zeros((100, 32), complex), AdcLayout(axes=("sample", "channel")), "'sample' axis has 100"),
    (np.zeros((128, 1, 8), complex), AdcLayout(), "'channel' axis has 8"),
    (np.full((128, 1, 32), np.nan, complex), AdcLayout(), "NaN"),
])
def test_bad_cubes_are_named(raw, layout, match):
    with pytest.raises(InputError, match=match):
        adc_cube_to_ra_map(raw, layout, RADAR)


def test_layout_rejects_unknown_axes():
    with pytest.raises(ValueError, match="permutation"):
        AdcLayout(axes=("sample", "doppler", "channel"))
