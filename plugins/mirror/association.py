"""Wall association (Sec. 4.1): anchor each mNLOS detection to its relay wall, and each wall to the
LOS detections that support it. Shared by the ``mirror`` and ``residual_mirror`` reconstructors.

Anchoring (geometric consistency, "the most plausible LOS cluster"): a virtual point o' is seen
along the ray radar → o' after one specular bounce, so its wall is the one that ray crosses
between the radar (origin) and o'. Wall j is crossed when the segment origin → o' meets its
supported segment (``WallPosterior.extent`` lengthened by ``margin`` [m] at both ends; a wall
without extent is an unbounded line); for an 'arc' the crossing is the ray's hit q on the arc,
inside the extent when q's coordinate along the tangent line lies between the extent ends' (±
margin). Of several crossed walls the first along the ray wins (the wave hits it first) — but a
crossing inside a wall's observed extent beats any crossing only within its margin: the ray radar →
o' into a side street passes just beyond the near building's corner, within the margin of that
building's facade, and the facade's seen end is the corner itself, not a gap in sparse detections.

Fallback when no wall is crossed: ``"nearest"`` takes the wall with o' on its far side (signed
distance δ(o') < 0, δ = nᵀo' + b for a line) that is closest to o'; ``"drop"`` leaves o'
unanchored. Unanchored points (no crossing and, with "nearest", no wall in front of them either)
get wall index −1; :func:`anchor_points` returns their indices and logs them — callers report
them, never drop them silently.

Support (the LOS-cluster view of a wall): the LOS points within ``distance`` [m] of the wall
(|δ|) whose coordinate along the wall lies inside the extent ± ``margin``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.geometry import ray_segment_intersection
from xnlos_core.numerics import snap
from xnlos_core.types import WallPosterior

from xnlos_core.wall import ray_hits, signed_distance

log = logging.getLogger(__name__)
FALLBACKS = ("nearest", "drop")


def _points(points, who: str) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.size == 0:
        return p.reshape(0, 2)
    if p.ndim != 2 or p.shape[1] != 2 or not np.all(np.isfinite(p)):
        raise InputError(f"{who}: points must be a finite (K, 2) array [m], got shape {p.shape}")
    return p


def crossing_parameters(points: np.ndarray, walls: list[WallPosterior], margin: float) -> np.ndarray:
    """(K, J) ray parameter t ∈ (0, 1) where the segment origin → point (points (K, 2) [m])
    crosses wall j's extent lengthened by ``margin`` [m] (its line when extent is None); +inf
    where it does not cross."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = np.full((len(pts), len(walls)), np.inf)
    for j, w in enumerate(walls):
        n, b = w.normal, w.offset
        u = np.array([-n[1], n[0]])
        if w.model == "arc":
            t = ray_hits("arc", w.mean, pts, w.anchor)[0]
            if w.extent is None:
                inside = np.ones(len(pts), dtype=bool)
            else:
                along = (w.extent - w.tangent_point) @ u
                with np.errstate(invalid="ignore"):
                    hit_along = (t[:, None] * pts - w.tangent_point) @ u
                    inside = (hit_along >= along.min() - margin) & (hit_along <= along.max() + margin)
        elif w.extent is None:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -b / (pts @ n)
            inside = np.ones(len(pts), dtype=bool)
        else:
            along = w.extent @ u
            lo, hi = along.min() - margin, along.max() + margin
            if not hi > lo:
                continue
            t, s = ray_segment_intersection(pts, -b * n + lo * u, -b * n + hi * u)
            with np.errstate(invalid="ignore"):
                inside = (s >= 0) & (s <= 1)
        with np.errstate(invalid="ignore"):
            ok = inside & (t > 0) & (t < 1)
        out[ok, j] = t[ok]
    return out


def signed_distances(points: np.ndarray, walls: list[WallPosterior]) -> np.ndarray:
    """(K, J) signed distance δ [m] of each point to each wall (positive on the radar side)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if not walls:
        return np.empty((len(pts), 0))
    return np.stack([pts @ w.normal + w.offset if w.model == "line" else
                     signed_distance(w.model, w.mean, pts, w.anchor).reshape(-1) for w in walls], axis=1)


@dataclass(frozen=True)
class Anchoring:
    """Result of :func:`anchor_points`.

    wall_index (K,) int: the wall of each point, −1 where unanchored; via (K,) str: "ray" (its
    ray crosses the wall), "nearest" (fallback) or "none"; unanchored (M,) int: indices of the
    points with wall_index −1.
    """

    wall_index: np.ndarray
    via: np.ndarray
    unanchored: np.ndarray


def anchor_points(points, walls: list[WallPosterior], margin: float = 2.0, fallback: str = "nearest",
                  who: str = "anchor_points", index=None) -> Anchoring:
    """Anchor virtual points o' (K, 2) [m] to ``walls`` (module doc); logs the unanchored ones
    (as ``index[i]`` when the caller's indices ``index`` (K,), e.g. into its detections, are given).

    Raises InputError for a bad ``points`` array or an unknown ``fallback``.
    """
    if fallback not in FALLBACKS:
        raise InputError(f"{who}: fallback must be one of {FALLBACKS}, got {fallback!r}")
    pts = _points(points, who)
    k = len(pts)
    if k == 0 or not walls:
        if k:
            log.info("%s: %d mNLOS point(s) but no wall to anchor them to", who, k)
        return Anchoring(np.full(k, -1, np.int64), np.full(k, "none"), np.arange(k, dtype=np.int64))
    t = crossing_parameters(pts, walls, margin)
    seen = crossing_parameters(pts, walls, 0.0) if margin > 0 else t  # crossings inside the observed extents
    t = np.where(np.isfinite(seen).any(axis=1, keepdims=True), seen, t)
    crossed = np.isfinite(t).any(axis=1)
    # the first wall crossed; walls crossed at the same parameter up to rounding (two walls meeting at a
    # corner's vertex) go to the lower index on every machine (xnlos_core.numerics.snap)
    choice = np.where(crossed, np.argmin(snap(t), axis=1), -1)
    via = np.where(crossed, "ray", "none")
    if fallback == "nearest":
        d = signed_distances(pts, walls)
        far = np.where(d < 0, -d, np.inf)
        nearest = np.where(np.isfinite(far).any(axis=1), np.argmin(snap(far), axis=1), -1)
        via = np.where(~crossed & (nearest >= 0), "nearest", via)
        choice = np.where(crossed, choice, nearest)
    unanchored = np.flatnonzero(choice < 0)
    if len(unanchored):
        shown = unanchored if index is None else np.asarray(index)[unanchored]
        log.info("%s: %d of %d mNLOS point(s) are anchored to no wall (no crossing, fallback=%r): indices %s",
                 who, len(unanchored), k, fallback, shown.tolist())
    return Anchoring(choice.astype(np.int64), via, unanchored)


def wall_support(los_points, walls: list[WallPosterior], distance: float = 1.0,
                 margin: float = 2.0) -> list[np.ndarray]:
    """For each wall, the indices into ``los_points`` (N, 2) [m] of the LOS points supporting it:
    |δ| ≤ ``distance`` [m] and, when the wall has an extent, the coordinate along its (tangent)
    line within the extent ± ``margin`` [m]. A point may support several walls (at corners)."""
    pts = _points(los_points, "wall_support")
    d = signed_distances(pts, walls)
    out = []
    for j, w in enumerate(walls):
        ok = np.abs(d[:, j]) <= distance
        if w.extent is not None and len(pts):
            n = w.normal
            u = np.array([-n[1], n[0]])
            along = np.asarray(w.extent) @ u
            s = pts @ u
            ok &= (s >= along.min() - margin) & (s <= along.max() + margin)
        out.append(np.flatnonzero(ok))
    return out
