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
  the hidden velocity along the mirrored line of sight ĝ_i, :mod:`plugins.mirror.mirror_doppler`), the
  scalar radial measurement y_c = ĝ_cᵀ v + noise of variance s_c [m²/s²]:
  ĝ_i = w_i/|w_i| (the principal eigenvector of velocity_cov_i when w_i = 0), y_i = ĝ_iᵀ w_i,
  s_i = ĝ_iᵀ velocity_cov_i ĝ_i + doppler_floor². The points of one object see it along nearly the
  same ĝ, so the cluster takes the inverse-variance weighted mean (weights u_i = 1/s_i, each ĝ_i's
  sign turned to agree with the first point's): ĝ_c = Σu_iĝ_i/|Σu_iĝ_i|, y_c = Σu_i y_i/Σu_i,
  s_c = 1/Σu_i. A point with w_i = 0 and velocity_cov_i = 0 carries no direction and is left out.

The tracker's measurement model is then H = [[I, 0], [0, ĝ_cᵀ]] on the state (p, v) (kalman.py).

Per relay wall (``doppler_rows = "wall"``). An object seen through two relay walls is seen from two
mirrored radars, along lines of sight that may differ by tens of degrees: its points then carry two
independent components of one velocity, and the full velocity is observable in a single frame (a
rigid body's scatterers share it). One weighted mean over all of them would mix those directions
(two perpendicular ĝ_i give ĝ_c on the bisector and y_c the mean of the two projections, √2 off the
bisector's). The points of a cluster are then grouped by ``HiddenPoints.wall_index`` and each group
gives its own row (ĝ_g, y_g, s_g) by the weighted mean above, the heaviest group first. With
"cluster" (default) each cluster is one group.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import HiddenPoints

from ..lsq import single_linkage


@dataclass(frozen=True)
class Measurements:
    """C objects of one frame: z (C, 2) [m], R (C, 2, 2) [m²]; the Doppler rows of each object's update,
    direction rows_g (C, K, 2) (unit), rows_y (C, K) [m/s], rows_s (C, K) [m²/s²] — K = 1 unless per
    relay wall (module docstring), the heaviest row first, s = inf where an object has fewer rows (none:
    no velocity)."""

    z: np.ndarray
    R: np.ndarray
    rows_g: np.ndarray
    rows_y: np.ndarray
    rows_s: np.ndarray

    @property
    def g(self) -> np.ndarray:
        """(C, 2) the first (heaviest) row's direction ĝ."""
        return self.rows_g[:, 0]

    @property
    def y(self) -> np.ndarray:
        """(C,) [m/s] the first row's radial velocity."""
        return self.rows_y[:, 0]

    @property
    def s(self) -> np.ndarray:
        """(C,) [m²/s²] the first row's variance (inf: no velocity)."""
        return self.rows_s[:, 0]

    @property
    def doppler(self) -> np.ndarray:
        """(C,) bool: whether the object has a radial velocity."""
        return np.isfinite(self.rows_s[:, 0])

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
            use_doppler: bool = True, who: str = "tracker", depth_ratio: float = 0.0,
            doppler_rows: str = "cluster") -> Measurements:
    """The frame's object measurements (module docstring); ``who`` names the caller in errors;
    ``doppler_rows`` "cluster" (one radial row per cluster) or "wall" (one per relay wall)."""
    m = len(points)
    if m == 0:
        return Measurements(np.empty((0, 2)), np.empty((0, 2, 2)), np.empty((0, 1, 2)), np.empty((0, 1)),
                            np.empty((0, 1)))
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
    if use_doppler and points.velocity is not None:
        w, vcov = np.asarray(points.velocity, np.float64), np.asarray(points.velocity_cov, np.float64)
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(vcov))):
            raise InputError(f"{who}.update: points.velocity and points.velocity_cov must be finite "
                             "(m/s, m²/s²); got NaN or inf")
        g, ok = _directions(w, vcov)
        if doppler_rows == "wall":
            walls = np.asarray(points.wall_index, np.int64)
            groups = np.unique(labels * (int(walls.max()) + 1) + walls, return_inverse=True)[1]
        else:
            groups = labels
        n_g = int(groups.max()) + 1
        gg, yg, sg, ug = _radial_means(g, w, vcov, ok, groups, n_g, doppler_floor)
        owner = np.zeros(n_g, np.int64)
        owner[groups] = labels                               # the cluster of each group
        order = np.lexsort((-ug, owner))                     # by cluster, the heaviest group first
        starts = np.r_[0, np.flatnonzero(np.diff(owner[order])) + 1]   # each cluster's first group in order
        slot = np.empty(n_g, np.int64)
        slot[order] = np.arange(n_g) - np.repeat(starts, np.diff(np.r_[starts, n_g]))  # rank within its cluster
        k = int(slot.max()) + 1
        rows_g, rows_y, rows_s = np.zeros((c, k, 2)), np.zeros((c, k)), np.full((c, k), np.inf)
        valid = ug > 0
        rows_g[owner[valid], slot[valid]] = gg[valid]
        rows_y[owner[valid], slot[valid]] = yg[valid]
        rows_s[owner[valid], slot[valid]] = sg[valid]
        return Measurements(z, R, rows_g, rows_y, rows_s)
    return Measurements(z, R, np.zeros((c, 1, 2)), np.zeros((c, 1)), np.full((c, 1), np.inf))


def _radial_means(g, w, vcov, ok, groups, n_g: int, doppler_floor: float):
    """Per group of points (module docstring): ĝ (G, 2), y (G,), s (G,) [m²/s², inf without a valid
    point] and the weight Σu (G,), each ĝ_i's sign turned to agree with the group's first valid point."""
    first = np.full(n_g, -1)
    for i in np.flatnonzero(ok)[::-1]:  # the first valid point of each group sets the sign
        first[groups[i]] = i
    ref = g[np.maximum(first[groups], 0)]
    sign = np.where(np.sum(g * ref, axis=1) < 0, -1.0, 1.0)
    g = g * sign[:, None]
    y = np.sum(g * w, axis=1)
    s = np.einsum("mi,mij,mj->m", g, vcov, g) + doppler_floor ** 2
    u = np.where(ok, 1.0 / s, 0.0)
    usum = np.bincount(groups, u, minlength=n_g)
    has = usum > 0
    gsum = np.stack([np.bincount(groups, u * g[:, 0], minlength=n_g), np.bincount(groups, u * g[:, 1], minlength=n_g)], 1)
    g_out, y_out, s_out = np.zeros((n_g, 2)), np.zeros(n_g), np.full(n_g, np.inf)
    g_out[has] = gsum[has] / np.linalg.norm(gsum[has], axis=1, keepdims=True)
    y_out[has] = np.bincount(groups, u * y, minlength=n_g)[has] / usum[has]
    s_out[has] = 1.0 / usum[has]
    return g_out, y_out, s_out, usum


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
