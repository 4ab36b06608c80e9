"""Every detector reads each detection's radial velocity from the RA map's Doppler maps at its peak cell
(plugins.detectors.detection_doppler; a learned detector's peak cell moved to the strongest cell beside it); None
without the maps."""
import dataclasses

import numpy as np
import pytest

from plugins.detectors.cfar import CFARDetector
from plugins.detectors.learned import detections_from_output
from plugins.detectors.nlos_cfar import NLOSCFARDetector
from plugins.detectors.tasks import DenseHead
from plugins.detectors.detection_doppler import nearest_cells, strongest_cells, with_cell_velocity
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
    det = detections_from_output(logits, DenseHead(), frame.ra_map, 0.5, (5, 5), True, 10, velocity_radius=0)
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


def _echo_map(shape=None, echo=(40, 20), power=100.0):
    """The synthetic frame's RA map, blank but for one echo of |κ|² = ``power`` at cell ``echo`` and a
    weaker one (|κ|² = 4) two cells beside it, with the velocity maps of :func:`_velocity_maps`."""
    ra = _with_doppler(synthetic_frame()).ra_map
    data = np.full(ra.shape, 0.1, np.complex64)
    data[echo] = np.sqrt(power)
    data[echo[0], echo[1] + 2] = 2.0
    return dataclasses.replace(ra, data=data)


def test_strongest_cells_moves_a_peak_beside_an_echo_onto_it():
    ra = _echo_map()
    # beside the echo (±1 cell, also diagonally) → the echo's cell; on it → unchanged
    r, c = strongest_cells(ra, [41, 40, 39, 40], [21, 20, 19, 21])
    np.testing.assert_array_equal(r, [40, 40, 40, 40])
    np.testing.assert_array_equal(c, [20, 20, 20, 20])
    # the weaker echo two cells away: its own cell is the strongest within ±1 and stays; within ±2 the
    # stronger echo wins
    assert strongest_cells(ra, [40], [22]) == ([40], [22])
    assert strongest_cells(ra, [40], [22], radius=2) == ([40], [20])
    # a flat neighbourhood keeps the given cell (no tie moves it); radius 0 is the identity
    assert strongest_cells(ra, [90], [60]) == ([90], [60])
    assert strongest_cells(ra, [41], [21], radius=0) == ([41], [21])
    # clipped at the map's corner
    corner = _echo_map(echo=(0, 0))
    assert strongest_cells(corner, [1], [1]) == ([0], [0])
    h, w = ra.shape
    assert strongest_cells(ra, [h - 1], [w - 1]) == ([h - 1], [w - 1])


def test_strongest_cells_names_bad_input():
    ra = _echo_map()
    with pytest.raises(InputError, match="radius must be ≥ 0"):
        strongest_cells(ra, [1], [1], radius=-1)
    with pytest.raises(InputError, match="cell indices into the"):
        strongest_cells(ra, [ra.shape[0]], [1])
    with pytest.raises(InputError, match="equal-length"):
        strongest_cells(ra, [1, 2], [1])


def test_learned_decoding_reads_the_velocity_of_the_echo_beside_its_peak():
    # the network's confidence peaks one cell off the echo (a sidelobe cell holding another return's
    # Doppler bin): the detection keeps its refined position and takes the echo cell's velocity
    ra = _echo_map()
    h, w = ra.shape
    logits = np.full((2, h, w), -10.0)
    rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    logits[1] = 6.0 - 0.5 * ((rr - 41) ** 2 + (cc - 21) ** 2)
    det = detections_from_output(logits, DenseHead(), ra, 0.5, (5, 5), True, 10)
    assert len(det) == 1
    assert _peak_cells(det, ra) == ([41], [21])
    assert det.velocity[0] == ra.velocity[40, 20] and det.velocity_var[0] == ra.velocity_std[40, 20] ** 2
    near = detections_from_output(logits, DenseHead(), ra, 0.5, (5, 5), True, 10, velocity_radius=0)
    assert near.velocity[0] == ra.velocity[41, 21]
