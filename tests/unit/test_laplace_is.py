"""laplace_is wall estimator: agreement with emcee, ESS / Pareto k̂, the emcee fallback, conformance,
and the importance-sampling helpers."""
import warnings

import numpy as np
import pytest
from scipy.stats import genpareto

from estimators.emcee_wall import EmceeWallEstimator
from estimators.importance import effective_sample_size, gpd_fit, pareto_k, student_t_draws, weighted_moments
from estimators.laplace_is import LaplaceISWallEstimator
from xnlos_core import ConfigError
from xnlos_core.testing import check_component

from .test_wall_estimators import EXACT, exact_line_posterior, isotropic_detections, wall_points


def _clean_wall():
    return isotropic_detections(wall_points(np.random.default_rng(0)), 0.15)


def test_posterior_agrees_with_emcee_on_a_clean_wall():
    det = _clean_wall()
    (a,) = LaplaceISWallEstimator({"seed": 1}).estimate(det)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        (b,) = EmceeWallEstimator({"n_walkers": 32, "n_steps": 1500, "burn": 200, "seed": 1}).estimate(det)
    assert a.info["fallback"] is None and a.model == b.model == "line"
    sd = np.sqrt(np.diag(b.cov))
    assert np.all(np.abs(a.mean - b.mean) < 0.15 * sd), (a.mean - b.mean) / sd
    ratio = np.sqrt(np.diag(a.cov)) / sd
    assert np.all(np.abs(ratio - 1) < 0.12), ratio
    corr = lambda c: c[0, 1] / np.sqrt(c[0, 0] * c[1, 1])  # noqa: E731
    assert abs(corr(a.cov) - corr(b.cov)) < 0.05
    assert a.samples.shape == (4000, 2)
    assert np.allclose(a.samples.mean(0), a.mean, atol=0.05 * sd)


@pytest.mark.parametrize("seed", [3, 4])
def test_posterior_matches_the_exact_gaussian_line_posterior(seed):
    """on the exact Gaussian line model (the points of emcee's exact test) the
    importance-weighted moments equal the quadrature posterior within Monte-Carlo error (ESS)."""
    sigma = 0.15
    pts = wall_points(np.random.default_rng(11), sigma=sigma)
    (w,) = LaplaceISWallEstimator({**EXACT, "seed": seed}).estimate(isotropic_detections(pts, sigma))
    assert w.info["fallback"] is None and w.info["pareto_k"] < 0.7
    mean, cov = exact_line_posterior(pts, sigma, w.mean[0] + np.linspace(-0.2, 0.2, 40001))
    sd = np.sqrt(np.diag(cov))
    ess = w.info["ess"]
    assert ess >= 1000, w.info
    assert np.all(np.abs(w.mean - mean) < 5 * sd / np.sqrt(ess)), (w.mean, mean, sd)
    assert np.allclose(np.diag(w.cov), np.diag(cov), rtol=6 * np.sqrt(2 / ess))
    corr_is = w.cov[0, 1] / np.sqrt(w.cov[0, 0] * w.cov[1, 1])
    assert abs(corr_is - cov[0, 1] / np.prod(sd)) < 0.06


def test_reports_ess_and_pareto_k_and_is_seeded():
    det = _clean_wall()
    a = LaplaceISWallEstimator({"seed": 5}).estimate(det)[0]
    b = LaplaceISWallEstimator({"seed": 5}).estimate(det)[0]
    c = LaplaceISWallEstimator({"seed": 6}).estimate(det)[0]
    assert np.array_equal(a.samples, b.samples) and np.array_equal(a.mean, b.mean)
    assert not np.array_equal(a.samples, c.samples)
    for key in ("ess", "pareto_k", "is_ess", "is_pareto_k", "n_draws", "proposal_dof", "fallback",
                "noise_scale", "solver_status", "time_s"):
        assert key in a.info, key
    assert 1000 <= a.info["ess"] <= 4000 and a.info["pareto_k"] < 0.7


def test_a_proposal_that_misses_the_mass_falls_back_to_emcee():
    """A proposal 20× too narrow: the weights' tail is heavy (k̂ ≫ 0.7), so emcee takes over."""
    det = _clean_wall()
    params = {"proposal_scale": 0.05, "fallback_n_steps": 400, "fallback_burn": 100, "seed": 2}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        (w,) = LaplaceISWallEstimator(params).estimate(det)
    assert w.info["is_pareto_k"] > 0.7 and w.info["fallback"] == "emcee"
    assert "tau" in w.info and w.info["estimator"] == "laplace_is" and w.samples is not None
    (good,) = LaplaceISWallEstimator({"seed": 2}).estimate(det)
    assert np.all(np.abs(w.mean - good.mean) < 0.3 * np.sqrt(np.diag(good.cov)))
    (kept,) = LaplaceISWallEstimator({**params, "fallback": False}).estimate(det)
    assert kept.info["fallback"] is None and kept.info["diagnostic_failed"]


def test_conformance_and_params():
    check_component("wall_estimator", "laplace_is")
    with pytest.raises(ConfigError, match="fallback_burn"):
        LaplaceISWallEstimator({"fallback_n_steps": 100, "fallback_burn": 100})
    with pytest.raises(ConfigError, match="proposal_dof"):
        LaplaceISWallEstimator({"proposal_dof": 2})


@pytest.mark.parametrize("k", [0.2, 0.5, 0.9])
def test_gpd_fit_agrees_with_scipy(k):
    x = genpareto.rvs(k, scale=1.0, size=200, random_state=np.random.default_rng(1))
    ours, sigma = gpd_fit(x)
    ref, _, ref_sigma = genpareto.fit(x, floc=0)
    assert abs(ours - ref) < 0.05 and abs(sigma / ref_sigma - 1) < 0.05


def test_pareto_k_and_ess_separate_good_and_bad_weights():
    rng = np.random.default_rng(3)
    bounded = rng.uniform(0.5, 1.5, 4000)
    heavy = rng.pareto(1.0, 4000) + 1  # infinite mean: k = 1
    assert pareto_k(bounded) < 0 and effective_sample_size(bounded) > 3500
    assert pareto_k(heavy) > 0.7 and effective_sample_size(heavy) < 1000
    assert effective_sample_size(np.ones(10)) == pytest.approx(10)


def test_student_t_draws_and_weighted_moments():
    rng = np.random.default_rng(4)
    mean, cov = np.array([0.3, 2.0]), np.array([[0.04, 0.01], [0.01, 0.09]])
    nu = 6.0
    x, logq = student_t_draws(mean, cov, nu, 200_000, rng)
    w = np.full(len(x), 1 / len(x))
    m, c = weighted_moments(x, w, mean)
    assert np.allclose(m, mean, atol=0.003) and np.allclose(c, cov * nu / (nu - 2), rtol=0.05, atol=5e-4)
    m2 = np.einsum("ni,ij,nj->n", x - mean, np.linalg.inv(cov), x - mean)
    assert np.allclose(logq, -0.5 * (nu + 2) * np.log1p(m2 / nu))


def test_a_wide_proposal_draws_more_batches_until_the_target_ess():
    """A proposal 4× too wide: k̂ passes but 4000 draws give ESS < 1000, so further batches of the
    same proposal join until ESS ≥ target_ess; with target_ess = 0 (and min_ess = 0, else the short
    batch falls back to emcee) one batch is kept."""
    det = _clean_wall()
    (one,) = LaplaceISWallEstimator({"proposal_scale": 4.0, "target_ess": 0, "min_ess": 0, "seed": 3}).estimate(det)
    assert one.info["n_draws"] == 4000 and one.info["ess"] < 1000 and one.info["pareto_k"] < 0.7, one.info
    (w,) = LaplaceISWallEstimator({"proposal_scale": 4.0, "seed": 3}).estimate(det)
    assert w.info["fallback"] is None and w.info["ess"] >= 1000 and w.info["n_draws"] > 4000, w.info
    assert w.info["n_draws"] % 4000 == 0 and w.info["n_draws"] <= 32_000
    (good,) = LaplaceISWallEstimator({"seed": 3}).estimate(det)
    assert good.info["n_draws"] == 4000  # the default proposal reaches the target in one batch
    assert np.all(np.abs(w.mean - good.mean) < 0.2 * np.sqrt(np.diag(good.cov)))


def test_the_emcee_fallback_extends_its_chain_until_the_target_ess():
    """A fallback chain too short for target_ess (16 walkers × 100 steps) is continued, block by
    block, until its ESS reaches the target; its first steps are those of the unextended chain."""
    det = _clean_wall()
    base = {"proposal_scale": 0.05, "fallback_n_walkers": 16, "fallback_n_steps": 100, "fallback_burn": 20,
            "fallback_min_ess": 0.0, "seed": 2}
    (short,) = LaplaceISWallEstimator({**base, "target_ess": 0.0}).estimate(det)
    assert short.info["fallback"] == "emcee" and short.info["n_steps"] == 100 and short.info["ess"] < 1000
    (long,) = LaplaceISWallEstimator({**base, "fallback_max_steps": 5000}).estimate(det)
    assert long.info["ess"] >= 1000 and 100 < long.info["n_steps"] <= 5000
    assert (long.info["n_steps"] - 100) % 80 == 0  # whole blocks of n_steps − burn
    (capped,) = LaplaceISWallEstimator({**base, "fallback_max_steps": 180}).estimate(det)
    assert capped.info["n_steps"] == 180 and capped.info["ess"] < 1000
