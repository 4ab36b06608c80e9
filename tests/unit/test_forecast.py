"""Forecast pieces: exact Gaussian disc radii, the CV forecast of kalman/nearest, region entry times."""
import numpy as np
import pytest
from scipy.stats import norm

from estimators.trackers.disc import disc_probability, disc_radius
from estimators.trackers.kalman import KalmanTracker
from estimators.trackers.nearest import NearestTracker
from estimators.trackers.region import Region
from xnlos_core import ConfigError, HiddenPoints, InputError


def hidden(points, sigma=0.1):
    pts = np.asarray(points, float).reshape(-1, 2)
    k = len(pts)
    return HiddenPoints(pts, np.tile(sigma ** 2 * np.eye(2), (k, 1, 1)), np.arange(k), np.zeros(k))


def test_disc_radius_closed_forms_and_a_seeded_draw():
    # isotropic: P(|X| ≤ r) = 1 − exp(−r²/2λ); a line (λ₂ = 0): r = √λ₁ Φ⁻¹((1 + p)/2)
    assert disc_radius(4.0 * np.eye(2), 0.5) == pytest.approx(np.sqrt(8 * np.log(2)), rel=1e-9)
    assert disc_radius(np.diag([4.0, 0.0]), 0.9) == pytest.approx(2 * norm.ppf(0.95), rel=1e-6)
    cov = np.array([[3.0, 1.0], [1.0, 0.5]])
    x = np.random.default_rng(0).multivariate_normal([0, 0], cov, 200_000)
    for p in (0.5, 0.9):
        r = disc_radius(cov, p)
        assert disc_probability(r, *np.linalg.eigvalsh(cov)[::-1]) == pytest.approx(p, abs=1e-9)
        assert np.mean(np.linalg.norm(x, axis=1) <= r) == pytest.approx(p, abs=0.005)
    with pytest.raises(InputError, match="prob"):
        disc_radius(cov, 1.0)


def test_kalman_forecast_is_cv_mean_with_propagated_covariance():
    # One frame, confirm_hits = 1: x = (z, 0), P = diag(R, σ_v² I) → covariance of the true position
    # at h is R + h²σ_v² I + q h³/3 I — no second R: the disc is for the object, not a future
    # measurement of it (isotropic: closed-form radii).
    q, sv, s = 2.0, 3.0, 0.2
    tr = KalmanTracker({"confirm_hits": 1, "accel_psd": q, "initial_speed_sigma": sv, "sigma_floor": 1e-3,
                        "extent_sigma": 0.0, "horizons": [0.5, 2.0]})
    out = tr.update(hidden([[10.0, 5.0]], s), 0.0)
    assert out.model == ("cv",) and np.allclose(out.forecast[0], [[10.0, 5.0], [10.0, 5.0]])
    lam = (s ** 2 + 1e-6) + out.horizons ** 2 * sv ** 2 + q * out.horizons ** 3 / 3
    assert np.allclose(out.radius50[0], np.sqrt(2 * lam * np.log(2)), rtol=1e-6)
    assert np.allclose(out.radius90[0], np.sqrt(2 * lam * np.log(10)), rtol=1e-6)


def test_nearest_forecast_cv_mean_nan_radii():
    tr = NearestTracker()
    tr.update(hidden([[0.0, 0.0]]), 0.0)
    out = tr.update(hidden([[1.0, 0.5]]), 0.5)
    assert np.allclose(out.forecast[0, 3], out.position[0] + 2.0 * out.velocity[0])
    assert np.all(np.isnan(out.radius90)) and out.model == ("cv",)
    with pytest.raises(ConfigError, match="horizon"):
        NearestTracker({"horizons": [4.0]})


def test_region_entry_time_of_a_straight_path_is_exact():
    lane = Region([[20.0, -1.0], [40.0, -1.0], [40.0, 1.0], [20.0, 1.0]])
    h = np.arange(31) * 0.1
    paths = np.stack([np.c_[5.0 + 7.0 * h, 0.3 * h],       # enters x = 20 at 15/7 s
                      np.c_[25.0 + 0 * h, 0 * h],          # inside from the start
                      np.c_[0 * h, 5.0 + h]])              # never
    t = lane.first_entry(paths, 0.1)
    assert t[0] == pytest.approx(15 / 7, abs=1e-12) and t[1] == 0.0 and np.isnan(t[2])
    with pytest.raises(InputError, match="vertices"):
        Region([[0.0, 0.0], [1.0, 1.0]])


def test_kalman_time_to_appearance_of_a_cv_target():
    # A target converged on v = (8, 0) m/s at x = 0 enters the lane x ∈ [20, 40] at t + 2.5 s.
    lane = [[20.0, -2.0], [40.0, -2.0], [40.0, 2.0], [20.0, 2.0]]
    tr = KalmanTracker({"region": lane, "accel_psd": 0.05, "seed": 3, "extent_sigma": 0.0})
    rng = np.random.default_rng(0)
    for k in range(41):
        t = 0.1 * k
        out = tr.update(hidden([[-32.0 + 8.0 * t + 0.05 * rng.standard_normal(), 0.0]], 0.05), t)
    assert out.arrival[0] == pytest.approx(4.0 + 2.5, abs=0.05)
    lo, hi = out.arrival_interval[0]
    assert lo < out.arrival[0] < hi and hi - lo < 0.5
    slow = KalmanTracker({"region": lane, "confirm_hits": 1})
    out = slow.update(hidden([[-100.0, 0.0]]), 0.0)           # at rest, 120 m away: never within 3 s
    assert np.isnan(out.arrival[0]) and np.all(np.isinf(out.arrival_interval[0]))


def test_mixture_forecast_moment_match_and_spread_scale():
    # Two members, P = 0, q = 0: the mean is the members' mean path and the covariance s² times the
    # members' spread, Eq. (1) of forecast.py; member paths by scipy's expm (independent of the cache).
    from scipy.linalg import expm

    from estimators.trackers import forecast as fc

    members = np.array([[[0.0, -0.3], [0.3, 0.0]], [[-0.2, 0.0], [0.0, -0.2]]])
    motion = fc.LinearMotion(members.mean(axis=0), members, "test")
    x, h = np.array([1.0, 2.0, 10.0, -3.0]), np.array([1.0, 2.5])
    mu = np.array([[(expm(fc.system_matrix(m) * hk) @ x)[:2] for hk in h] for m in members])
    d = mu - mu.mean(axis=0)
    for s in (1.0, 0.5):
        mean, cov = fc.forecast(motion, x, np.zeros((4, 4)), h, 0.0, s)
        assert np.allclose(mean, mu.mean(axis=0), atol=1e-10)
        assert np.allclose(cov, s ** 2 * np.einsum("mki,mkj->kij", d, d) / 2, atol=1e-10)
    r50, r90 = fc.radii(cov)
    assert np.allclose(r50, disc_radius(cov, 0.5)) and np.allclose(r90, disc_radius(cov, 0.9))


def test_interval_scale_multiplies_the_disc_radii():
    # the conformal factors (benchmarks/interval_calibration.py) scale each level's radius, nothing else
    kw = {"confirm_hits": 1, "horizons": [1.0, 2.0]}
    base = KalmanTracker(kw).update(hidden([[10.0, 5.0]], 0.2), 0.0)
    scaled = KalmanTracker({**kw, "interval_scale": [0.5, 2.0]}).update(hidden([[10.0, 5.0]], 0.2), 0.0)
    np.testing.assert_allclose(scaled.radius50, 0.5 * base.radius50)
    np.testing.assert_allclose(scaled.radius90, 2.0 * base.radius90)
    np.testing.assert_array_equal(scaled.forecast, base.forecast)


def test_disc_radius_from_its_table_start_solves_eq_1_for_any_shape_and_probability():
    # λ₂/λ₁ from 0 (a line) to 1 (isotropic), probabilities from the table (two) and more than it holds
    # (the bracket-midpoint start): P(|X| ≤ r) of Eq. (1) equals the probability asked for
    lam1 = np.array([4.0, 4.0, 1.0, 9.0, 0.25, 2.0])
    lam2 = np.array([0.0, 1e-6, 0.3, 9.0, 0.2, 1.0])
    cov = np.zeros((6, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = lam1, lam2
    for prob in (np.array([0.5, 0.9])[:, None], np.linspace(0.05, 0.95, 19)[:, None]):
        r = disc_radius(cov[None], prob)
        assert np.allclose(disc_probability(r, lam1, lam2), np.broadcast_to(prob, r.shape), atol=1e-10)


def test_a_motions_cached_transition_is_a_copy():
    from estimators.trackers.forecast import LinearMotion

    m = LinearMotion(np.array([[0.0, -0.3], [0.3, 0.0]]), np.zeros((1, 2, 2)))
    a = m.transition(0.1)
    a[:] = 0.0
    assert np.allclose(m.transition(0.1)[:2, :2], np.eye(2))
