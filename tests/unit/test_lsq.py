"""Least-squares walls: exact recovery, clustering, covariance vs Monte Carlo, errors."""
import numpy as np
import pytest

from estimators.lsq import LSQWallEstimator, fit_line
from xnlos_core import LOS, MNLOS, Detections, InsufficientDataError, WallPosterior

def detections(points, label=LOS, range_std=0.0, azimuth_std=0.0):
    return Detections.from_points(points, label, 1.0, range_std, azimuth_std)

def on_line(n, b, t):
    """Points on nᵀx + b = 0 at along-line coordinates t (from the foot point −b n)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    u = np.array([-n[1], n[0]])
    return -b * n + np.asarray(t, float)[:, None] * u

def test_exact_line_recovered():
    n = np.array([-1.0, -1.0]) / np.sqrt(2)  # wall x + y = 25, radar side positive
    pts = on_line(n, 25 / np.sqrt(2), np.linspace(-8, 8, 30))
    (w,) = LSQWallEstimator().estimate(detections(pts))
    assert np.allclose(w.normal, n, atol=1e-9)
    assert w.offset == pytest.approx(25 / np.sqrt(2), abs=1e-9)
    assert w.info["residual_rms"] < 1e-9 and w.info["cluster_size"] == 30 and w.n_points == 30
    assert np.allclose(w.cov, 0, atol=1e-18)
    assert np.allclose(np.sort(w.extent[:, 0]), [25 / 2 - 8 / np.sqrt(2), 25 / 2 + 8 / np.sqrt(2)])
    assert w.info["detection_index"] == list(range(30))

def test_two_walls_two_posteriors_largest_first_and_mnlos_ignored():
    a = on_line([-1, 0], 20.0, np.linspace(2, 12, 21))  # x = 20
    b = on_line([0, -1], 8.0, np.linspace(-10, -2, 9))  # y = 8
    pts = np.concatenate([b, a, [[40.0, 40.0]]])
    labels = np.r_[np.full(len(b) + len(a), LOS), MNLOS]
    walls = LSQWallEstimator().estimate(detections(pts, labels))
    assert [w.n_points for w in walls] == [21, 9]
    assert np.allclose(walls[0].normal, [-1, 0]) and walls[0].offset == pytest.approx(20)
    assert np.allclose(walls[1].normal, [0, -1]) and walls[1].offset == pytest.approx(8)
    assert sorted(walls[1].info["detection_index"]) == list(range(9))

def test_covariance_matches_monte_carlo():
    rng = np.random.default_rng(7)
    n_true, b_true, sigma = np.array([-1.0, 0.0]), 20.0, 0.15
    base = on_line(n_true, b_true, np.linspace(-15, -3, 25))  # x = 20, y ∈ [3, 15]: strong φ–b coupling
    draws, covs = [], []
    for _ in range(3000):
        w = fit_line(base + sigma * rng.standard_normal(base.shape))
        draws.append(w.mean)
        covs.append(w.cov)
    draws = np.array(draws)
    draws[:, 0] = np.angle(np.exp(1j * (draws[:, 0] - np.pi)))  # φ near π: unwrap around it
    emp = np.cov(draws.T)
    pred = np.mean(covs, axis=0)
    assert pred[0, 0] == pytest.approx(emp[0, 0], rel=0.2)
    assert pred[1, 1] == pytest.approx(emp[1, 1], rel=0.2)
    assert pred[0, 1] == pytest.approx(emp[0, 1], rel=0.2)
    assert abs(emp[0, 1]) / np.sqrt(emp[0, 0] * emp[1, 1]) > 0.5  # the cross term matters here
    # The estimator path (detections → clusters → fit) gives the same answer as fit_line.
    noisy = base + sigma * rng.standard_normal(base.shape)
    (w,) = LSQWallEstimator().estimate(detections(noisy))
    assert np.allclose(w.cov, fit_line(noisy).cov)

def test_two_points_use_detection_covariance():
    pts = on_line([-1, 0], 20.0, [-5.0, -4.0])
    (w,) = LSQWallEstimator().estimate(detections(pts, range_std=0.1, azimuth_std=0.01))
    assert w.n_points == 2 and w.cov[0, 0] > 0 and w.cov[1, 1] > 0
    assert np.linalg.eigvalsh(w.cov).min() >= 0

def test_fewer_than_two_los_points_raise_with_count():
    det = detections([[10.0, 0.0], [20.0, 5.0], [30.0, 1.0]], [LOS, MNLOS, MNLOS])
    with pytest.raises(InsufficientDataError, match=r"1 LOS detection\(s\) among 3 detections.*at least 2"):
        LSQWallEstimator().estimate(det)
    with pytest.raises(InsufficientDataError, match="0 LOS"):
        LSQWallEstimator().estimate(Detections.empty())

def test_min_points_fallback_and_isolated_points():
    pairs = np.array([[10.0, 0.0], [10.0, 1.0], [30.0, 0.0], [30.0, 1.5], [30.0, 3.0]])
    walls = LSQWallEstimator({"min_points": 4}).estimate(detections(pairs))
    assert len(walls) == 1 and walls[0].n_points == 3  # largest cluster, below min_points
    far = np.array([[10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    with pytest.raises(InsufficientDataError, match="cluster_distance"):
        LSQWallEstimator().estimate(detections(far))
    with pytest.raises(InsufficientDataError, match="coincide"):
        LSQWallEstimator().estimate(detections([[10.0, 0.0], [10.0, 0.0]]))

def test_wall_posterior_flip_negates_cross_covariance():
    cov = np.array([[0.01, 0.02], [0.02, 0.09]])
    w = WallPosterior("line", np.array([0.0, -5.0]), cov)  # b < 0: canonical form flips n
    assert w.offset == 5.0 and np.allclose(w.normal, [-1, 0])
    assert np.allclose(w.cov, [[0.01, -0.02], [-0.02, 0.09]])
