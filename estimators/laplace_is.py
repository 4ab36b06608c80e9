"""``laplace_is`` wall estimator: the casadi MAP's Laplace approximation corrected by importance
sampling, with a fallback to emcee when the correction cannot be trusted.

Per LOS cluster: the MAP fits and model choice of :mod:`estimators.robust` (as casadi_map and
emcee), then, on the chosen model's posterior p(θ | x) over θ = (φ, b[, κ][, log s]) — the same
log-probability emcee samples (:meth:`estimators.likelihood.WallLikelihood.log_prob`):

1. proposal q = t_ν(θ̂, c²·H⁻¹): a Student-t (``proposal_dof`` ν, default 5) around the MAP θ̂
   with the Laplace covariance H⁻¹ scaled by ``proposal_scale`` c (heavy tails cover the t the
   unknown noise scale leaves in the wall parameters, :func:`estimators.map_solver.student_t_cov`);
2. ``n_draws`` draws, self-normalised weights w ∝ p/q (:mod:`estimators.importance`); while the
   ESS is below ``target_ess`` (1000) and k̂ passes, another batch of ``n_draws`` from the same
   proposal joins them (pooled weights), up to ``max_draws`` — a wide but valid proposal (an arc's
   curvature, a noise scale the data barely fix) then still reaches the target ESS;
3. diagnostics: ESS = (Σw)²/Σw² and the PSIS Pareto k̂ of the largest weights;
4. if k̂ > ``max_pareto_k`` (0.7) or ESS < ``min_ess``: fallback — emcee (``fallback_n_walkers``
   × ``fallback_n_steps`` = 128 × 200, 60 burn-in: ESS 2031–2659 per wall at ≈ 100 ms on the
   calibration frames against 16 × 2000's 1045–2095 at ≈ 740 ms (2 shared cores); τ ≈ 8–11
   steps; it warns below ``fallback_min_ess``; emcee's own defaults since the fast path;
   :class:`estimators.emcee_wall.EmceeWallEstimator`; a chain whose ESS is below ``target_ess``
   is continued from where its walkers are, 140 steps at a time, up to ``fallback_max_steps``,
   so the fallback's walls reach the same ESS as the importance-sampled ones)
   runs in-process on the same cluster fit, from the same MAP; info then says ``fallback: "emcee"`` and keeps the failed
   k̂ and ESS (``is_pareto_k``, ``is_ess``);
5. otherwise the WallPosterior's mean and cov are the weighted moments (φ averaged on the
   circle), ``samples`` are ``max_samples`` draws by systematic resampling.

info: ``ess`` (IS ESS, or emcee's ESS after a fallback), ``pareto_k``, ``is_ess``,
``is_pareto_k``, ``n_draws``, ``proposal_dof``, ``proposal_scale``, ``fallback`` (None or
"emcee"), ``sample_time_s``, plus the MAP/selection keys every probabilistic estimator reports.
Every draw comes from ``seed`` (the wall's generator; emcee's RandomState is set from it).
"""
from __future__ import annotations

import time

import numpy as np
from pydantic import Field, model_validator

from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.interfaces import WallEstimator
from xnlos_core.types import Detections, WallPosterior

from .emcee_wall import EmceeParams, EmceeWallEstimator
from .importance import (effective_sample_size, normalised_weights, pareto_k, resample, student_t_draws,
                         weighted_moments)
from .robust import ClusterFit, RobustWallParams, estimate_walls, fit_cluster, posterior_from_fit, warm_up


class LaplaceISParams(RobustWallParams):
    """Parameters of laplace_is (proposal, diagnostics thresholds, plus RobustWallParams)."""

    n_draws: int = Field(4000, ge=100, le=10_000_000, description="importance draws per wall (first batch)")
    target_ess: float = Field(1000.0, ge=0, le=1e9, description="draw further batches of n_draws while the "
                              "importance ESS is below this (and k̂ passes), up to max_draws")
    max_draws: int = Field(32_000, ge=100, le=100_000_000, description="most importance draws per wall")
    proposal_dof: float = Field(5.0, gt=2, le=1e6, description="degrees of freedom ν of the Student-t "
                                "proposal (large: Gaussian)")
    proposal_scale: float = Field(1.2, gt=0, le=100, description="factor c on the Laplace standard "
                                  "deviations in the proposal's scale matrix")
    max_pareto_k: float = Field(0.7, gt=0, le=10, description="fall back to emcee when the Pareto k̂ "
                                "of the weights exceeds this")
    min_ess: float = Field(1000.0, ge=0, le=1e9, description="fall back to emcee when the importance ESS "
                           "is below this once max_draws are drawn (the default equals target_ess: every "
                           "wall gets ESS ≥ 1000 from one sampler or the other)")
    fallback: bool = Field(True, description="run emcee when a diagnostic fails (else keep the IS "
                           "result and only report it)")
    fallback_n_walkers: int = Field(128, ge=8, le=4096, description="emcee walkers of the fallback")
    fallback_n_steps: int = Field(200, ge=20, le=10_000_000, description="emcee steps of the fallback, "
                                  "burn-in included")
    fallback_burn: int = Field(60, ge=0, le=10_000_000, description="emcee burn-in steps of the fallback")
    fallback_max_steps: int = Field(1000, ge=20, le=10_000_000, description="the fallback's chain is "
                                    "extended while its ESS is below target_ess, up to this many steps")
    fallback_min_ess: float = Field(400.0, ge=0, le=1e9, description="the fallback warns when its "
                                    "effective sample size is below this (EmceeParams.min_ess)")
    max_samples: int = Field(4000, ge=10, le=10_000_000, description="resampled draws kept in "
                             "WallPosterior.samples")

    @model_validator(mode="after")
    def _burn_below_steps(self):
        if self.fallback_burn >= self.fallback_n_steps:
            raise ValueError(f"fallback_burn ({self.fallback_burn}) must be smaller than fallback_n_steps "
                             f"({self.fallback_n_steps})")
        return self


def importance_posterior(fit: ClusterFit, params: LaplaceISParams, rng: np.random.Generator):
    """(mean (P,), cov (P, P), resampled draws (max_samples, P), diagnostics) of the chosen
    model's posterior by Laplace + Student-t importance sampling (module doc, steps 1–3).
    Raises InsufficientDataError when no proposal draw has a finite posterior."""
    t0 = time.perf_counter()
    lik = fit.likelihoods[fit.chosen]
    mf = fit.best
    scale = params.proposal_scale**2 * mf.cov
    draws, log_q = student_t_draws(mf.theta, scale, params.proposal_dof, params.n_draws, rng)
    log_p = lik.log_prob(draws)
    while True:
        try:
            w = normalised_weights(log_p, log_q)
        except InputError as exc:
            raise InsufficientDataError(
                f"laplace_is wall posterior ({lik.model}): none of {len(draws)} draws around the MAP "
                f"θ = {np.round(mf.theta, 6).tolist()} lies inside the posterior's support") from exc
        if (effective_sample_size(w) >= params.target_ess or len(draws) + params.n_draws > params.max_draws
                or pareto_k(w) > params.max_pareto_k):
            break
        # a valid but wide proposal: ESS grows in proportion to the draws (same proposal, pooled weights)
        more, more_q = student_t_draws(mf.theta, scale, params.proposal_dof, params.n_draws, rng)
        draws, log_q = np.concatenate([draws, more]), np.concatenate([log_q, more_q])
        log_p = np.concatenate([log_p, lik.log_prob(more)])
    ess = effective_sample_size(w)
    k_hat = pareto_k(w)
    mean, cov = weighted_moments(draws, w, mf.theta)
    kept = draws[resample(w, params.max_samples, rng)]
    diag = {"ess": ess, "pareto_k": k_hat, "is_ess": ess, "is_pareto_k": k_hat, "n_draws": len(draws),
            "proposal_dof": params.proposal_dof, "proposal_scale": params.proposal_scale,
            "sample_time_s": time.perf_counter() - t0}
    return mean, cov, kept, diag


class LaplaceISWallEstimator(WallEstimator):
    """MAP + Laplace, corrected by Student-t importance sampling (ESS, Pareto k̂), emcee fallback."""

    Params = LaplaceISParams

    def _emcee(self) -> EmceeWallEstimator:
        shared = RobustWallParams.model_fields.keys()
        return EmceeWallEstimator(EmceeParams(**{k: getattr(self.params, k) for k in shared},
                                              n_walkers=self.params.fallback_n_walkers,
                                              n_steps=self.params.fallback_n_steps, burn=self.params.fallback_burn,
                                              max_samples=self.params.max_samples,
                                              min_ess=self.params.fallback_min_ess,
                                              target_ess=self.params.target_ess,
                                              max_steps=self.params.fallback_max_steps))

    def fit_wall(self, points: np.ndarray, point_cov: np.ndarray, rng: np.random.Generator) -> WallPosterior:
        """WallPosterior with samples for one LOS cluster: points (N, 2) [m], point_cov (N, 2, 2) [m²]."""
        fit = fit_cluster(points, point_cov, self.params, rng)
        mean, cov, kept, diag = importance_posterior(fit, self.params, rng)
        failed = diag["pareto_k"] > self.params.max_pareto_k or diag["ess"] < self.params.min_ess
        if failed and self.params.fallback:
            extra = {k: diag[k] for k in ("is_ess", "is_pareto_k", "n_draws", "proposal_dof", "proposal_scale")}
            extra.update({"pareto_k": diag["pareto_k"], "fallback": "emcee",
                          "is_time_s": diag["sample_time_s"]})
            return self._emcee().posterior_of(fit, rng, estimator="laplace_is", extra_info=extra)
        return posterior_from_fit(fit, "laplace_is", mean=mean, cov=cov, samples=kept,
                                  extra_info={**diag, "fallback": None, "diagnostic_failed": bool(failed)})

    def warm_up(self, max_points: int = 64) -> int:
        """Build the casadi problems for clusters of up to ``max_points`` LOS points now, so that
        the first frames are as fast as later ones; returns how many problem shapes were built."""
        return warm_up(self.params, max_points)

    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """One sampled WallPosterior per LOS cluster (largest first); info carries the model
        choice, ESS, Pareto k̂, fallback, outlier fraction, solver status and time. Raises
        InsufficientDataError with < 2 LOS points or no usable cluster."""
        return estimate_walls(detections, self.params, "LaplaceISWallEstimator", self.fit_wall)
