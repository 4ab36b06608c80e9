"""wall_max_speed (ClusterParams): a road user in line of sight moves, a wall does not; LOS
detections faster than wall_max_speed stay out of every wall fit, this frame's and the held ones."""
import numpy as np
import pytest

from estimators.lsq import ClusterParams, LSQWallEstimator, los_clusters
from xnlos_core.errors import InsufficientDataError
from xnlos_core.types import LOS, Detections


def _rows(pts, velocity):
    """LOS Detections at Cartesian points (K, 2) [m] with 5 cm / 2 mrad errors and radial velocities (K,) or None."""
    base = Detections.from_points(pts, label=LOS, range_std=0.05, azimuth_std=0.002)
    v = None if velocity is None else np.asarray(velocity, float)
    return Detections(base.range, base.azimuth, base.label, base.confidence, base.range_std, base.azimuth_std,
                      velocity=v, velocity_var=None if v is None else np.full(len(v), 0.01))


def _detections(velocity):
    """A facade x = 10 m (y = −6 … 6 m, static) and a car's side 3 m in front of it, close enough to chain
    into the facade's cluster (x = 8.5 … 9, y = −2 … 2, moving at the given radial velocity)."""
    wall = np.c_[np.full(13, 10.0), np.linspace(-6, 6, 13)]
    car = np.c_[np.linspace(8.5, 9.0, 5), np.linspace(-2, 2, 5)]
    v = None if velocity is None else np.r_[np.zeros(len(wall)), np.full(len(car), velocity)]
    return _rows(np.vstack([wall, car]), v)


def test_moving_los_points_are_left_out_of_the_walls():
    det = _detections(-3.0)
    idx, _, _, chosen = los_clusters(det, ClusterParams(wall_max_speed=0.5), "t")
    assert set(idx.tolist()) == set(range(13))  # the car's 5 rows are gone
    w = LSQWallEstimator({"wall_max_speed": 0.5}).estimate(det)
    assert len(w) == 1 and abs(abs(w[0].normal[0]) - 1) < 1e-9 and w[0].offset == pytest.approx(10.0, abs=1e-9)
    assert sorted(w[0].info["detection_index"]) == list(range(13))
    assert ClusterParams().wall_max_speed == 0.5  # the default
    # None keeps them, and the car tilts the wall.
    idx, _, _, _ = los_clusters(det, ClusterParams(wall_max_speed=None), "t")
    assert len(idx) == 18
    assert LSQWallEstimator({"wall_max_speed": None}).estimate(det)[0].offset != pytest.approx(10.0, abs=0.05)


def test_without_doppler_every_los_point_is_kept():
    assert len(los_clusters(_detections(None), ClusterParams(wall_max_speed=0.5), "t")[0]) == 18
    assert len(los_clusters(_detections(0.4), ClusterParams(wall_max_speed=0.5), "t")[0]) == 18  # ≤ the bound


def test_only_moving_points_give_a_clear_error():
    car = _rows(np.array([[9.0, 0.0], [9.0, 1.0], [9.0, 2.0]]), np.full(3, 4.0))
    with pytest.raises(InsufficientDataError, match="3 LOS detection.*faster than wall_max_speed = 0.5 m/s"):
        los_clusters(car, ClusterParams(wall_max_speed=0.5), "t")
