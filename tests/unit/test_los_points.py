"""Line-of-sight detections as tracker points: positions, covariances and radial velocity rows."""
from __future__ import annotations

import numpy as np

from xnlos_core.los_points import detection_points
from xnlos_core.types import LOS, MNLOS, UNCLASSIFIED, Detections


def test_polar_errors_become_a_covariance_along_and_across_the_line_of_sight():
    r, th = np.array([10.0, 4.0, 7.0]), np.array([0.3, -0.5, 1.0])
    det = Detections(r, th, np.array([LOS, MNLOS, UNCLASSIFIED], np.int8), np.ones(3), np.array([0.1, 0.2, 0.3]),
                     np.array([0.01, 0.02, 0.03]), velocity=np.array([1.5, -2.0, -0.5]),
                     velocity_var=np.array([0.04, 0.09, 0.01]))
    pts = detection_points(det)
    assert pts.source_index.tolist() == [0, 2]  # the mNLOS image is not where an object is
    for i, k in enumerate(pts.source_index):
        u = np.array([np.cos(th[k]), np.sin(th[k])])
        n = np.array([-u[1], u[0]])
        np.testing.assert_allclose(pts.mean[i], r[k] * u)
        np.testing.assert_allclose(pts.view[i], u)
        # σ_r² along û, (r·σ_θ)² across it, nothing between (closed form of J·diag(σ_r², σ_θ²)·Jᵀ)
        np.testing.assert_allclose(u @ pts.cov[i] @ u, det.range_std[k] ** 2)
        np.testing.assert_allclose(n @ pts.cov[i] @ n, (r[k] * det.azimuth_std[k]) ** 2)
        np.testing.assert_allclose(u @ pts.cov[i] @ n, 0.0, atol=1e-15)
        # the radial velocity as the component along û, its variance along û only
        np.testing.assert_allclose(pts.velocity[i], det.velocity[k] * u)
        np.testing.assert_allclose(u @ pts.velocity_cov[i] @ u, det.velocity_var[k])
        np.testing.assert_allclose(n @ pts.velocity_cov[i] @ n, 0.0, atol=1e-15)
    assert np.all(pts.wall_index == 0)


def test_without_doppler_or_detections():
    det = Detections(np.array([5.0]), np.array([0.0]), np.array([LOS], np.int8), np.ones(1))
    pts = detection_points(det)
    assert pts.velocity is None and len(pts) == 1
    assert len(detection_points(Detections.empty())) == 0
