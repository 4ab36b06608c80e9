"""Time-to-appearance: when a predicted path first enters a named region (a polygon in the ego frame).

A region is a simple polygon [[x, y], …] [m] (e.g. the ego lane, or the area in line of sight).
Paths are positions sampled at h_k = kδ [s]; between samples a path is taken as straight. The first
entry time is the sample time if the path starts inside, else the first crossing of the polygon's
boundary by a segment (p_{k−1}, p_k) with p_k inside, at the exact fraction s ∈ [0, 1] of that segment
where it meets the nearest edge (a + s(b − a) = c + u(d − c), the smallest s over the edges) — exact for
straight (CV) paths. Inside/outside by matplotlib's Path.contains_points (even–odd rule).

Arrival of a track (``arrival``): the mean path's entry time, NaN if it does not enter within the grid;
its interval: the 5 % and 95 % quantiles of the draws' entry times, counting a draw that does not enter
as +∞ (so the upper end is +∞ when fewer than 95 % of the draws arrive, and both ends are +∞ when fewer
than 5 % do).
"""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError


class Region:
    """A polygon ``vertices`` (V ≥ 3, 2) [m]; closed implicitly."""

    def __init__(self, vertices):
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.all(np.isfinite(v)):
            raise InputError(f"Region: vertices must be a finite [[x, y], …] list of ≥ 3 points [m], got shape {v.shape}")
        area = 0.5 * np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
        if abs(area) == 0:
            raise InputError("Region: the polygon's vertices are collinear (zero area)")
        from matplotlib.path import Path  # here: matplotlib costs ~0.3 s, and importing the kalman tracker
        # (every `xnlos` start registers it) must not load it

        self.vertices = v
        self._path = Path(v)
        self._c, self._d = v, np.roll(v, -1, axis=0)

    def contains(self, points) -> np.ndarray:
        """Inside mask (…) of points (…, 2) [m]."""
        p = np.asarray(points, dtype=np.float64)
        return self._path.contains_points(p.reshape(-1, 2)).reshape(p.shape[:-1])

    def first_entry(self, paths, step: float) -> np.ndarray:
        """Entry times (N,) [s] (NaN: never) of paths (N, G, 2) [m] sampled every ``step`` [s]."""
        paths = np.asarray(paths, dtype=np.float64)
        inside = self.contains(paths)                                    # (N, G)
        hit = inside.any(axis=1)
        k = np.argmax(inside, axis=1)
        out = np.full(len(paths), np.nan)
        out[hit & (k == 0)] = 0.0
        cross = np.flatnonzero(hit & (k > 0))
        if len(cross):
            a, b = paths[cross, k[cross] - 1], paths[cross, k[cross]]
            out[cross] = (k[cross] - 1 + self._fraction(a, b)) * step
        return out

    def _fraction(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Smallest s ∈ [0, 1] (N,) where segment a→b (N, 2) meets an edge; 1 if none (numerically)."""
        r = (b - a)[:, None, :]                                         # (N, 1, 2)
        e = (self._d - self._c)[None]                                   # (1, E, 2)
        w = self._c[None] - a[:, None, :]                               # (N, E, 2)
        den = r[..., 0] * e[..., 1] - r[..., 1] * e[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den
            u = (w[..., 0] * r[..., 1] - w[..., 1] * r[..., 0]) / den
        ok = (den != 0) & (s >= 0) & (s <= 1) & (u >= 0) & (u <= 1)
        return np.min(np.where(ok, s, 1.0), axis=1)


def arrival(region: Region, mean_path, draws, step: float, t0: float) -> tuple[float, np.ndarray]:
    """(arrival [s], interval (2,) [s]) in absolute time (``t0`` + entry), from the mean path (G, 2)
    and the draws (D, G, 2) sampled every ``step`` [s] (module docstring)."""
    t_mean = region.first_entry(np.asarray(mean_path)[None], step)[0]
    t_draws = region.first_entry(draws, step)
    t_draws = np.where(np.isnan(t_draws), np.inf, t_draws)
    lo, hi = np.quantile(t_draws, [0.05, 0.95], method="inverted_cdf")
    return t0 + t_mean, t0 + np.array([lo, hi])
