"""``emcee`` wall estimator: posterior samples of each wall with an affine-invariant ensemble.

Per LOS cluster: the casadi MAP fits and model choice of :mod:`estimators.robust`, then
emcee (Foreman-Mackey et al. 2013) on the chosen model's posterior (:mod:`estimators.likelihood`;
the noise scale log s is sampled and marginalised):

* walkers start in a small Gaussian ball around the MAP, θ̂ + ``init_scale``·L·ξ with
  L Lᵀ the Laplace covariance (redrawn if outside the prior support);
* the log-probability is vectorised (one numpy call per half-ensemble, ``vectorize=True``);
* moves: differential evolution (``DEMove``; τ ≈ 10–20 steps on these 3–4-D posteriors) or
  emcee's default stretch move (τ ≈ 30–40). Not ``DESnookerMove``: in emcee 3.1.6 it scales its
  direction by 1/√|x − z| instead of 1/|x − z| and its proposal is not reversible — mixed in at
  20 % it shrank our posteriors' standard deviations by ≈ 9 % (alone by ≈ 40 %) against a long
  stretch-move reference;
* every draw comes from ``seed``: the sampler's RandomState is set from the wall's generator
  (``sampler.random_state``), never from numpy's global state;
* diagnostics in ``info``: integrated autocorrelation time τ per parameter
  (``get_autocorr_time(tol=0)`` after burn-in — no emcee log line: the ESS check below replaces
  emcee's 50·τ rule; emcee averages the autocorrelation over the
  walkers, so 128 walkers estimate τ from a chain of ≈ 14 τ), effective sample size
  ESS = n_walkers·(n_steps − burn)/max τ, mean acceptance fraction, ``ess_too_low``; a
  RuntimeWarning when ESS < ``min_ess`` (default 400: the Monte-Carlo error of a posterior mean is
  then ≤ σ/√400 = 5 % of its posterior σ, and of a 90 % region's coverage
  √(0.9·0.1/400) ≈ 1.5 points). This replaces the earlier "chain ≥ 50·τ" rule, which the short
  chains of many walkers below fail although their ESS is in the thousands.

Defaults: 128 walkers × 200 steps, 60 burn-in — many walkers and few steps,
because emcee's per-step overhead (not the vectorised log-probability) dominated 16 × 2000: on
the 200 frontier frames τ ≈ 7–12 steps, ESS ≥ 1342 (median 2586) per wall at 144 ms, against
16 × 2000's ESS ≥ 296 (median 2128) at 601 ms, with the same coverage (90 % total 0.859 vs
0.855; benchmarks/wall_frontier.md, 2 loaded cores). The WallPosterior's
mean and cov are the sample moments after burn-in; ``samples`` keeps up to ``max_samples`` evenly
thinned draws of the wall parameters for propagation (Eq. 7) and plots.
"""
from __future__ import annotations

import time
import warnings
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from xnlos_core.errors import InsufficientDataError
from xnlos_core.interfaces import WallEstimator
from xnlos_core.types import Detections, WallPosterior

from .likelihood import WallLikelihood
from .map_solver import MapFit
from .robust import ClusterFit, RobustWallParams, estimate_walls, fit_cluster, posterior_from_fit, warm_up


class EmceeParams(RobustWallParams):
    """Parameters of the emcee wall estimator (sampler settings + RobustWallParams)."""

    n_walkers: int = Field(128, ge=8, le=4096, description="ensemble size (≥ 2× the parameter count)")
    n_steps: int = Field(200, ge=20, le=10_000_000, description="steps per walker, burn-in included")
    burn: int = Field(60, ge=0, le=10_000_000, description="steps discarded as burn-in")
    moves: Literal["de", "stretch"] = Field("de", description="proposal: differential evolution (DEMove) "
                                            "or the stretch move")
    init_scale: float = Field(0.1, gt=0, le=10, description="radius of the initial ball in Laplace σ")
    max_samples: int = Field(4000, ge=10, le=10_000_000, description="posterior draws kept in "
                             "WallPosterior.samples")
    min_ess: float = Field(400.0, ge=0, le=1e9, description="warn when the effective sample size "
                           "n_walkers·(n_steps − burn)/max τ is below this (0: never)")
    target_ess: float = Field(0.0, ge=0, le=1e9, description="continue the chain, n_steps − burn steps "
                              "at a time, while its ESS is below this, up to max_steps (0: never; the "
                              "first n_steps are the same either way)")
    max_steps: int = Field(1000, ge=20, le=10_000_000, description="most steps per walker when "
                           "target_ess extends the chain")

    @model_validator(mode="after")
    def _burn_below_steps(self):
        if self.burn >= self.n_steps:
            raise ValueError(f"burn ({self.burn}) must be smaller than n_steps ({self.n_steps})")
        return self


def _initial_ball(lik: WallLikelihood, fit: MapFit, n_walkers: int, scale: float,
                  rng: np.random.Generator) -> np.ndarray:
    """(n_walkers, P) start positions θ̂ + scale·L·ξ inside the prior support."""
    p = len(fit.theta)
    vals, vecs = np.linalg.eigh(0.5 * (fit.cov + fit.cov.T))
    root = vecs * np.sqrt(np.clip(vals, 0, None))
    out = fit.theta + scale * rng.standard_normal((n_walkers, p)) @ root.T
    for _ in range(20):
        bad = ~np.isfinite(lik.log_prob(out))
        if not bad.any():
            break
        out[bad] = fit.theta + 0.5 * scale * rng.standard_normal((int(bad.sum()), p)) @ root.T
        scale *= 0.5
    bad = ~np.isfinite(lik.log_prob(out))
    if bad.any():  # a posterior too narrow for the Laplace root: a tiny relative jitter
        out[bad] = fit.theta * (1 + 1e-9 * rng.standard_normal((int(bad.sum()), p))) + \
            1e-12 * rng.standard_normal((int(bad.sum()), p))
    return out


def sample_posterior(lik: WallLikelihood, fit: MapFit, params: EmceeParams,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, dict]:
    """Run emcee on ``lik`` from around ``fit`` (module doc).

    Returns (chain after burn-in (n_walkers·(n_steps − burn), P), thinned samples (≤ max_samples,
    P), diagnostics {tau, ess, acceptance_fraction, n_walkers, n_steps, burn, moves, ess_too_low, min_ess,
    sample_time_s}).
    Raises InsufficientDataError when the MAP lies outside the sampler's support or no independent
    initial ensemble fits inside it (points that do not determine a wall direction).
    """
    import emcee
    from emcee.ensemble import walkers_independent  # the check run_mcmc would fail with a bare ValueError

    t0 = time.perf_counter()
    p = lik.n_params
    n_walkers = max(params.n_walkers, 2 * p)
    moves = None
    if params.moves == "de":
        moves = emcee.moves.DEMove()
    sampler = emcee.EnsembleSampler(n_walkers, p, lik.log_prob, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(int(rng.integers(2**32 - 1))).get_state()
    if not np.isfinite(lik.log_prob(fit.theta[None])[0]):
        # IPOPT is unconstrained: on points that do not pin down a direction (a blob) the MAP can
        # turn ≥ 90° from the TLS line, outside the sampler's support, where no walker can start.
        raise InsufficientDataError(
            f"emcee wall posterior ({lik.model}): the MAP θ = {np.round(fit.theta, 6).tolist()} lies outside the "
            f"sampler's support (|φ − φ_ref| < π/2, the line within {lik.support_halfwidth:.3g} m of the points' "
            f"centroid); the {len(lik.points)} points (spread {float(np.ptp(lik.points, axis=0).max()):.3g} m) "
            "do not determine a wall direction")
    start = _initial_ball(lik, fit, n_walkers, params.init_scale, rng)
    if not walkers_independent(start):
        raise InsufficientDataError(
            f"emcee wall posterior ({lik.model}): could not place {n_walkers} linearly independent walkers "
            f"inside the posterior's support around the MAP θ = {np.round(fit.theta, 6).tolist()}")
    sampler.run_mcmc(start, params.n_steps, progress=False)
    n_steps = params.n_steps
    tau, ess = _ess(sampler, params.burn, n_walkers, n_steps)
    while ess < params.target_ess and n_steps < params.max_steps:  # extend from where the walkers are
        more = min(params.n_steps - params.burn, params.max_steps - n_steps)
        sampler.run_mcmc(None, more, progress=False)
        n_steps += more
        tau, ess = _ess(sampler, params.burn, n_walkers, n_steps)
    chain = sampler.get_chain(discard=params.burn, flat=True)
    n_kept = n_steps - params.burn
    acc = float(np.mean(sampler.acceptance_fraction))
    low = not (ess >= params.min_ess)
    if low:
        warnings.warn(
            f"emcee wall posterior ({lik.model}): effective sample size {ess:.0f} < min_ess = "
            f"{params.min_ess:g} ({n_walkers} walkers × {n_kept} steps after burn-in, τ = "
            f"{np.round(tau, 1).tolist()} steps); posterior moments and credible regions are unreliable — "
            "raise n_walkers or n_steps", RuntimeWarning, stacklevel=3)
    stride = max(1, int(np.ceil(len(chain) / params.max_samples)))
    diag = {"tau": tau.tolist(), "ess": ess, "acceptance_fraction": acc, "n_walkers": n_walkers,
            "n_steps": n_steps, "target_ess": params.target_ess, "burn": params.burn, "moves": params.moves,
            "ess_too_low": bool(low), "min_ess": params.min_ess, "sample_time_s": time.perf_counter() - t0}
    return chain, chain[::stride], diag


def _ess(sampler, burn: int, n_walkers: int, n_steps: int) -> tuple[np.ndarray, float]:
    """(τ per parameter [steps], ESS = n_walkers·(n_steps − burn)/max τ) of the chain so far."""
    tau = np.asarray(sampler.get_autocorr_time(discard=burn, quiet=True, tol=0), dtype=np.float64)
    tau_max = float(np.nanmax(tau)) if np.isfinite(tau).any() else float("inf")
    n = n_walkers * (n_steps - burn)
    return tau, (float(n / tau_max) if tau_max > 0 else float(n))


class EmceeWallEstimator(WallEstimator):
    """Posterior samples of each wall (model chosen by evidence) with emcee, started at the casadi MAP."""

    Params = EmceeParams

    def fit_wall(self, points: np.ndarray, point_cov: np.ndarray, rng: np.random.Generator) -> WallPosterior:
        """WallPosterior with samples for one LOS cluster: points (N, 2) [m], point_cov (N, 2, 2) [m²]."""
        fit = fit_cluster(points, point_cov, self.params, rng)
        return self.posterior_of(fit, rng)

    def posterior_of(self, fit: ClusterFit, rng: np.random.Generator, estimator: str = "emcee",
                     extra_info: dict | None = None) -> WallPosterior:
        """Sampled WallPosterior of an already fitted cluster (the chosen model's posterior, from
        around its MAP); ``estimator`` and ``extra_info`` go into info (used by laplace_is's fallback)."""
        lik = fit.likelihoods[fit.chosen]
        chain, kept, diag = sample_posterior(lik, fit.best, self.params, rng)
        mean = chain.mean(axis=0)
        # φ may straddle ±π: average it on the circle.
        mean[0] = fit.best.theta[0] + float(np.mean(np.angle(np.exp(1j * (chain[:, 0] - fit.best.theta[0])))))
        centred = chain - mean
        centred[:, 0] = np.angle(np.exp(1j * centred[:, 0]))
        cov = centred.T @ centred / max(len(chain) - 1, 1)
        return posterior_from_fit(fit, estimator, mean=mean, cov=cov, samples=kept,
                                  extra_info={**diag, **(extra_info or {})})

    def warm_up(self, max_points: int = 64) -> int:
        """Build the casadi problems for clusters of up to ``max_points`` LOS points now, so that
        the first frames are as fast as later ones; returns how many problem shapes were built."""
        return warm_up(self.params, max_points)

    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """One sampled WallPosterior per LOS cluster (largest first); info carries the model choice,
        τ, ESS, acceptance fraction, outlier fraction, solver status and time. Raises
        InsufficientDataError with < 2 LOS points or no usable cluster."""
        return estimate_walls(detections, self.params, "EmceeWallEstimator", self.fit_wall)
