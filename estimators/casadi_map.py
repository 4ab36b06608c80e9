"""``casadi_map`` wall estimator: robust MAP per wall with casadi/IPOPT and its Laplace covariance.

Per LOS cluster (one wall): MAP of each wall model under the anisotropic, outlier-robust
likelihood (:mod:`estimators.likelihood`), warm-started from the ``lsq`` line; the model order
is chosen by Laplace evidence (:mod:`estimators.selection`); the covariance is the inverse
Hessian of the negative log posterior at the MAP (:mod:`estimators.map_solver`), marginalised
over the noise scale: with the scale estimated, the wall block is that of the Student-t the
scale's uncertainty leaves (×ν/(ν − 2), ν from the same Laplace fit; :func:`estimators.map_solver.
student_t_cov`; ``info["t_dof"]``), so its credible regions are calibrated as emcee's. Flow and shared parameters: :mod:`estimators.robust`. ≈ 12 ms per wall
(2–4 IPOPT solves of ≈ 2 ms) once the casadi problems are built (``warm_up``, or ≈ 50 ms on the
first cluster of each padded size).
"""
from __future__ import annotations

import numpy as np

from xnlos_core.interfaces import WallEstimator
from xnlos_core.types import Detections, WallPosterior

from .map_solver import student_t_cov
from .robust import RobustWallParams, estimate_walls, fit_cluster, posterior_from_fit, warm_up
from xnlos_core.wall import MODEL_PARAMS


class CasadiMapParams(RobustWallParams):
    """Parameters of casadi_map (all shared with emcee; see RobustWallParams)."""


class CasadiMapWallEstimator(WallEstimator):
    """Robust MAP wall (line or arc, chosen by evidence) with Laplace covariance, via casadi/IPOPT."""

    Params = CasadiMapParams

    def fit_wall(self, points: np.ndarray, point_cov: np.ndarray, rng: np.random.Generator) -> WallPosterior:
        """WallPosterior of one LOS cluster: points (N, 2) [m], point_cov (N, 2, 2) [m²]."""
        fit = fit_cluster(points, point_cov, self.params, rng)
        if not self.params.estimate_noise_scale:  # known scale: the Gaussian is the posterior
            return posterior_from_fit(fit, "casadi_map")
        cov, nu = student_t_cov(fit.best.cov, len(MODEL_PARAMS[fit.chosen]))
        return posterior_from_fit(fit, "casadi_map", cov=cov,
                                  extra_info={"t_dof": nu, "t_inflation": nu / (nu - 2.0)})

    def warm_up(self, max_points: int = 64) -> int:
        """Build the casadi problems for clusters of up to ``max_points`` LOS points now, so that
        the first frames are as fast as later ones; returns how many problem shapes were built."""
        return warm_up(self.params, max_points)

    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """One WallPosterior per LOS cluster (largest first); info carries the model choice and
        criteria, solver status, Laplace regularisation, outlier fraction, noise scale, time.
        Raises InsufficientDataError with < 2 LOS points or no usable cluster."""
        return estimate_walls(detections, self.params, "CasadiMapWallEstimator", self.fit_wall)
