"""casadi_map and emcee wall estimators: exact Bayesian answer, least squares, outliers, model
selection, several walls, reproducibility and diagnostics."""
import warnings

import numpy as np
import pytest

from estimators.casadi_map import CasadiMapWallEstimator
from estimators.emcee_wall import EmceeWallEstimator
from estimators.lsq import LSQWallEstimator
from xnlos_core import LOS, MNLOS, ConfigError, Detections
from xnlos_core.geometry import cartesian_to_polar

# The exact Gaussian line fit: no outlier term, no roughness, the stated noise taken as known.
EXACT = {"outlier_fraction": 0.0, "wall_roughness": 0.0, "estimate_noise_scale": False, "models": ["line"]}


def isotropic_detections(points, sigma, label=LOS):
    """Detections whose Cartesian covariance is exactly σ²I (range σ, azimuth σ/r)."""
    r, a = cartesian_to_polar(points)
    k = len(r)
    return Detections(r, a, np.full(k, label, np.int8), np.ones(k), np.full(k, sigma), sigma / r)


def wall_points(rng, n=14, sigma=0.15, x0=20.0, half=6.0, tilt=0.2):
    """Noisy points of the line x = x0 + tilt·y, y ∈ [−half, half], isotropic noise σ."""
    y = np.linspace(-half, half, n)
    pts = np.stack([x0 + tilt * y, y], 1)
    return pts + rng.normal(0, sigma, pts.shape)


def exact_line_posterior(points, sigma, phi_grid):
    """Posterior moments of (φ, b) under a flat prior and known isotropic noise σ (quadrature).

    p(φ, b | x) ∝ exp(−Σ(nᵀx_i + b)²/2σ²): b | φ ~ N(−nᵀx̄, σ²/N) and, integrating b out,
    p(φ | x) ∝ exp(−nᵀSn/2σ²) with S the scatter matrix about the centroid x̄.
    """
    xbar = points.mean(0)
    d = points - xbar
    s = d.T @ d
    n = np.stack([np.cos(phi_grid), np.sin(phi_grid)], 1)
    logp = -np.einsum("gi,ij,gj->g", n, s, n) / (2 * sigma**2)
    w = np.exp(logp - logp.max())
    w /= w.sum()
    bmean = -(n @ xbar)
    e_phi, e_b = w @ phi_grid, w @ bmean
    var_phi = w @ (phi_grid - e_phi) ** 2
    var_b = w @ (sigma**2 / len(points) + bmean**2) - e_b**2
    cov_pb = w @ (phi_grid * bmean) - e_phi * e_b
    return np.array([e_phi, e_b]), np.array([[var_phi, cov_pb], [cov_pb, var_b]])


@pytest.mark.parametrize("chain", [{"n_walkers": 16, "n_steps": 2200, "burn": 200}, {}],
                         ids=["16x2200", "defaults"])
def test_emcee_matches_the_exact_gaussian_line_posterior(chain):
    """the many-walkers, few-steps defaults (128 × 200) as well as a long 16-walker chain."""
    rng = np.random.default_rng(11)
    sigma = 0.15
    pts = wall_points(rng, sigma=sigma)
    est = EmceeWallEstimator({**EXACT, **chain, "seed": 3})
    (w,) = est.estimate(isotropic_detections(pts, sigma))
    phi0 = w.mean[0]
    mean, cov = exact_line_posterior(pts, sigma, phi0 + np.linspace(-0.2, 0.2, 40001))
    sd = np.sqrt(np.diag(cov))
    ess = w.info["ess"]
    assert ess > 500, w.info
    # Monte-Carlo error of a mean ≈ σ/√ESS, of a variance ≈ √(2/ESS)·σ².
    assert np.all(np.abs(w.mean - mean) < 5 * sd / np.sqrt(ess)), (w.mean, mean, sd)
    assert np.allclose(np.diag(w.cov), np.diag(cov), rtol=6 * np.sqrt(2 / ess))
    corr_mc = w.cov[0, 1] / np.sqrt(w.cov[0, 0] * w.cov[1, 1])
    corr = cov[0, 1] / np.prod(sd)
    assert abs(corr_mc - corr) < 0.06
    assert 0.1 < w.info["acceptance_fraction"] < 0.9 and not w.info["ess_too_low"]
    if not chain:
        assert w.info["n_walkers"] == 128 and w.info["n_steps"] == 200 and ess >= 1000, w.info
    assert w.samples is not None and w.samples.shape[1] == 2


@pytest.mark.parametrize("params", [EXACT, {}], ids=["exact", "defaults"])
def test_casadi_map_equals_least_squares_without_outliers(params):
    rng = np.random.default_rng(5)
    sigma = 0.1
    pts = wall_points(rng, n=20, sigma=sigma)
    det = isotropic_detections(pts, sigma)
    (w,) = CasadiMapWallEstimator(params).estimate(det)
    (ls,) = LSQWallEstimator().estimate(det)
    assert w.model == "line" and w.info["solver_success"], w.info
    sd = np.sqrt(np.diag(w.cov))
    tol = 1e-6 if params is EXACT else 0.05  # the robust likelihood is not exactly quadratic
    assert np.all(np.abs(w.mean - ls.mean) < tol * sd), (w.mean, ls.mean, sd)
    if params is EXACT:  # the Laplace covariance is the Gauss–Newton one with the known σ
        assert np.allclose(w.cov, ls.cov * sigma**2 / ls.info["sigma2"], rtol=1e-3)


def outlier_frame(rng, frac=0.2, n=30):
    """A facade x = 20 (|y| ≤ 8) seen with range/azimuth errors, plus clutter 1.5–3 m in front of
    its upper half (parked cars, poles): a fraction ``frac`` of the LOS detections."""
    n_out = int(round(frac * n))
    y = rng.uniform(-8, 8, n - n_out)
    on = np.stack([np.full_like(y, 20.0), y], 1)
    yo = rng.uniform(2, 8, n_out)
    off = np.stack([20.0 - rng.uniform(1.5, 3.0, n_out), yo], 1)
    pts = np.concatenate([on, off])
    r, a = cartesian_to_polar(pts)
    r = r + rng.normal(0, 0.05, len(r))
    a = a + rng.normal(0, 0.004, len(a))
    k = len(r)
    return Detections(r, a, np.zeros(k, np.int8), np.ones(k), np.full(k, 0.05), np.full(k, 0.004))


def _errors(w):
    ang = np.degrees(np.arccos(min(1.0, abs(w.normal @ [-1.0, 0.0]))))
    return ang, abs(w.offset - 20.0)


def test_casadi_map_resists_20_percent_outliers_where_lsq_fails():
    fails = 0
    for seed in range(5):
        det = outlier_frame(np.random.default_rng(seed))
        ls = LSQWallEstimator().estimate(det)[0]
        (w,) = CasadiMapWallEstimator({"models": ["line"]}).estimate(det)
        ang, off = _errors(w)
        assert ang < 0.5 and off < 0.08, (seed, ang, off, w.info)
        assert 4 <= w.info["n_outliers"] <= 8, w.info["n_outliers"]
        ang_ls, off_ls = _errors(ls)
        fails += ang_ls > 2.0 or off_ls > 0.3
    assert fails >= 4, "the outliers should break the least-squares baseline"


def arc_frame(rng, kappa, n=30, length=20.0):
    """A wall curving with curvature κ through (20, 0) (tangent x = 20), seen like outlier_frame."""
    from estimators.calibration import wall_point

    theta = np.array([np.pi, 20.0, kappa])
    pts, _ = wall_point(theta, np.array([20.0, 0.0]), rng.uniform(-length / 2, length / 2, n))
    r, a = cartesian_to_polar(pts)
    r = r + rng.normal(0, 0.07, n)
    a = a + rng.normal(0, 0.01, n)
    return Detections(r, a, np.zeros(n, np.int8), np.ones(n), np.full(n, 0.07), np.full(n, 0.01))


@pytest.mark.parametrize("kappa", [0.0, 0.04, -0.04])
def test_model_selection_line_for_flat_arc_for_curved(kappa):
    for seed in range(3):
        det = arc_frame(np.random.default_rng(seed), kappa)
        (w,) = CasadiMapWallEstimator().estimate(det)
        sel = w.info["model_selection"]
        assert sel["chosen"] == w.model and sel["reason"]
        assert set(sel["values"]) == {"line", "arc"} and set(sel["bic"]) == {"line", "arc"}
        if kappa == 0:
            assert w.model == "line", sel
        else:
            assert w.model == "arc", sel
            assert abs(w.curvature - kappa) < 3 * np.sqrt(w.cov[2, 2]) + 1e-3, (w.curvature, w.cov)


def test_two_walls_in_one_frame_and_mnlos_ignored():
    rng = np.random.default_rng(2)
    a = np.stack([np.full(15, 20.0), np.linspace(2, 12, 15)], 1)  # x = 20
    b = np.stack([np.linspace(5, 15, 12), np.full(12, -8.0)], 1)  # y = −8
    pts = np.concatenate([a, b]) + rng.normal(0, 0.05, (27, 2))
    det = Detections.concat(isotropic_detections(pts, 0.05),
                            isotropic_detections(np.array([[30.0, 10.0], [12.0, -15.0]]), 0.05, MNLOS))
    for est in (CasadiMapWallEstimator(), EmceeWallEstimator({"n_steps": 400, "burn": 100})):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            walls = est.estimate(det)
        assert len(walls) == 2
        assert walls[0].offset == pytest.approx(20.0, abs=0.1) and walls[1].offset == pytest.approx(8.0, abs=0.1)
        assert sorted(walls[0].info["detection_index"]) == list(range(15))
        for w in walls:
            assert w.extent is not None and w.info["time_s"] > 0


def test_emcee_is_reproducible_and_reports_diagnostics():
    det = isotropic_detections(wall_points(np.random.default_rng(0)), 0.15)
    params = {"n_steps": 300, "burn": 50, "seed": 7}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        np.random.seed(0)
        a = EmceeWallEstimator(params).estimate(det)[0]
        np.random.seed(1)  # the global state must not matter
        b = EmceeWallEstimator(params).estimate(det)[0]
        c = EmceeWallEstimator({**params, "seed": 8}).estimate(det)[0]
    assert np.array_equal(a.samples, b.samples) and np.array_equal(a.mean, b.mean)
    assert not np.array_equal(a.samples, c.samples)
    for key in ("tau", "ess", "acceptance_fraction", "outlier_fraction", "solver_status", "model_selection",
                "noise_scale", "time_s"):
        assert key in a.info, key
    assert len(a.info["tau"]) == 3  # φ, b, log s


def test_emcee_warns_when_the_effective_sample_size_is_too_low():
    """16 walkers × 50 kept steps: ESS = 16·50/τ ≪ 400 (τ ≥ 4 here), so the ESS check warns; the
    defaults on the same wall pass it silently."""
    det = isotropic_detections(wall_points(np.random.default_rng(0)), 0.15)
    with pytest.warns(RuntimeWarning, match=r"effective sample size \d+ < min_ess = 400"):
        (w,) = EmceeWallEstimator({"n_walkers": 16, "n_steps": 60, "burn": 10}).estimate(det)
    assert w.info["ess_too_low"] and w.info["ess"] < 400 and w.info["min_ess"] == 400
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        (ok,) = EmceeWallEstimator({"seed": 4}).estimate(det)
    assert not ok.info["ess_too_low"] and ok.info["ess"] >= 1000, ok.info


def test_sampler_params_are_validated():
    with pytest.raises(ConfigError, match="burn"):
        EmceeWallEstimator({"n_steps": 100, "burn": 100})
    with pytest.raises(ConfigError, match="models"):
        CasadiMapWallEstimator({"models": []})
    with pytest.raises(ConfigError, match="outlier_fraction"):
        CasadiMapWallEstimator({"outlier_fraction": 0.7})


def test_casadi_map_reports_the_student_t_of_an_estimated_noise_scale():
    """with the noise scale estimated, the wall block is the Student-t's covariance
    Σ·ν/(ν − 2); for the Gaussian line fit ν = n − p + 1/(2σ_s²) (σ_s = 0.5: + 2 points), read off
    the Laplace variance of log s. With the scale known, the Gaussian is left as it is."""
    from estimators.robust import fit_cluster, posterior_from_fit

    sigma = 0.1
    est = CasadiMapWallEstimator({"outlier_fraction": 0.0, "wall_roughness": 0.0, "models": ["line"]})
    for n in (8, 16, 24):
        nus = []
        for seed in range(4):
            pts = wall_points(np.random.default_rng(seed), n=n, sigma=sigma)
            (w,) = est.estimate(isotropic_detections(pts, sigma))
            nu = w.info["t_dof"]
            assert w.info["t_inflation"] == pytest.approx(nu / (nu - 2))
            fit = fit_cluster(pts, np.tile(sigma**2 * np.eye(2), (n, 1, 1)), est.params, np.random.default_rng(0))
            laplace = posterior_from_fit(fit, "casadi_map")  # the Gaussian given s = ŝ
            assert np.allclose(w.mean, laplace.mean, atol=1e-9)
            assert np.allclose(w.cov, laplace.cov * nu / (nu - 2), rtol=1e-6)
            nus.append(nu)
        assert np.mean(nus) == pytest.approx(n - 2 + 2, rel=0.15), (n, nus)
    (known,) = CasadiMapWallEstimator(EXACT).estimate(isotropic_detections(pts, sigma))
    assert "t_dof" not in known.info
