"""Raised elements beamformed with their height: a 3 TX × 4 RX board whose middle transmitter sits λ
to the side and λ/2 up (TI xWR1843-style). Described flat, its raised channels pose as an aperture
extension; described by their true (y, z), the map at ε = 0 peaks at the target's azimuth, and with
``azimuth_channels = "row"`` a target off the horizontal plane keeps the flat row's sidelobes."""
from __future__ import annotations

import numpy as np
import pytest

from xnlos_core.radar import RadarConfig
from xnlos_core.signal.antenna import azimuth_row, azimuth_weights, channel_positions
from xnlos_core.signal.chain import dechirp, noise_floor, ra_map_from_cube
from xnlos_core.signal.elevation import elevation_spectrum

WAVE = dict(carrier_frequency=77e9, bandwidth=1e9, n_samples=64, max_range=8.0, n_azimuth_bins=241)
TRUE = RadarConfig(**WAVE, tx_positions=((0.0, 0.0), (1.0, 0.5), (2.0, 0.0)),
                   rx_positions=((0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (1.5, 0.0)))
FLAT = RadarConfig(**WAVE, n_tx=3, n_rx=4)  # the same 12 channels taken as one 12-element row
ROW = TRUE.model_copy(update={"azimuth_channels": "row"})
TARGET = (3.0, np.radians(-2.0))  # range [m], azimuth [rad]


def _row_db(board: RadarConfig, radar: RadarConfig, elevation_deg: float) -> np.ndarray:
    """Power over azimuth [dB re peak] at the target's range bin: the channels ``board`` records,
    beamformed as ``radar`` describes them."""
    cube = dechirp(board, [2 * TARGET[0]], [TARGET[1]], [1.0], elevation=[np.radians(elevation_deg)])
    ra = ra_map_from_cube(cube, radar)
    p = np.abs(ra.data[np.argmin(np.abs(ra.range_axis - TARGET[0]))]) ** 2
    return 10 * np.log10(p / p.max())


def _at(radar: RadarConfig, row: np.ndarray, deg: float) -> float:
    return float(row[np.argmin(np.abs(radar.azimuth_axis - np.radians(deg)))])


def test_the_row_is_the_eight_flat_channels():
    keep = azimuth_row(TRUE)
    assert keep.tolist() == [True] * 4 + [False] * 4 + [True] * 4  # TX 0 and TX 2; TX 1 is raised
    w = azimuth_weights(ROW)
    assert np.all(w[4:8] == 0) and np.all(w[keep] > 0)
    np.testing.assert_array_equal(azimuth_weights(TRUE.model_copy(update={"azimuth_channels": "row",
                                                                         "tx_positions": None,
                                                                         "rx_positions": None,
                                                                         "n_tx": 3, "n_rx": 4})),
                                  azimuth_weights(FLAT))  # a flat array: every channel is the row
    # the map's noise floor follows the channels it uses: 8 of 12 → 1.76 dB higher floor at the same taper
    assert noise_floor(ROW) > noise_floor(TRUE)
    assert "azimuth_channels" not in TRUE.model_dump() and ROW.model_dump()["azimuth_channels"] == "row"


@pytest.mark.parametrize("elevation_deg", [0.0, 20.0])
def test_true_positions_put_the_peak_at_the_target(elevation_deg):
    grid = np.degrees(TRUE.azimuth_axis[1] - TRUE.azimuth_axis[0])
    for radar in (TRUE, ROW):
        row = _row_db(TRUE, radar, elevation_deg)
        assert abs(np.degrees(TRUE.azimuth_axis[np.argmax(row)]) + 2.0) <= grid / 2 + 1e-9
    # taken flat, the raised channels shift the peak a grid step and more towards boresight
    flat = _row_db(TRUE, FLAT, elevation_deg)
    assert abs(np.degrees(FLAT.azimuth_axis[np.argmax(flat)]) + 2.0) >= 1.0 - 1e-9


def test_the_minus_50_degree_sidelobe_of_a_raised_target():
    """A target at −2° and 20–30° elevation: taken flat, a sidelobe at −50° reaches −11…−16 dB (a CFAR
    detection); with the true heights it stays below −19 dB, with the row below −39 dB."""
    for el, flat_db in ((20.0, -15.0), (30.0, -11.0)):
        flat = _at(FLAT, _row_db(TRUE, FLAT, el), -50.0)
        true = _at(TRUE, _row_db(TRUE, TRUE, el), -50.0)
        row = _at(ROW, _row_db(TRUE, ROW, el), -50.0)
        assert flat > flat_db - 1.0 and true < -19.0 and row < -39.0, (el, flat, true, row)
        assert true < flat - 4.0 and row < true - 15.0
        far = np.abs(TRUE.azimuth_axis - TARGET[1]) > np.radians(25)
        assert _row_db(TRUE, ROW, el)[far].max() < -27.0  # the row's own sidelobes, whatever the elevation


def test_elevation_is_still_resolved_from_every_channel():
    """``azimuth_channels = "row"`` changes the RA map only: the elevation spectrum keeps the raised channels."""
    from xnlos_core.signal.chain import decouple, range_fft

    el = np.radians(20.0)
    cube = dechirp(TRUE, [2 * TARGET[0]], [TARGET[1]], [1.0], elevation=[el])
    prof = decouple(range_fft(cube, ROW), ROW)
    k = int(np.argmin(np.abs(ROW.range_axis - TARGET[0])))
    grid = np.radians(np.arange(-60.0, 60.5, 0.5))
    a, b = elevation_spectrum(prof, ROW, k, TARGET[1], grid), elevation_spectrum(prof, TRUE, k, TARGET[1], grid)
    np.testing.assert_allclose(a, b)
    assert channel_positions(ROW)[4:8, 1].min() > 0
