"""One frame's hidden points → one measurement per object: position, and radial velocity (Doppler).

Points are grouped by single linkage (cut at ``distance`` [m]); cluster c of n_c points gives

* position z_c (2,) [m], the centroid, with R_c = Σ cov_i / n_c² + floor² I [m²] (independent points),
  moved to the object's centre where the points carry their view directions (HiddenPoints.view, the
  mirrored line of sight û_i): the seen scatterers lie on the object's side facing the mirrored radar,
  so its centre lies behind their centroid, along the cluster's mean view direction û_c, by ``depth_ratio``
  times their span s_c across û_c (extreme minus least of (o_i − z_c)ᵀû_c⊥):
  z_c ← z_c + depth_ratio · s_c · û_c. A box of length L and width W seen broadside puts its centre
  W/2 behind the centroid of a face of span L, W/(2L) = 0.2 for a car; a cylinder 2R/π behind a span
  of 2R, 0.32;
* where the points carry a velocity (HiddenPoints.velocity, the observed component w_i = y_i ĝ_i of
  the hidden velocity along the mirrored line of sight ĝ_i, :mod:`xnlos_core.mirror_doppler`), the
  scalar radial measurement y_c = ĝ_cᵀ v + noise of variance s_c [m²/s²]:
  ĝ_i = w_i/|w_i| (the principal eigenvector of velocity_cov_i when w_i = 0), y_i = ĝ_iᵀ w_i,
  s_i = ĝ_iᵀ velocity_cov_i ĝ_i + doppler_floor². The points of one object see it along nearly the
  same ĝ, so the cluster takes the inverse-variance weighted mean (weights u_i = 1/s_i, each ĝ_i's
  sign turned to agree with the first point's): ĝ_c = Σu_iĝ_i/|Σu_iĝ_i|, y_c = Σu_i y_i/Σu_i,
  s_c = 1/Σu_i. A point with w_i = 0 and velocity_cov_i = 0 carries no direction and is left out.

The tracker's measurement model is then H = [[I, 0], [0, ĝ_cᵀ]] on the state (p, v) (kalman.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import HiddenPoints

from ..lsq import single_linkage


@dataclass(frozen=True)
class Measurements:
    """C objects of one frame: z (C, 2) [m], R (C, 2, 2) [m²]; Doppler: direction g (C, 2) (unit),
    y (C,) [m/s], s (C,) [m²/s²], doppler (C,) bool — False where the cluster has no velocity."""

    z: np.ndarray
    R: np.ndarray
    g: np.ndarray
    y: np.ndarray
    s: np.ndarray
    doppler: np.ndarray

    def __len__(self) -> int:
        return len(self.z)


def _directions(w: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit ĝ_i (M, 2) and a validity mask (M,) from the velocities w (M, 2) and covariances (M, 2, 2)."""
    norm = np.linalg.norm(w, axis=1)
    g = np.divide(w, norm[:, None], out=np.zeros_like(w), where=norm[:, None] > 0)
    still = norm == 0
    if still.any():  # no radial speed: the direction is where the covariance is (rank one along ĝ)
        lam, vec = np.linalg.eigh(cov[still])
        g[still] = vec[:, :, 1]
        ok = np.ones(len(w), bool)
        ok[still] = lam[:, 1] > 0
        return g, ok
    return g, np.ones(len(w), bool)


def cluster(points: HiddenPoints, distance: float, floor: float, doppler_floor: float = 0.1,
            use_doppler: bool = True, who: str = "tracker", depth_ratio: float = 0.0) -> Measurements:
    """The frame's object measurements (module docstring); ``who`` names the caller in errors."""
    m = len(points)
    if m == 0:
        e = np.empty((0, 2))
        return Measurements(e, np.empty((0, 2, 2)), e, np.empty(0), np.empty(0), np.empty(0, bool))
    labels = single_linkage(np.asarray(points.mean, np.float64), distance)
    n = np.bincount(labels).astype(np.float64)
    c = len(n)
    z = np.stack([np.bincount(labels, points.mean[:, 0]), np.bincount(labels, points.mean[:, 1])], axis=1) / n[:, None]
    if depth_ratio > 0 and points.view is not None:
        z = z + depth_ratio * _behind(np.asarray(points.mean, np.float64), np.asarray(points.view, np.float64),
                                      labels, z)
    R = np.zeros((c, 2, 2))
    np.add.at(R, labels, points.cov)
    R = R / n[:, None, None] ** 2 + floor ** 2 * np.eye(2)
    g_c, y_c, s_c, has = np.zeros((c, 2)), np.zeros(c), np.full(c, np.inf), np.zeros(c, bool)
    if use_doppler and points.velocity is not None:
        w, vcov = np.asarray(points.velocity, np.float64), np.asarray(points.velocity_cov, np.float64)
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(vcov))):
            raise InputError(f"{who}.update: points.velocity and points.velocity_cov must be finite "
                             "(m/s, m²/s²); got NaN or inf")
        g, ok = _directions(w, vcov)
        first = np.full(c, -1)
        for i in np.flatnonzero(ok)[::-1]:  # the first valid point of each cluster sets the sign
            first[labels[i]] = i
        ref = g[np.maximum(first[labels], 0)]
        sign = np.where(np.sum(g * ref, axis=1) < 0, -1.0, 1.0)
        g = g * sign[:, None]
        y = np.sum(g * w, axis=1)
        s = np.einsum("mi,mij,mj->m", g, vcov, g) + doppler_floor ** 2
        u = np.where(ok, 1.0 / s, 0.0)
        usum = np.bincount(labels, u, minlength=c)
        has = usum > 0
        gsum = np.stack([np.bincount(labels, u * g[:, 0], minlength=c), np.bincount(labels, u * g[:, 1], minlength=c)], 1)
        g_c[has] = gsum[has] / np.linalg.norm(gsum[has], axis=1, keepdims=True)
        y_c[has] = np.bincount(labels, u * y, minlength=c)[has] / usum[has]
        s_c[has] = 1.0 / usum[has]
    return Measurements(z, R, g_c, y_c, s_c, has)


def _behind(mean: np.ndarray, view: np.ndarray, labels: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(C, 2) [m]: s_c · û_c per cluster (module docstring); 0 where the mean view direction vanishes."""
    c = len(z)
    u = np.stack([np.bincount(labels, view[:, 0], minlength=c), np.bincount(labels, view[:, 1], minlength=c)], 1)
    norm = np.linalg.norm(u, axis=1, keepdims=True)
    u = np.divide(u, norm, out=np.zeros_like(u), where=norm > 0)
    across = np.sum((mean - z[labels]) * np.c_[-u[labels, 1], u[labels, 0]], axis=1)
    hi, lo = np.full(c, -np.inf), np.full(c, np.inf)
    np.maximum.at(hi, labels, across)
    np.minimum.at(lo, labels, across)
    return (hi - lo)[:, None] * u
