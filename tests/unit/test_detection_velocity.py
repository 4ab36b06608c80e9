"""Every detector reads each detection's radial velocity from the RA map's Doppler maps at its peak cell
(xnlos_core.detection_doppler); None without the maps."""
import dataclasses

import numpy as np
import pytest

from plugins.detectors.cfar import CFARDetector
from plugins.detectors.learned import detections_from_output
from plugins.detectors.nlos_cfar import NLOSCFARDetector
from plugins.detectors.tasks import DenseHead
from xnlos_core.detection_doppler import nearest_cells, with_cell_velocity
from xnlos_core.errors import InputError
from xnlos_core.testing import synthetic_frame
from xnlos_core.types import LOS, MNLOS, Detections


def _velocity_maps(shape):
    """A distinct velocity in every cell [m/s] (so a detection read off the wrong cell is caught)
    and a σ that varies too [m/s]."""
    i, j = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    return 0.01 * i - 0.0037 * j - 1.0, 0.05 + 0.001 * i + 0.0002 * j


def _with_doppler(frame):
    v, s = _velocity_maps(frame.ra_map.shape)
    return dataclasses.replace(frame, ra_map=dataclasses.replace(frame.ra_map, velocity=v, velocity_std=s))


def _peak_cells(det, ra_map):
    """Nearest (range, azimuth) bin of each detection: its peak cell (refinement ≤ ½ bin)."""
    fr = np.interp(det.range, ra_map.range_axis, np.arange(ra_map.shape[0]))
    fc = np.interp(det.azimuth, ra_map.azimuth_axis, np.arange(ra_map.shape[1]))
    return np.rint(fr).astype(int), np.rint(fc).astype(int)


@pytest.mark.parametrize("detector", [CFARDetector(), NLOSCFARDetector()], ids=["cfar", "nlos_cfar"])
def test_detections_carry_the_velocity_of_their_peak_cell(detector):
    plain = synthetic_frame()
    frame = _with_doppler(plain)
    det = detector.detect(frame)
    assert len(det) >= 5
    r, c = _peak_cells(det, frame.ra_map)
    np.testing.assert_array_equal(det.velocity, frame.ra_map.velocity[r, c])
    np.testing.assert_array_equal(det.velocity_var, frame.ra_map.velocity_std[r, c] ** 2)
    # the rest is what the same map without Doppler gives, and that one has no velocity
    base = detector.detect(plain)
    assert base.velocity is None and base.velocity_var is None
    for f in ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std"):
        np.testing.assert_array_equal(getattr(det, f), getattr(base, f))


def test_nlos_cfar_labels_and_keeps_the_velocity():
    det = NLOSCFARDetector().detect(_with_doppler(synthetic_frame()))
    assert set(det.label.tolist()) == {LOS, MNLOS}  # labelled, and the Doppler fields survived the relabel
    assert det.velocity is not None and len(det.velocity) == len(det)


def test_learned_decoding_reads_the_velocity_at_the_peak_cell():
    frame = _with_doppler(synthetic_frame())
    h, w = frame.ra_map.shape
    logits = np.full((2, h, w), -10.0)
    peaks = [(0, 20, 30), (1, 70, 12), (0, 45, 60)]  # (class, row, col)
    rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    for k, r0, c0 in peaks:  # Gaussian bumps offset by 0.3 cell: refined off-grid, same peak cell
        logits[k] = np.maximum(logits[k], 6.0 - 0.5 * ((rr - r0 - 0.3) ** 2 + (cc - c0 + 0.3) ** 2))
    det = detections_from_output(logits, DenseHead(), frame.ra_map, 0.5, (5, 5), True, 10)
    assert len(det) == 3
    r, c = _peak_cells(det, frame.ra_map)
    assert sorted(zip(r.tolist(), c.tolist())) == sorted((r0, c0) for _, r0, c0 in peaks)
    np.testing.assert_array_equal(det.velocity, frame.ra_map.velocity[r, c])
    assert detections_from_output(logits, DenseHead(), synthetic_frame().ra_map, 0.5, (5, 5), True, 10).velocity is None


def test_without_maps_the_detections_are_returned_as_they_are():
    frame = synthetic_frame()
    det = Detections.from_points([[10.0, 1.0]])
    assert with_cell_velocity(det, frame.ra_map, [3], [4]) is det


def test_bad_peak_cells_are_named():
    ra = _with_doppler(synthetic_frame()).ra_map
    det = Detections.from_points([[10.0, 1.0], [12.0, 0.0]])
    with pytest.raises(InputError, match="integer arrays of shape \\(2,\\)"):
        with_cell_velocity(det, ra, [1.5, 2.0], [3, 4])
    with pytest.raises(InputError, match="must lie in the"):
        with_cell_velocity(det, ra, [1, ra.shape[0]], [3, 4])


def test_nearest_cells_round_and_clip():
    r, c = nearest_cells([0.4, 2.6, -0.3, 9.7], [1.2, 0.5, 3.49, 5.0], (10, 4))
    np.testing.assert_array_equal(r, [0, 3, 0, 9])
    np.testing.assert_array_equal(c, [1, 0, 3, 3])
    assert r.dtype.kind == "i"
