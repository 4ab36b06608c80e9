"""Wall posterior → hidden-point mean and covariance through Eq. 7.

For a virtual point o' (mNLOS detection, covariance Σ_o') and a wall posterior p(θ):

* with posterior samples θ_s (WallPosterior.samples, S × P): o_s = R_θs(o') for every sample
  (:func:`xnlos_core.wall.mirror`, the exact map — for an arc the tangent at the point
  where the ray radar → o' meets it), and

      E[o] ≈ mean_s o_s,   Σ_o ≈ Cov_s[o_s] + J_x Σ_o' J_xᵀ,

  with J_x = ∂o/∂o' at the posterior mean (detection and wall errors independent; the
  detection term to first order, which is exact for a line: J_x = I − 2nnᵀ);
* with the Laplace Gaussian (no samples): o = R_θ̄(o'), Σ_o = J_x Σ_o' J_xᵀ + J_θ Σ_θ J_θᵀ
  (first order; J_θ analytic for a line, central differences for an arc).

Points (M, 2) [m], covariances (M, 2, 2) [m²]; the wall a 'line' or 'arc' WallPosterior.
"""
from __future__ import annotations

import numpy as np

from .errors import InputError
from .geometry import mirror_jacobians
from .types import WallPosterior
from .wall import check_model, mirror


def symmetric(c: np.ndarray) -> np.ndarray:
    """(C + Cᵀ)/2 over the last two axes (round-off asymmetry of a propagated covariance removed)."""
    return 0.5 * (c + np.swapaxes(c, -1, -2))


def point_jacobian(wall: WallPosterior, points: np.ndarray, theta: np.ndarray | None = None) -> np.ndarray:
    """J_x = ∂o/∂o' (M, 2, 2) at θ (default: the wall's mean)."""
    theta = wall.mean if theta is None else np.asarray(theta, float)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if wall.model == "line":
        n = np.array([np.cos(theta[0]), np.sin(theta[0])])
        return np.broadcast_to(np.eye(2) - 2 * np.outer(n, n), (len(p), 2, 2)).copy()
    h = 1e-6 * np.maximum(1.0, np.linalg.norm(p, axis=1))
    jac = np.empty((len(p), 2, 2))
    for k in range(2):
        e = np.zeros((len(p), 2))
        e[:, k] = h
        plus = mirror(wall.model, theta, p + e, wall.anchor)[0]
        minus = mirror(wall.model, theta, p - e, wall.anchor)[0]
        jac[:, :, k] = (plus - minus) / (2 * h[:, None])
    return jac


def wall_jacobian(wall: WallPosterior, points: np.ndarray) -> np.ndarray:
    """J_θ = ∂o/∂θ (M, 2, P) at the wall's mean (analytic for a line, central differences else)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if wall.model == "line":
        return mirror_jacobians(p, float(wall.mean[0]), float(wall.mean[1]))[1]
    return theta_jacobian(lambda theta: mirror(wall.model, theta, p, wall.anchor)[0], wall)


def theta_jacobian(f, wall: WallPosterior) -> np.ndarray:
    """∂f/∂θ (M, 2, P) at the wall's mean of f(θ (P,)) → (M, 2), by central differences with steps
    of 1e-4 posterior standard deviations (at least 1e-8·(1 + |θ|))."""
    theta = wall.mean
    sd = np.sqrt(np.clip(np.diag(wall.cov), 0, None))
    steps = np.maximum(1e-4 * sd, 1e-8 * (1.0 + np.abs(theta)))
    jac = None
    for j, h in enumerate(steps):
        e = np.zeros(len(theta))
        e[j] = h
        d = (f(theta + e) - f(theta - e)) / (2 * h)
        jac = np.empty(d.shape + (len(theta),)) if jac is None else jac
        jac[..., j] = d
    return jac


def propagate(points, point_cov, wall: WallPosterior, use_samples: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Hidden points (mean (M, 2) [m], cov (M, 2, 2) [m²]) of virtual points o' through ``wall``
    (module doc): sample-based when the wall has samples and ``use_samples``, else Laplace."""
    if not isinstance(wall, WallPosterior):
        raise InputError(f"propagate: wall must be a WallPosterior, got {type(wall).__name__}")
    check_model(wall.model)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    pc = np.asarray(point_cov, dtype=np.float64).reshape(-1, 2, 2)
    if len(pc) != len(p):
        raise InputError(f"propagate: point_cov has {len(pc)} entries for {len(p)} points")
    jx = point_jacobian(wall, p)
    det_cov = jx @ pc @ np.swapaxes(jx, -1, -2)
    if use_samples and wall.samples is not None and len(wall.samples) >= 2:
        o = mirror(wall.model, wall.samples, p, wall.anchor)[0]  # (S, M, 2)
        mean = o.mean(axis=0)
        d = o - mean
        wall_cov = np.einsum("smi,smj->mij", d, d) / (len(o) - 1)
        return mean, symmetric(wall_cov + det_cov)
    mean = mirror(wall.model, wall.mean, p, wall.anchor)[0].reshape(-1, 2)
    jw = wall_jacobian(wall, p)
    return mean, symmetric(det_cov + jw @ wall.cov @ np.swapaxes(jw, -1, -2))
