"""Robust MAP of one wall model with casadi/IPOPT, and its Laplace approximation.

The negative log posterior −log p(θ | x) (:mod:`estimators.likelihood`) is built once per
(model, padded size, flags, solver settings) as a ``casadi.Opti`` problem whose data are Opti
parameters, and turned into a casadi Function with ``Opti.to_function``; repeated frames only
call it (≈1–3 ms per solve) instead of rebuilding the problem. Clusters are padded with
zero-weight rows up to the next power of two (≥ 8), so a handful of Functions serves every
cluster size.

The optimisation variable is scaled, θ = θ₀ + D·z, with θ₀ the warm start and D the expected
posterior widths, so IPOPT sees an O(1)-conditioned problem whether the wall is 5 m or 1 km away.

Noise scale: the joint mode of (θ, log s) shrinks s when few points constrain the wall (with two
points the residuals vanish and s → 0: the classic bias of maximum likelihood variances,
σ̂² = RSS/n instead of RSS/(n − p)). IPOPT therefore maximises the Laplace approximation of the
posterior with the wall parameters integrated out for log s — the objective adds
½ log det Σ_i r_i ∇_θδ_i ∇_θδ_iᵀ/σ_i² (Gauss–Newton information of the wall parameters, r_i the
inlier probabilities) — the REML correction; the reported Laplace covariance and evidence are
those of the true posterior at that point.

Laplace: Σ_θ = H⁻¹, H = ∇²(−log p)(θ̂) from casadi's exact (AD) Hessian. If H is not positive
definite (a direction the data do not constrain), eigenvalues below 10⁻¹²·max are raised to
that floor: the covariance becomes very wide along that direction, and ``regularised`` says so.
Laplace log evidence (flat priors on φ and b cancel between models; κ and log s priors are proper):

    log Z ≈ log p(x | θ̂) + log π(θ̂) + (P/2) log 2π − ½ log det H.

Estimated scale (:func:`student_t_cov`): the Gaussian block of the wall parameters is their
posterior *given* s = ŝ. With s estimated from a handful of points (8–24 LOS points per wall),
integrating s out leaves a Student-t with ν degrees of freedom — exactly so for the linear
Gaussian fit: ν = n − p, the classic t of regression with σ̂² = RSS/(n − p) — whose tails the
Gaussian misses (90 % ellipses then cover ≈ 82 % of true walls, against emcee's 89 %). ν is read
off the same Laplace fit: at the REML mode, ∂²(−log p)/∂(log s)² = 2(n − p) + 1/σ_s² for that
fit, so ν = 1/(2·Var(log s)) = n − p + 1/(2σ_s²) (the log s prior counts as 1/(2σ_s²) points),
and with outliers and the arc's κ prior it counts the effective inliers and parameters alike.
The reported covariance is the t's, Σ_θ·ν/(ν − 2): the moments that emcee's samples estimate.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .likelihood import LOG_2PI, WallLikelihood, casadi_ops, log_prior, point_terms

IPOPT_OK = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
_LOCK = threading.Lock()


def bucket(n: int) -> int:
    """Padded cluster size: the next power of two ≥ max(n, 8)."""
    return max(8, 1 << int(np.ceil(np.log2(max(n, 1)))))


def _neg_log_post(model, mixture, scale, theta, data, w, hyper, wrt=None):
    """−log posterior, Σ log-likelihood (casadi expressions) of θ (P,) given padded data (B, 5).

    With ``wrt`` (the symbol θ is a function of, wall parameters first) and an estimated noise
    scale, the first output is the objective of the scale-marginal MAP instead (module doc):
    −log p + ½ log det Σ_i r_i ∇δ_i ∇δ_iᵀ / σ_i² (r_i the inlier probability)."""
    import casadi as ca

    ops = casadi_ops()
    phi, b = theta[0], theta[1]
    kappa = theta[2] if model == "arc" else 0.0
    log_s = theta[theta.shape[0] - 1] if scale else 0.0
    ell, inlier, delta, var = point_terms(model, mixture, phi, b, kappa, log_s, data[:, 0], data[:, 1],
                                          data[:, 2], data[:, 3], data[:, 4], hyper, ops)
    loglik = ops.sum(w * ell)
    f = -(loglik + log_prior(model, scale, kappa, log_s, hyper, ops))
    if wrt is not None and scale:
        p = 3 if model == "arc" else 2
        jac = ca.jacobian(delta, wrt)[:, :p]
        weight = w * ops.exp(inlier - ell) / var
        info = ca.mtimes(jac.T, jac * ca.repmat(weight, 1, p))
        if model == "arc":  # the κ prior's precision (curvature is only weakly seen by few points)
            info = info + ca.diag(ca.vertcat(0, 0, 1 / hyper[3] ** 2))
        jitter = 1e-9 * (ca.trace(info) + 1e-300) * ca.DM.eye(p)
        f = f + 0.5 * ca.log(ca.det(info + jitter))
    return f, loglik


@lru_cache(maxsize=64)
def _solver(model: str, size: int, mixture: bool, scale: bool, max_iter: int, tol: float):
    """The IPOPT solve as a casadi Function for one problem shape (module doc)."""
    import casadi as ca

    n_par = (3 if model == "arc" else 2) + int(scale)
    opti = ca.Opti()
    z = opti.variable(n_par)
    data = opti.parameter(size, 5)
    w = opti.parameter(size)
    hyper = opti.parameter(8)
    th0 = opti.parameter(n_par)
    sc = opti.parameter(n_par)
    f, _ = _neg_log_post(model, mixture, scale, th0 + sc * z, data, w, hyper, wrt=z)
    opti.minimize(f)
    opti.solver("ipopt", {"print_time": False, "error_on_fail": False, "calc_lam_p": False},
                {"print_level": 0, "sb": "yes", "max_iter": int(max_iter), "tol": float(tol)})
    opti.set_value(data, np.tile([0.0, 0.0, 1.0, 0.0, 1.0], (size, 1)))
    opti.set_value(w, np.zeros(size))
    opti.set_value(hyper, np.zeros(8))
    opti.set_value(th0, np.zeros(n_par))
    opti.set_value(sc, np.ones(n_par))
    return opti.to_function(f"wall_map_{model}_{size}", [data, w, hyper, th0, sc, z], [z, f],
                            ["data", "w", "hyper", "theta0", "scale", "z0"], ["z", "f"])


@lru_cache(maxsize=64)
def _hessian_function(model: str, size: int, mixture: bool, scale: bool):
    """casadi Function θ, data → (−log p, ∇, ∇², Σ log-lik) for one problem shape (exact AD)."""
    import casadi as ca

    n_par = (3 if model == "arc" else 2) + int(scale)
    th = ca.SX.sym("theta", n_par)
    d_s = ca.SX.sym("data", size, 5)
    w_s = ca.SX.sym("w", size)
    h_s = ca.SX.sym("hyper", 8)
    f_s, ll_s = _neg_log_post(model, mixture, scale, th, d_s, w_s, h_s)
    hess, grad = ca.hessian(f_s, th)
    return ca.Function(f"wall_hess_{model}_{size}", [th, d_s, w_s, h_s], [f_s, grad, hess, ll_s])


def warm_up(models, max_points: int, mixture: bool, scale: bool, max_iter: int = 100, tol: float = 1e-8) -> int:
    """Build the casadi Functions of every padded size up to ``max_points`` for ``models`` now
    (≈30–80 ms each), so that no frame pays for a first use. Returns how many were built."""
    built = 0
    size = 8
    while True:
        for m in models:
            _solver(m, size, mixture, scale, int(max_iter), float(tol))
            _hessian_function(m, size, mixture, scale)
            built += 1
        if size >= max_points:
            return built
        size *= 2


def _padded(lik: WallLikelihood) -> tuple[np.ndarray, np.ndarray, int]:
    n = len(lik.points)
    size = bucket(n)
    data = np.tile([0.0, 0.0, 1.0, 0.0, 1.0], (size, 1))
    data[:n, :2] = lik.points
    data[:n, 2] = lik.point_cov[:, 0, 0]
    data[:n, 3] = lik.point_cov[:, 0, 1]
    data[:n, 4] = lik.point_cov[:, 1, 1]
    w = np.zeros(size)
    w[:n] = 1.0
    return data, w, size


@dataclass
class MapFit:
    """A MAP solution θ̂ (P,) with its Laplace Gaussian and diagnostics.

    neg_log_post: −log p(θ̂ | x) (up to the flat-prior constant); log_lik: Σ log p(x_i | θ̂);
    cov (P, P): H⁻¹; log_evidence: Laplace log Z (module doc); status: IPOPT return status;
    regularised: whether H needed an eigenvalue floor; iterations: IPOPT iterations.
    """

    model: str
    theta: np.ndarray
    neg_log_post: float
    log_lik: float
    cov: np.ndarray
    hessian: np.ndarray
    log_evidence: float
    status: str
    success: bool
    regularised: bool = False
    iterations: int = 0
    info: dict = field(default_factory=dict)


def hessian(lik: WallLikelihood, theta) -> tuple[float, np.ndarray, np.ndarray, float]:
    """(−log p, gradient (P,), Hessian (P, P), Σ log-lik) at θ (P,) via casadi AD."""
    cfg = lik.cfg
    data, w, size = _padded(lik)
    hfun = _hessian_function(lik.model, size, cfg.mixture, cfg.estimate_noise_scale)
    with _LOCK:
        f, g, h, ll = hfun(np.asarray(theta, float), data, w, lik.hyper)
    return float(f), np.asarray(g, float).ravel(), np.asarray(h, float), float(ll)


def laplace(h: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, float]:
    """(cov (P, P), H (P, P) symmetrised, regularised, log det H) from the Hessian H of the
    negative log posterior at the MAP (module doc)."""
    h = 0.5 * (h + h.T)
    if not np.all(np.isfinite(h)):
        raise FloatingPointError("non-finite Hessian of the negative log posterior")
    vals, vecs = np.linalg.eigh(h)
    top = max(float(np.abs(vals).max()), 1e-300)
    floor = 1e-12 * top
    regularised = bool(vals.min() <= floor)
    vals = np.maximum(vals, floor)
    cov = (vecs / vals) @ vecs.T
    return 0.5 * (cov + cov.T), h, regularised, float(np.sum(np.log(vals)))


NU_MIN = 3.0  # the t's variance needs ν > 2; below ~3 points' worth of scale information it is capped (×3)


def student_t_cov(cov: np.ndarray, n_wall: int) -> tuple[np.ndarray, float]:
    """(covariance (P, P), ν) of the wall parameters with the noise scale integrated out (module
    doc): the first ``n_wall`` rows/columns of the Laplace covariance ``cov`` (P, P) over
    (wall parameters, log s) scaled by √(ν/(ν − 2)) each (so the wall block is ×ν/(ν − 2) and the
    whole stays positive definite), ν = max(1/(2·cov[−1, −1]), NU_MIN). Only for an estimated
    scale (log s the last parameter)."""
    cov = np.asarray(cov, float)
    nu = max(1.0 / (2.0 * float(cov[-1, -1])), NU_MIN) if cov[-1, -1] > 0 else NU_MIN
    d = np.ones(len(cov))
    d[:n_wall] = np.sqrt(nu / (nu - 2.0))
    return cov * d[:, None] * d[None, :], nu


def solve_map(lik: WallLikelihood, theta0, scale, max_iter: int = 100, tol: float = 1e-8) -> MapFit:
    """MAP of ``lik`` started at θ₀ (P,) with variable scales D (P,) (module doc), plus Laplace."""
    cfg = lik.cfg
    theta0 = np.asarray(theta0, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    data, w, size = _padded(lik)
    solve = _solver(lik.model, size, cfg.mixture, cfg.estimate_noise_scale, int(max_iter), float(tol))
    with _LOCK:
        try:
            z, _ = solve(data, w, lik.hyper, theta0, scale, np.zeros(len(theta0)))
            stats = solve.stats()
        except RuntimeError as exc:  # IPOPT met NaN/inf it could not step around
            z, stats = np.zeros(len(theta0)), {"return_status": f"Evaluation_Failed ({str(exc)[:60]})"}
    theta = theta0 + scale * np.asarray(z, float).ravel()
    status = str(stats.get("return_status", "unknown"))
    success = status in IPOPT_OK and bool(np.all(np.isfinite(theta)))
    if not np.all(np.isfinite(theta)):
        theta = theta0
    f, _, h, ll = hessian(lik, theta)
    cov, h, regularised, logdet = laplace(h)
    p = len(theta)
    log_z = -f + 0.5 * p * LOG_2PI - 0.5 * logdet
    return MapFit(lik.model, theta, f, ll, cov, h, float(log_z), status, success, regularised,
                  int(stats.get("iter_count", 0)))
