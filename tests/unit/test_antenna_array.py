"""Planar array: 3-D element pattern, TX/RX steering, non-MIMO option and mutual coupling."""
import math

import numpy as np
import pytest

from xnlos_core.signal.antenna import (beam_pattern, channel_positions, column_factor, coupling_matrix,
                                element_directivity, element_gain, radiation_efficiency, steering_vector,
                                transmit_gain)
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import dechirp, ra_map_from_cube

RADAR = RadarConfig()
SMALL = dict(n_samples=128, max_range=30.0, n_azimuth_bins=61)


def test_isotropic_half_space_directivity_is_two():
    r = RadarConfig(element_pattern_exponent=0.0, element_pattern_exponent_el=0.0)
    assert element_directivity(r) == pytest.approx(2.0, rel=2e-3)  # 3.01 dBi


def test_single_patch_keeps_its_stated_gain_and_a_column_adds_directivity():
    assert element_gain(RADAR, 0.0) == pytest.approx(10 ** 0.6)
    col = RadarConfig(n_elevation=4)
    gain = float(element_gain(col, 0.0))
    assert gain == pytest.approx(radiation_efficiency(RADAR) * element_directivity(col), rel=1e-12)
    assert 10 ** 0.6 < gain < 4 * 10 ** 0.6  # directive patches: less than n·G0


def test_column_factor_nulls_at_predicted_elevations():
    col = RadarConfig(n_elevation=4, elevation_spacing=0.5)
    null = math.asin(1 / (4 * 0.5))  # sin ε = λ/(n d) = 30°
    assert column_factor(col, null) < 1e-25
    assert column_factor(col, 0.0) == 1.0
    # azimuth unaffected by the column; elevation cut shaped by it
    assert element_gain(col, 0.3, 0.0) / element_gain(col, 0.0, 0.0) == pytest.approx(math.cos(0.3) ** 1.2)


def test_elevated_path_is_steered_with_its_elevation():
    r = RadarConfig(tx_elevation_offset=2.0)
    pos = channel_positions(r)
    a = steering_vector(r, 0.2, 0.1)[:, 0]
    ref = np.exp(-2j * np.pi * (pos[:, 0] * math.sin(0.2) * math.cos(0.1) + pos[:, 1] * math.sin(0.1)) / r.wavelength)
    np.testing.assert_allclose(a, ref, rtol=1e-12)
    np.testing.assert_allclose(steering_vector(r, 0.2)[:, 0],
                               np.exp(-2j * np.pi * pos[:, 0] * math.sin(0.2) / r.wavelength), rtol=1e-12)


@pytest.mark.parametrize("which, n", [("tx", 4), ("rx", 8)])
def test_steered_beam_peaks_at_its_steering_angle(which, n):
    r = RadarConfig(tx_spacing=0.5)  # phased TX at λ/2 (no grating lobes)
    th = np.radians(np.linspace(-60, 60, 2401))
    b = beam_pattern(r, which, th, steer=math.radians(20))
    assert math.degrees(th[np.argmax(b / element_gain(r, th))]) == pytest.approx(20, abs=0.06)
    assert beam_pattern(r, which, math.radians(20), steer=math.radians(20)) == pytest.approx(
        n * element_gain(r, math.radians(20)))


def test_non_mimo_records_rx_only_and_transmits_a_steered_beam():
    r = RadarConfig(mimo=False, tx_spacing=0.5, tx_steering=math.radians(10), **SMALL)
    assert r.n_channels == 8 and len(r.virtual_positions) == 8
    assert transmit_gain(r, math.radians(10)) == pytest.approx(16.0)  # n_tx²
    assert transmit_gain(RadarConfig(), 0.3) == 1.0  # MIMO: one TX at a time
    cube = dechirp(r, [40.0], [0.2], [1.0])
    assert cube.shape == (r.n_samples, 8)
    assert ra_map_from_cube(cube, r).shape == (r.n_range_bins, r.n_azimuth_bins)


def test_modelled_coupling_is_toeplitz_and_compensation_undoes_it():
    r = RadarConfig(coupling_db=-15.0, coupling_phase=0.4, **SMALL)
    c = coupling_matrix(r)
    assert c.shape == (32, 32)
    rx = c[:8, :8]
    assert abs(rx[0, 1]) == pytest.approx(10 ** (-15 / 20)) and np.angle(rx[0, 1]) == pytest.approx(0.4)
    assert abs(rx[0, 2]) == pytest.approx(10 ** (-30 / 20))
    np.testing.assert_allclose(np.diag(c), 1.0)
    plain = RadarConfig(**SMALL)
    paths = ([30.0, 47.0], [0.1, -0.5], [1.0, 0.3j])
    ref = ra_map_from_cube(dechirp(plain, *paths), plain).data
    coupled = dechirp(r, *paths)
    assert np.abs(ra_map_from_cube(coupled, r).data - ref).max() > 1e-3 * np.abs(ref).max()
    comp = r.model_copy(update={"coupling_compensation": True})
    np.testing.assert_allclose(ra_map_from_cube(coupled, comp).data, ref, atol=1e-5 * np.abs(ref).max())


@pytest.mark.parametrize("suffix", [".npy", ".csv", ".npz"])
def test_measured_coupling_file(tmp_path, suffix):
    m = np.eye(32, dtype=complex) + 0.05j * np.eye(32, k=1)
    f = tmp_path / f"c{suffix}"
    if suffix == ".npy":
        np.save(f, m)
    elif suffix == ".npz":
        np.savez(f, coupling=m)
    else:
        np.savetxt(f, m, delimiter=",")
    np.testing.assert_allclose(coupling_matrix(RadarConfig(coupling_file=str(f))), m)


def test_bad_coupling_inputs(tmp_path):
    f = tmp_path / "c.npy"
    np.save(f, np.eye(8))
    with pytest.raises(InputError, match=r"\(32, 32\)"):
        coupling_matrix(RadarConfig(coupling_file=str(f)))
    with pytest.raises(InputError, match="cannot read"):
        coupling_matrix(RadarConfig(coupling_file=str(tmp_path / "missing.npy")))
    with pytest.raises(ValueError, match="exclusive"):
        RadarConfig(coupling_db=-20.0, coupling_file=str(f))
