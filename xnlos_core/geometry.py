"""Planar (bird's-eye) geometry in the ego frame: x forward, y left, θ = atan2(y, x).

Relay walls are lines nᵀx + b = 0 with unit normal n; the sign is chosen so that b ≥ 0, i.e.
the radar at the origin lies on the non-negative side. All functions are float64.
"""
from __future__ import annotations

import numpy as np

from .errors import InputError


def polar_to_cartesian(rng: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """(r [m], θ [rad]) → points (…, 2) [m]."""
    rng = np.asarray(rng, dtype=np.float64)
    azimuth = np.asarray(azimuth, dtype=np.float64)
    return np.stack([rng * np.cos(azimuth), rng * np.sin(azimuth)], axis=-1)


def cartesian_to_polar(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (…, 2) [m] → (range [m], azimuth [rad])."""
    p = np.asarray(points, dtype=np.float64)
    return np.hypot(p[..., 0], p[..., 1]), np.arctan2(p[..., 1], p[..., 0])


def line_from_points(p0, p1) -> tuple[np.ndarray, float]:
    """Line through two distinct points as (unit normal n (2,), offset b) with b ≥ 0."""
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    d = p1 - p0
    length = float(np.hypot(*d))
    if not length > 0:
        raise InputError(f"line_from_points: the two points coincide at {p0.tolist()}; a wall needs length > 0")
    n = np.array([-d[1], d[0]]) / length
    return canonical_line(n, -float(n @ p0))


def canonical_line(normal, offset: float) -> tuple[np.ndarray, float]:
    """Normalise (n, b) to a unit normal with b ≥ 0 (radar side positive)."""
    n = np.asarray(normal, dtype=np.float64)
    norm = float(np.hypot(*n))
    if not norm > 0 or not np.isfinite(norm):
        raise InputError(f"wall normal: expected a finite non-zero 2-vector, got {n.tolist()}")
    n, b = n / norm, float(offset) / norm
    if b < 0:
        n, b = -n, -b
    return n, b


def mirror_reflect(points: np.ndarray, normal, offset: float) -> np.ndarray:
    """Reflect points across the line nᵀx + b = 0 (Eq. 7 without residual): x − 2(nᵀx + b)n.

    points: (…, 2) [m]; normal: (2,) unit; offset [m]. The map is an involution.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.hypot(*n)
    d = p @ n + float(offset)
    return p - 2.0 * d[..., None] * n


def mirror_jacobians(points: np.ndarray, phi: float, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives of Eq. 7 for n = (cos φ, sin φ).

    Returns (J_x (…, 2, 2) w.r.t. the point, J_w (…, 2, 2) w.r.t. (φ, b)).
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.array([np.cos(phi), np.sin(phi)])
    dn = np.array([-np.sin(phi), np.cos(phi)])
    d = p @ n + offset
    jx = np.broadcast_to(np.eye(2) - 2.0 * np.outer(n, n), p.shape[:-1] + (2, 2)).copy()
    # ∂/∂φ [x − 2 d n] = −2 (xᵀ dn) n − 2 d dn
    dphi = -2.0 * (p @ dn)[..., None] * n - 2.0 * d[..., None] * dn
    db = np.broadcast_to(-2.0 * n, p.shape)
    jw = np.stack([dphi, db], axis=-1)
    return jx, jw


def ray_segment_intersection(direction: np.ndarray, start, end) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from the origin along ``direction`` (…, 2) cross the segment start→end.

    Returns (t, s): the ray parameter (hit at t·direction) and the segment parameter in [0, 1]
    for a hit; rays parallel to the segment give t = s = NaN.
    """
    u = np.asarray(direction, dtype=np.float64)
    a = np.asarray(start, dtype=np.float64)
    e = np.asarray(end, dtype=np.float64) - a
    den = u[..., 0] * (-e[1]) - u[..., 1] * (-e[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[0] * (-e[1]) - a[1] * (-e[0])) / den
        s = (u[..., 0] * a[1] - u[..., 1] * a[0]) / den
    bad = np.abs(den) < 1e-12
    t = np.where(bad, np.nan, t)
    s = np.where(bad, np.nan, s)
    return t, s


def segments_intersect(p0: np.ndarray, p1: np.ndarray, q0, q1, eps: float = 1e-9) -> np.ndarray:
    """True where the open segments p0→p1 (…, 2) cross the segment q0→q1 (2,).

    Touching at the segment ends (within ``eps`` of the parameters 0 or 1) does not count, so a
    path that ends on a wall is not blocked by that wall.
    """
    p0 = np.asarray(p0, dtype=np.float64)
    d = np.asarray(p1, dtype=np.float64) - p0
    q0 = np.asarray(q0, dtype=np.float64)
    e = np.asarray(q1, dtype=np.float64) - q0
    den = d[..., 0] * e[1] - d[..., 1] * e[0]
    w = q0 - p0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[1] - w[..., 1] * e[0]) / den
        s = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / den
    ok = np.abs(den) > 1e-12
    return ok & (t > eps) & (t < 1 - eps) & (s >= -eps) & (s <= 1 + eps)
