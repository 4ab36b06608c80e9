"""Nearest-neighbour constant-velocity tracker."""
import numpy as np
import pytest

from estimators.trackers.nearest import NearestTracker, cluster_centroids
from xnlos_core import HiddenPoints, InputError


def hidden(points):
    pts = np.asarray(points, float).reshape(-1, 2)
    k = len(pts)
    return HiddenPoints(pts, np.zeros((k, 2, 2)), np.arange(k), np.zeros(k))


def car_points(center):
    """A car's several scatterers (front/back/side), all within 2 m of each other."""
    return np.asarray(center) + np.array([[-1.5, 0.0], [0.0, 0.6], [1.5, 0.0]])


def test_constant_velocity_keeps_one_id_and_velocity_converges():
    rng = np.random.default_rng(0)
    v_true = np.array([0.0, 5.0])
    tracker = NearestTracker()
    for k in range(40):
        t = 0.1 * k
        pts = car_points(np.array([22.0, -14.0]) + v_true * t) + 0.05 * rng.standard_normal((3, 2))
        tracks = tracker.update(hidden(pts), t)
        assert tracks.track_id.tolist() == [0]
    assert np.linalg.norm(tracks.velocity[0] - v_true) < 0.3
    centroid = car_points(np.array([22.0, -14.0]) + v_true * 3.9).mean(axis=0)
    assert np.linalg.norm(tracks.position[0] - centroid) < 0.15
    assert np.allclose(tracks.predicted[0], tracks.position[0] + 0.1 * tracks.velocity[0])


def test_exact_motion_gives_exact_velocity():
    tracker = NearestTracker()
    for k in range(3):
        tracks = tracker.update(hidden([[10.0 + 2.0 * k, 0.0]]), 0.5 * k)
    assert np.allclose(tracks.velocity, [[4.0, 0.0]])


def test_two_objects_gating_deletion_and_reset():
    tracker = NearestTracker({"max_misses": 2, "gate": 3.0})
    tracker.update(hidden([[0.0, 0.0], [20.0, 0.0]]), 0.0)
    tracks = tracker.update(hidden([[0.5, 0.0], [20.5, 0.0]]), 0.1)
    assert tracks.track_id.tolist() == [0, 1]
    tracks = tracker.update(hidden([[1.0, 0.0], [40.0, 0.0]]), 0.2)  # 40 m is outside the gate: new track
    assert sorted(tracks.track_id.tolist()) == [0, 1, 2]
    tracks = tracker.update(hidden([[1.5, 0.0]]), 0.3)  # tracks 1 and 2 miss; 1 has now missed twice
    assert sorted(tracks.track_id.tolist()) == [0, 2]
    tracks = tracker.update(hidden(np.empty((0, 2))), 0.4)
    assert sorted(tracks.track_id.tolist()) == [0]
    tracker.reset()
    assert tracker.update(hidden([[5.0, 5.0]]), 0.0).track_id.tolist() == [0]


def test_clustering_and_errors():
    c = cluster_centroids(np.r_[car_points([0.0, 0.0]), car_points([10.0, 0.0])], 2.0)
    assert np.allclose(sorted(c[:, 0]), [0.0, 10.0]) and np.allclose(c[:, 1], 0.2)
    tracker = NearestTracker()
    tracker.update(hidden([[0.0, 0.0]]), 1.0)
    with pytest.raises(InputError, match="must not decrease"):
        tracker.update(hidden([[0.0, 0.0]]), 0.5)
    assert len(NearestTracker().update(HiddenPoints.empty(), 0.0)) == 0
