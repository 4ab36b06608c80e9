"""The oracle detector (plugins/detectors/oracle.py): ground truth in, seeded noise, velocities along r̂'."""
import math

import numpy as np
import pytest

from plugins.detectors.oracle import OracleDetector
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.testing import check_detector
from xnlos_core.types import LOS, MNLOS, Frame, GroundTruth, RAMap

RADAR = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)


def _frame(index=3, velocity=True):
    gt = GroundTruth(los_points=np.array([[5.0, 1.0], [6.0, -2.0]]), mnlos_points=np.array([[10.0, 4.0]]),
                     hidden_points=np.array([[7.0, -3.0]]),
                     hidden_velocity=np.array([[0.0, 2.0]]) if velocity else None,
                     mnlos_velocity=np.array([[2.0, 0.0]]) if velocity else None)
    ra = RAMap.from_radar(np.ones((RADAR.n_range_bins, RADAR.n_azimuth_bins), np.complex64), RADAR)
    return Frame(ra, ground_truth=gt, index=index)


def test_noise_free_oracle_returns_the_ground_truth():
    det = OracleDetector({"range_sigma": 0, "azimuth_sigma": 0, "velocity_sigma": 0}).detect(_frame())
    np.testing.assert_array_equal(det.label, [LOS, LOS, MNLOS])
    np.testing.assert_allclose(det.position, [[5.0, 1.0], [6.0, -2.0], [10.0, 4.0]], atol=1e-12)
    # the virtual point moves at (2, 0) m/s; its radial velocity is r̂'ᵀv' = 2·10/√116
    np.testing.assert_allclose(det.velocity, [0.0, 0.0, 2.0 * 10.0 / math.sqrt(116.0)], atol=1e-12)


def test_a_road_user_in_line_of_sight_keeps_its_range_rate():
    # GroundTruth.los_radial_velocity: the second LOS point is on a car driving away at 3 m/s radially.
    f = _frame()
    gt = f.ground_truth
    moving = GroundTruth(gt.los_points, gt.mnlos_points, gt.hidden_points, hidden_velocity=gt.hidden_velocity,
                         mnlos_velocity=gt.mnlos_velocity, los_radial_velocity=[0.0, 3.0])
    det = OracleDetector({"range_sigma": 0, "azimuth_sigma": 0, "velocity_sigma": 0}).detect(
        Frame(f.ra_map, ground_truth=moving, index=3))
    np.testing.assert_allclose(det.velocity, [0.0, 3.0, 2.0 * 10.0 / math.sqrt(116.0)], atol=1e-12)


def test_noise_is_seeded_per_frame_and_has_its_sigma():
    o = OracleDetector({"range_sigma": 0.5, "seed": 7})
    a, b = o.detect(_frame(index=3)), o.detect(_frame(index=3))
    np.testing.assert_array_equal(a.range, b.range)
    assert not np.array_equal(a.range, o.detect(_frame(index=4)).range)
    np.testing.assert_allclose(a.range_std, 0.5)
    truth = np.array([math.hypot(5, 1), math.hypot(6, 2), math.hypot(10, 4)])
    errs = np.concatenate([o.detect(_frame(index=i)).range - truth for i in range(400)])
    assert np.std(errs) == pytest.approx(0.5, rel=0.1)


def test_without_velocities_or_ground_truth_or_outside_the_map():
    assert OracleDetector().detect(_frame(velocity=False)).velocity is None
    assert len(OracleDetector().detect(Frame(_frame().ra_map))) == 0  # a recorded frame: nothing to read
    narrow = RadarConfig(n_samples=128, max_range=8.0, n_azimuth_bins=31)  # 8 m: the 10.8 m mNLOS point is out
    ra = RAMap.from_radar(np.ones((narrow.n_range_bins, narrow.n_azimuth_bins), np.complex64), narrow)
    det = OracleDetector().detect(Frame(ra, ground_truth=_frame().ground_truth, index=1))
    np.testing.assert_array_equal(det.label, [LOS, LOS])
    with pytest.raises(InputError, match="expected a Frame"):
        OracleDetector().detect(_frame().ra_map)


def test_conformance_kit():
    check_detector(OracleDetector())
