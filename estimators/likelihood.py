"""Robust likelihood of LOS detections given a relay wall, with the priors of the wall posterior.

Measurement model (Sec. 4.1: LOS samples are sparse and noisy). A LOS detection x_i (2,) [m]
is a point w_i of the wall plus a detection error e_i ~ N(0, Σ_i), with Σ_i the anisotropic
Cartesian covariance of its (range, azimuth) errors (Detections.position_cov: σ_r² along the ray,
(r·σ_θ)² across it — the azimuth error dominates beyond a few metres). The along-wall position of
w_i is unknown; integrating it out (flat along the wall) leaves the signed distance δ_i(θ) of x_i
to the wall (:mod:`xnlos_core.wall`), Gaussian with the variance of Σ_i projected on the
local wall normal n_i, scaled by a noise factor s (the detector's stated errors may be off) plus
the wall's own roughness ρ (its surface departs from the model):

    σ_i² = s²·n_iᵀ Σ_i n_i + ρ².

A fraction ε of the LOS detections are outliers (points not on the wall). A share c of them is
clutter in front of the wall (parked cars, poles: the radar cannot see LOS points behind it),
uniform over a depth W [m] on the radar side and seen with the same error, so its density in δ
is Φ(δ/σ_i)/W (the uniform convolved with the noise, Φ the normal CDF); the rest (gross errors,
misclassified mNLOS echoes) is uniform over a band of width W on both sides:

    p_out(δ_i) = [c·Φ(δ_i/σ_i) + (1 − c)] / W,
    log p(x_i | θ) = log[(1 − ε)·N(δ_i; 0, σ_i²) + ε·p_out(δ_i)]   (Gaussian + outlier mixture)

(c = 0: the plain Gaussian + uniform mixture.) One-sided clutter that the model took as
symmetric would pull the wall towards the radar.

The posterior of θ = (φ, b[, κ][, log s]) multiplies the likelihood with priors: flat in φ and b
(restricted, for the sampler, to |φ − φ_ref| < π/2 — the other half-turn is the same line with
a flipped normal — and to walls passing within max(W/2, 10·σ̃) of the cluster centroid, σ̃ the
largest stated position error (std) of any point, which keeps the posterior proper: far from
the data every point is an outlier and the mixture likelihood is flat); κ ~ N(0, σ_κ²) (proper,
so the Laplace evidence of the arc carries its Occam factor); log s ~ N(0, σ_s²). With ε = 0,
s fixed and ρ = 0 this is the exact Gaussian line fit.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from types import SimpleNamespace

import numpy as np

from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.wall import NP, check_model, local_geometry

LOG_2PI = float(np.log(2 * np.pi))


@lru_cache(maxsize=1)
def casadi_ops() -> SimpleNamespace:
    """The ``ops`` namespace of :func:`xnlos_core.wall.local_geometry` for symbolic casadi
    expressions (casadi imported on first use)."""
    import casadi as ca

    def logaddexp(a, b):  # shifted by the max: exact value and derivatives on either branch
        m = ca.fmax(a, b)
        return m + ca.log(ca.exp(a - m) + ca.exp(b - m))

    def ndtr(z):
        return 0.5 * (1 + ca.erf(z / np.sqrt(2.0)))

    return SimpleNamespace(cos=ca.cos, sin=ca.sin, sqrt=ca.sqrt, log=ca.log, exp=ca.exp,
                           logaddexp=logaddexp, sum=ca.sum1, ndtr=ndtr)


@dataclass(frozen=True)
class LikelihoodConfig:
    """Hyper-parameters of the measurement model (module doc).

    outlier_fraction ε ∈ [0, 0.5); outlier_width W [m]; clutter_share c ∈ [0, 1]; wall_roughness ρ [m];
    estimate_noise_scale: sample/optimise log s (else s = 1); noise_scale_prior_std σ_s (of log s);
    curvature_prior_std σ_κ [1/m].
    """

    outlier_fraction: float = 0.1
    outlier_width: float = 4.0
    wall_roughness: float = 0.02
    estimate_noise_scale: bool = True
    noise_scale_prior_std: float = 0.5
    curvature_prior_std: float = 0.03
    clutter_share: float = 0.8

    @property
    def mixture(self) -> bool:
        return self.outlier_fraction > 0

    def hyper(self, anchor) -> np.ndarray:
        """The numeric hyper-parameters as the vector the casadi functions take (8,):
        (log(1−ε), log(ε/W), ρ², σ_κ, σ_s, a_x, a_y, c) with a the arc's anchor point [m]."""
        eps = self.outlier_fraction
        log_in = float(np.log1p(-eps))
        log_out = float(np.log(eps / self.outlier_width)) if eps > 0 else 0.0
        return np.array([log_in, log_out, self.wall_roughness**2, self.curvature_prior_std,
                         self.noise_scale_prior_std, float(anchor[0]), float(anchor[1]), self.clutter_share])


def param_names(model: str, cfg: LikelihoodConfig) -> tuple[str, ...]:
    """Names of the sampled/optimised parameters: the wall's, then log_s when estimated."""
    return check_model(model) + (("log_s",) if cfg.estimate_noise_scale else ())


def point_terms(model, mixture, phi, b, kappa, log_s, x, y, cxx, cxy, cyy, hyper, ops):
    """Per point: log-likelihood ℓ_i, the Gaussian (inlier) term log(1 − ε) + log N(δ_i; 0, σ_i²),
    δ_i and σ_i², element-wise in ``ops`` (numpy batch or casadi).
    hyper = (log(1−ε), log(ε/W), ρ², σ_κ, σ_s, a_x, a_y, c)."""
    geo = local_geometry(model, phi, b, kappa, x, y, (hyper[5], hyper[6]), ops)
    var_det = geo.gx * geo.gx * cxx + 2 * geo.gx * geo.gy * cxy + geo.gy * geo.gy * cyy
    var = ops.exp(2 * log_s) * var_det + hyper[2]
    inlier = hyper[0] - 0.5 * geo.delta * geo.delta / var - 0.5 * (LOG_2PI + ops.log(var))
    if not mixture:
        return inlier, inlier, geo.delta, var
    front = ops.ndtr(geo.delta / ops.sqrt(var))  # Φ(δ/σ)
    outlier = hyper[1] + ops.log(hyper[7] * front + (1 - hyper[7]))
    return ops.logaddexp(inlier, outlier), inlier, geo.delta, var


def log_prior(model, estimate_scale, kappa, log_s, hyper, ops):
    """log π(κ) + log π(log s): normalised Gaussians (flat, improper, in φ and b)."""
    out = 0 * log_s if estimate_scale else 0.0
    if model == "arc":
        out = out - 0.5 * (kappa / hyper[3]) ** 2 - ops.log(hyper[3]) - 0.5 * LOG_2PI
    if estimate_scale:
        out = out - 0.5 * (log_s / hyper[4]) ** 2 - ops.log(hyper[4]) - 0.5 * LOG_2PI
    return out


class WallLikelihood:
    """Posterior of one wall model given one cluster of LOS detections (module doc).

    points (N, 2) [m]; point_cov (N, 2, 2) [m²]; anchor (2,) [m]: the arc's anchor point
    (default: the centroid); phi_ref [rad] and the centroid define the sampler's support.
    ``log_prob`` is vectorised for emcee.
    """

    def __init__(self, model: str, points, point_cov, cfg: LikelihoodConfig, anchor=None,
                 phi_ref: float | None = None):
        self.model = model
        self.names = param_names(model, cfg)
        self.cfg = cfg
        x = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        c = np.asarray(point_cov, dtype=np.float64).reshape(-1, 2, 2)
        if len(x) < 2:
            raise InsufficientDataError(f"WallLikelihood: {len(x)} LOS point(s); a wall needs at least 2")
        if len(c) != len(x):
            raise InputError(f"WallLikelihood: point_cov has {len(c)} entries for {len(x)} points")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(c))):
            raise InputError("WallLikelihood: points and point_cov must be finite")
        if cfg.wall_roughness == 0 and np.any(np.linalg.eigvalsh(c)[:, 0] <= 0):
            raise InputError("WallLikelihood: with wall_roughness = 0 every LOS detection needs a positive-"
                             "definite position covariance (range_std > 0 and azimuth_std > 0)")
        self.points, self.point_cov = x, c
        self.centroid = x.mean(axis=0)
        self.anchor = self.centroid.copy() if anchor is None else np.asarray(anchor, float).reshape(2)
        self.phi_ref = phi_ref
        self.hyper = cfg.hyper(self.anchor)
        worst = float(np.sqrt(np.max(np.linalg.eigvalsh(c)[:, 1]) + cfg.wall_roughness**2))
        self.support_halfwidth = max(0.5 * cfg.outlier_width, 10.0 * worst)

    @property
    def n_params(self) -> int:
        return len(self.names)

    def _split(self, theta: np.ndarray):
        t = np.atleast_2d(np.asarray(theta, dtype=np.float64))
        kappa = t[:, 2:3] if self.model == "arc" else np.zeros_like(t[:, :1])
        log_s = t[:, -1:] if self.cfg.estimate_noise_scale else np.zeros_like(t[:, :1])
        return t, t[:, 0:1], t[:, 1:2], kappa, log_s

    def _terms(self, phi, b, kappa, log_s):
        x, c = self.points, self.point_cov
        return point_terms(self.model, self.cfg.mixture, phi, b, kappa, log_s, x[:, 0], x[:, 1],
                           c[:, 0, 0], c[:, 0, 1], c[:, 1, 1], self.hyper, NP)[:2]

    def terms(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """(ℓ (W, N), inlier term (W, N)) for a batch θ (W, P)."""
        _, phi, b, kappa, log_s = self._split(theta)
        return self._terms(phi, b, kappa, log_s)

    def log_likelihood(self, theta) -> np.ndarray:
        """Σ_i log p(x_i | θ) (W,) for a batch θ (W, P)."""
        return self.terms(theta)[0].sum(axis=-1)

    def log_prior(self, theta) -> np.ndarray:
        """log π(θ) (W,) inside the support (flat parts omitted)."""
        _, _, _, kappa, log_s = self._split(theta)
        lp = log_prior(self.model, self.cfg.estimate_noise_scale, kappa, log_s, self.hyper, NP)
        return np.broadcast_to(np.asarray(lp, dtype=np.float64), kappa.shape)[:, 0]

    def _support(self, phi, b) -> np.ndarray:
        ok = np.isfinite(phi) & np.isfinite(b)
        if self.phi_ref is not None:
            ok &= np.cos(phi - self.phi_ref) > 0
        dist = np.cos(phi) * self.centroid[0] + np.sin(phi) * self.centroid[1] + b
        return ok & (np.abs(dist) <= self.support_halfwidth)

    def in_support(self, theta) -> np.ndarray:
        """(W,) bool: |φ − φ_ref| < π/2 and the tangent line passes near the centroid (module doc)."""
        _, phi, b, _, _ = self._split(theta)
        return self._support(phi[:, 0], b[:, 0])

    def log_prob(self, theta) -> np.ndarray:
        """Log posterior (W,) up to a constant for a batch θ (W, P); −inf outside the support
        (emcee's vectorised log-probability)."""
        t, phi, b, kappa, log_s = self._split(theta)
        out = np.full(len(t), -np.inf)
        ok = self._support(phi[:, 0], b[:, 0])
        if ok.all():
            sel = slice(None)
        elif ok.any():
            sel = ok
        else:
            return out
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            ell, _ = self._terms(phi[sel], b[sel], kappa[sel], log_s[sel])
            lp = log_prior(self.model, self.cfg.estimate_noise_scale, kappa[sel], log_s[sel], self.hyper, NP)
            val = ell.sum(axis=-1) + np.reshape(np.broadcast_to(lp, kappa[sel].shape), -1)
        out[sel] = np.where(np.isfinite(val), val, -np.inf)
        return out

    def inlier_probability(self, theta) -> np.ndarray:
        """Posterior probability (N,) that each point is on the wall (not an outlier) at θ (P,)."""
        ell, inlier = self.terms(np.asarray(theta, dtype=np.float64)[None])
        return np.exp(inlier - ell)[0]
