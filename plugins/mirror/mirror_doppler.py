"""Mirror Doppler: a hidden object's velocity from its virtual (mNLOS) image's velocity.

A hidden point o moves with velocity v; its virtual image o' = R_θ(o) (Eq. 7 across the wall θ)
moves with v' = J v, J = ∂o'/∂o. Eq. 7 is an involution (R_θ ∘ R_θ = id), so un-mirroring uses
the same map: v = J_x v' with J_x = ∂o/∂o' (:func:`xnlos_core.wall_propagation.point_jacobian`).
For a line wall n = (cos φ, sin φ) this is

    v = (I − 2nnᵀ) v',

independent of b; for an arc, J_x is the arc mirror's Jacobian at o' (the tangent at the ray's hit
q moves with o').

Radial velocity: a radar measures only v_r' = r̂'ᵀv' along the virtual line of sight r̂' = o'/|o'|.
With v' = J_x⁻¹ v, v_r' = gᵀv with g = J_x⁻ᵀ r̂' (for a line g = (I − 2nnᵀ) r̂', the unit direction
from the bounce point q to o): the hidden velocity's component along ĝ = g/|g| is v_r'/|g| and
its perpendicular part is not observed in one frame. :func:`unmirror_radial_velocity` returns
that observed component as the vector w = (v_r'/|g|)·ĝ.

Covariance (first order; the velocity measurement, the position o' and the wall independent):

    Σ = A Σ_meas Aᵀ + D_x Σ_o' D_xᵀ + D_θ Σ_θ D_θᵀ,

A = ∂(result)/∂(measurement) (J_x, or g/|g|² for a radial velocity), D_x = ∂/∂o' and
D_θ = ∂/∂θ by central differences (the wall's φ turns n; for a line b does not enter, and o' enters
a radial result through r̂'). Points (M, 2) [m], velocities (M, 2) [m/s], covariances [m²/s²].
"""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import WallPosterior
from xnlos_core.wall import check_model
from xnlos_core.wall_propagation import point_jacobian, symmetric, theta_jacobian


def _check(points, wall, who: str) -> np.ndarray:
    if not isinstance(wall, WallPosterior):
        raise InputError(f"{who}: wall must be a WallPosterior, got {type(wall).__name__}")
    check_model(wall.model)
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or not np.all(np.isfinite(p)):
        raise InputError(f"{who}: points must be a finite (M, 2) array of virtual points o' [m], got shape {p.shape}")
    return p


def _array(name: str, value, shape, who: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise InputError(f"{who}: {name} must be a finite array of shape {shape}, got shape {a.shape}")
    return a


def _propagated_cov(f, points, wall: WallPosterior, point_cov) -> np.ndarray:
    """D_x Σ_o' D_xᵀ + D_θ Σ_θ D_θᵀ (M, 2, 2) of f(points (M, 2), θ (P,)) → (M, 2), central differences."""
    p = np.asarray(points, dtype=np.float64)
    theta = wall.mean
    d_theta = theta_jacobian(lambda th: f(p, th), wall)
    cov = d_theta @ wall.cov @ np.swapaxes(d_theta, -1, -2)
    if point_cov is not None:
        h = 1e-4 * np.maximum(1.0, np.linalg.norm(p, axis=1))[:, None]
        d_x = np.empty((len(p), 2, 2))
        for k in range(2):
            e = np.zeros_like(p)
            e[:, k] = h[:, 0]
            d_x[:, :, k] = (f(p + e, theta) - f(p - e, theta)) / (2 * h)
        cov = cov + d_x @ point_cov @ np.swapaxes(d_x, -1, -2)
    return cov


def unmirror_velocity(points, velocity, velocity_cov, wall: WallPosterior,
                      point_cov=None) -> tuple[np.ndarray, np.ndarray]:
    """Hidden velocities v = J_x v' (M, 2) [m/s] and their covariance (M, 2, 2) [m²/s²] from the virtual
    points o' (M, 2) [m], their velocities v' (M, 2) [m/s] with covariance Σ_v' (M, 2, 2), and the
    wall posterior (module doc; ``point_cov`` Σ_o' (M, 2, 2) [m²] adds the position's share for an arc,
    none for a line). InputError for malformed arrays or a wall model other than 'line'/'arc'."""
    who = "unmirror_velocity"
    p = _check(points, wall, who)
    m = len(p)
    vp = _array("velocity", velocity, (m, 2), who)
    vc = _array("velocity_cov", velocity_cov, (m, 2, 2), who)
    pc = None if point_cov is None else _array("point_cov", point_cov, (m, 2, 2), who)

    def f(x, theta):
        return np.einsum("mij,mj->mi", point_jacobian(wall, x, theta), vp)

    jx = point_jacobian(wall, p)
    cov = jx @ vc @ np.swapaxes(jx, -1, -2) + _propagated_cov(f, p, wall, pc)
    return np.einsum("mij,mj->mi", jx, vp), symmetric(cov)


def observed_direction(points, wall: WallPosterior, theta=None) -> np.ndarray:
    """g = J_x⁻ᵀ r̂' (M, 2): v_r' = gᵀv for a hidden velocity v (module doc); |g| = 1 for a line."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    r_hat = p / np.linalg.norm(p, axis=1, keepdims=True)
    jx = point_jacobian(wall, p, theta)
    return np.linalg.solve(np.swapaxes(jx, -1, -2), r_hat[..., None])[..., 0]


def unmirror_radial_velocity(points, radial_velocity, radial_var, wall: WallPosterior,
                             point_cov=None) -> tuple[np.ndarray, np.ndarray]:
    """The observed part w (M, 2) [m/s] of each hidden velocity — its component along ĝ, the mirrored
    line of sight — and its covariance (M, 2, 2) [m²/s²], from mNLOS detections at o' (M, 2) [m] with
    radial velocity v_r' (M,) [m/s] (positive receding) of variance (M,) [m²/s²] (module doc).
    ``point_cov`` Σ_o' (M, 2, 2) [m²] adds the share of the detection's azimuth error. The component
    perpendicular to ĝ is unobserved (0 in w, no variance in the covariance): fuse frames for it."""
    who = "unmirror_radial_velocity"
    p = _check(points, wall, who)
    m = len(p)
    vr = _array("radial_velocity", radial_velocity, (m,), who)
    var = _array("radial_var", radial_var, (m,), who)
    if m and var.min() < 0:
        raise InputError(f"{who}: radial_var must be ≥ 0 [m²/s²], got min {var.min()}")
    if m and np.linalg.norm(p, axis=1).min() == 0:
        raise InputError(f"{who}: a virtual point at the radar (0, 0) has no line of sight")
    pc = None if point_cov is None else _array("point_cov", point_cov, (m, 2, 2), who)

    def gain(x, theta):  # g/|g|²: w = v_r'·g/|g|²
        g = observed_direction(x, wall, theta)
        return g / np.sum(g * g, axis=1, keepdims=True)

    a = gain(p, wall.mean)
    cov = var[:, None, None] * a[:, :, None] * a[:, None, :]
    cov = cov + _propagated_cov(lambda x, theta: vr[:, None] * gain(x, theta), p, wall, pc)
    return vr[:, None] * a, symmetric(cov)
