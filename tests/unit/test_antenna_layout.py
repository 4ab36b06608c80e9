"""Any antenna layout: element positions, the virtual array, its array factor, refusals."""
import math

import numpy as np
import pytest

from sims.image import ImageForwardModel, received_power
from xnlos_core.signal.antenna import (aperture_taper, array_factor, azimuth_weights, channel_positions,
                                coupling_matrix, has_elevation_aperture, steering_vector, virtual_layout)
from xnlos_core.signal.elevation import azimuth_elevation_spectrum, elevation_spectrum
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig, load_radar
from xnlos_core.scene import ObjectSpec, Scene
from xnlos_core.signal.chain import beamform, dechirp, ra_map_from_cube, range_fft

SMALL = dict(n_samples=128, max_range=30.0, n_azimuth_bins=61)
# 3 TX × 4 RX board, middle transmitter raised by λ/2 (as on TI's AWR1843): [[y, z]] in wavelengths
TX_RAISED = [[0.0, 0.0], [1.0, 0.5], [2.0, 0.0]]
RX_LINE = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.5, 0.0]]
RAISED = RadarConfig(tx_positions=TX_RAISED, rx_positions=RX_LINE, **SMALL)
# p = tx_i + rx_j, tx-major, written out by hand
VIRTUAL = np.array([[0.0, 0], [0.5, 0], [1.0, 0], [1.5, 0],
                    [1.0, .5], [1.5, .5], [2.0, .5], [2.5, .5],
                    [2.0, 0], [2.5, 0], [3.0, 0], [3.5, 0]])


def test_raised_layout_derives_counts_and_its_virtual_array():
    assert (RAISED.n_tx, RAISED.n_rx, RAISED.n_channels, RAISED.rx_spacing) == (3, 4, 12, 0.5)
    np.testing.assert_array_equal(virtual_layout(RAISED), VIRTUAL)
    lam = RAISED.wavelength
    pos = channel_positions(RAISED)
    np.testing.assert_allclose(pos[:, 0], (VIRTUAL[:, 0] - 1.75) * lam, atol=1e-15)
    np.testing.assert_allclose(pos[:, 1], VIRTUAL[:, 1] * lam, atol=1e-15)
    np.testing.assert_allclose(RAISED.virtual_positions, pos[:, 0], atol=1e-15)
    assert has_elevation_aperture(RAISED) and not has_elevation_aperture(RadarConfig(**SMALL))


@pytest.mark.parametrize("elevation", [0.0, 0.25, -0.6])
def test_raised_layout_gives_the_array_factor_of_its_virtual_array(elevation):
    # closed form |Σ_k exp(j (k − k₀)·p_k)|² / K², k = 2π/λ (sin θ cos ε, sin ε) in the y–z plane
    theta = np.linspace(-1.2, 1.2, 801)
    steer = 0.3
    ky = 2 * np.pi * np.sin(theta) * np.cos(elevation) - 2 * np.pi * np.sin(steer)
    kz = np.full_like(theta, 2 * np.pi * np.sin(elevation))
    closed = np.abs(np.exp(1j * (np.outer(ky, VIRTUAL[:, 0]) + np.outer(kz, VIRTUAL[:, 1]))).sum(axis=1)) ** 2 / 144
    af = array_factor(RAISED, theta, steer, "boxcar", elevation=elevation)
    np.testing.assert_allclose(af, closed, rtol=1e-10, atol=1e-12)
    assert af.max() == pytest.approx(1.0 if elevation == 0.0 else closed.max())


def test_raised_transmitter_dephases_elevated_arrivals_unlike_a_flat_board():
    flat = RadarConfig(tx_positions=[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], rx_positions=RX_LINE, **SMALL)
    th = math.asin(math.sin(0.3) / math.cos(0.4))  # same y phase slope as (0.3, 0) when ε = 0.4
    assert float(array_factor(flat, th, 0.3, elevation=0.4)) == pytest.approx(1.0, abs=1e-12)
    assert float(array_factor(RAISED, th, 0.3, elevation=0.4)) < 0.95


def test_explicit_flat_layout_equals_the_implicit_default_bit_for_bit():
    implicit = RadarConfig(n_tx=3, n_rx=4, coupling_db=-20.0, **SMALL)
    explicit = RadarConfig(tx_positions=[[0, 0], [2, 0], [4, 0]], rx_positions=RX_LINE, coupling_db=-20.0, **SMALL)
    th, el = np.linspace(-1.0, 1.0, 41), np.linspace(-0.5, 0.5, 41)
    assert np.array_equal(steering_vector(explicit, th, el), steering_vector(implicit, th, el))
    assert np.array_equal(azimuth_weights(explicit), azimuth_weights(implicit))
    assert np.array_equal(coupling_matrix(explicit), coupling_matrix(implicit))
    cube = dechirp(implicit, [21.3], [0.2], [1.0])
    assert np.array_equal(dechirp(explicit, [21.3], [0.2], [1.0]), cube)
    assert np.array_equal(ra_map_from_cube(cube, explicit).data, ra_map_from_cube(cube, implicit).data)


def test_unset_positions_leave_the_serialised_config_alone_and_set_ones_round_trip():
    assert "tx_positions" not in RadarConfig().model_dump() and "rx_positions" not in RadarConfig().model_dump()
    back = RadarConfig.model_validate_json(RAISED.model_dump_json())
    assert back == RAISED and hash(back) == hash(RAISED)
    assert back.model_dump()["tx_positions"] == tuple(tuple(p) for p in TX_RAISED)


def _load(**fields):
    return load_radar({**SMALL, **fields}, "radar.toml", ".")


@pytest.mark.parametrize("fields, names", [
    (dict(tx_positions=[[0, 0], [1, 0.5], [0, 0]]), ["tx_positions", "elements 0 and 2 overlap"]),
    (dict(rx_positions=[[0, 0], [0.5, 0], [0.5, 0]]), ["rx_positions", "elements 1 and 2 overlap"]),
])
def test_overlapping_physical_elements_are_refused(fields, names):
    with pytest.raises(ConfigError) as err:
        _load(**fields)
    assert all(n in str(err.value) for n in names)


def test_coinciding_virtual_elements_are_allowed_and_add():
    r = RadarConfig(tx_positions=[[0, 0], [0.5, 0]], rx_positions=RX_LINE, **SMALL)
    assert np.ptp(channel_positions(r)[:, 0]) == pytest.approx(2 * r.wavelength)  # 8 channels on 5 places
    w = azimuth_weights(r)
    y = virtual_layout(r)[:, 0]
    for value in np.unique(y):  # coinciding channels weigh the same
        assert np.ptp(w[y == value]) == 0
    assert float(array_factor(r, 0.0, 0.0, "taylor")) == pytest.approx(1.0)


@pytest.mark.parametrize("fields, names", [
    (dict(n_tx=2, tx_positions=TX_RAISED), ["n_tx=2", "tx_positions"]),
    (dict(n_rx=8, rx_positions=RX_LINE), ["n_rx=8", "rx_positions"]),
    (dict(tx_spacing=2.0, tx_positions=TX_RAISED), ["tx_spacing", "tx_positions"]),
    (dict(tx_elevation_offset=1.0, tx_positions=TX_RAISED), ["tx_elevation_offset", "tx_positions"]),
    (dict(rx_spacing=1.0, rx_positions=RX_LINE), ["rx_spacing", "rx_positions"]),
    (dict(tx_positions=[[0.0, float("inf")]]), ["tx_positions"]),
    (dict(rx_positions=[]), ["rx_positions"]),
])
def test_contradictions_and_bad_positions_are_refused_naming_the_fields(fields, names):
    with pytest.raises(ConfigError) as err:
        _load(**fields)
    assert all(n in str(err.value) for n in names)


def test_agreeing_counts_and_preset_defaults_are_accepted():
    r = _load(n_tx=3, n_rx=4, rx_spacing=0.5, tx_elevation_offset=0.0, tx_positions=TX_RAISED, rx_positions=RX_LINE)
    assert r == RAISED
    with pytest.raises(ConfigError, match="n_tx=5 contradicts tx_positions"):
        RAISED.model_copy(update={"n_tx": 5}).tx_layout  # unvalidated copies are still caught


def test_taper_follows_aperture_position_not_channel_index():
    w = azimuth_weights(RAISED)
    y = virtual_layout(RAISED)[:, 0]
    order = np.argsort(y, kind="stable")
    assert np.all(np.diff(w[order][: len(w) // 2]) >= 0)  # rises towards the centre of the aperture
    np.testing.assert_allclose(w, aperture_taper("taylor", 3.5 - y), rtol=1e-12)  # symmetric about it
    shuffled = np.array([1.0, 0.0, 3.0, 2.0])
    np.testing.assert_array_equal(aperture_taper("hann", shuffled)[[1, 0, 3, 2]], aperture_taper("hann", np.arange(4.0)))


@pytest.mark.parametrize("j", [18, 30, 44])
def test_point_target_simulated_with_the_raised_layout_beamforms_to_its_azimuth(j):
    radar = RAISED
    r, th = 80 * radar.range_resolution, radar.azimuth_axis[j]
    point = ObjectSpec(name="p", shape="point", center=(r * np.cos(th), r * np.sin(th)), rcs=5.0)
    f = ImageForwardModel({"noise": False, "random_phase": False}).simulate(
        Scene(objects=[point]), radar, np.random.default_rng(0))
    assert f.ra_map.shape == (radar.n_range_bins, radar.n_azimuth_bins)
    assert np.unravel_index(np.argmax(f.ra_map.power), f.ra_map.shape) == (80, j)
    assert f.ra_map.power[80, j] == pytest.approx(received_power(radar, r, th, 5.0), rel=1e-4)


def test_elevation_spectrum_peaks_at_the_arrival_elevation_and_matches_the_ra_row_at_zero():
    radar = RAISED
    k, th0, el0 = 60, 0.35, 0.3
    cube = dechirp(radar, [2 * k * radar.range_resolution], [th0], [2.0], elevation=[el0])
    profiles = range_fft(cube, radar)
    el = np.linspace(-1.2, 1.2, 2401)
    spec = np.abs(elevation_spectrum(profiles, radar, k, th0, el))
    assert el[np.argmax(spec)] == pytest.approx(el0, abs=1e-3)
    assert spec.max() == pytest.approx(2.0, rel=1e-6)  # a matched plane wave sums coherently
    full = azimuth_elevation_spectrum(profiles, radar, k, elevation=[0.0, el0])
    assert full.shape == (2, radar.n_azimuth_bins)
    np.testing.assert_allclose(full[0], beamform(profiles, radar)[k], rtol=1e-12, atol=1e-15)


def test_elevation_spectrum_needs_channels_at_two_heights_and_a_valid_bin():
    flat = RadarConfig(**SMALL)
    profiles = np.zeros((flat.n_range_bins, flat.n_channels), complex)
    with pytest.raises(InputError, match="one height"):
        elevation_spectrum(profiles, flat, 3, 0.0)
    with pytest.raises(InputError, match="range_bin"):
        elevation_spectrum(np.zeros((5, RAISED.n_channels)), RAISED, 5, 0.0)
    with pytest.raises(InputError, match="n_channels = 12"):
        elevation_spectrum(np.zeros((5, 4)), RAISED, 1, 0.0)
