"""CFAR reports no detection on the azimuth edge of the map: there a cell's maximum may lie beyond
the field of view, where the map holds nothing to compare it with."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plugins.detectors.peaks import cfar_peaks, local_maxima
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import add_noise, dechirp, ra_map_from_cube

RADAR = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, n_chirps=4, n_tx=2, n_rx=4,
                    max_range=20.0, n_azimuth_bins=31)


def _map(azimuth_deg, seed=0):
    cube = dechirp(RADAR, [2 * 8.0], [math.radians(azimuth_deg)], [1e-5])
    return ra_map_from_cube(add_noise(cube, RADAR, np.random.default_rng(seed)), RADAR)


@pytest.mark.parametrize("azimuth_deg", [68.0, 75.0, -72.0])
def test_an_echo_beyond_the_field_of_view_is_no_detection(azimuth_deg):
    ra = _map(azimuth_deg)
    p = ra.power
    row = int(np.argmax(p.max(axis=1)))
    edge = 0 if azimuth_deg < 0 else -1
    # the echo leaves a map rising towards the edge: the edge cell passes the 3×3 test …
    assert local_maxima(p)[row, edge] and p[row, edge] == p[row].max()
    det = cfar_peaks(ra, 1e-4, (2, 2), (4, 4), 1.0)
    # … but is not reported: no detection at the echo's range on the edge, or anywhere near it
    near = np.abs(det.range - 8.0) < 1.0
    assert not np.any(near & (np.abs(det.azimuth) >= RADAR.field_of_view - 1e-9)), det.azimuth[near]


@pytest.mark.parametrize("azimuth_deg", [52.0, -50.0, 0.0])
def test_an_echo_inside_the_field_of_view_is_detected_on_its_peak(azimuth_deg):
    det = cfar_peaks(_map(azimuth_deg), 1e-4, (2, 2), (4, 4), 1.0)
    k = int(np.argmin(np.abs(det.range - 8.0) + np.abs(det.azimuth - math.radians(azimuth_deg))))
    assert det.range[k] == pytest.approx(8.0, abs=RADAR.range_resolution)
    assert det.azimuth[k] == pytest.approx(math.radians(azimuth_deg), abs=math.radians(4.0))
    assert np.all(np.abs(det.azimuth) < RADAR.field_of_view)
