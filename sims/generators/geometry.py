"""Bird's-eye (2-D) geometry for scene generation and scene checks, vectorised over walls.

Points are (…, 2) float64 arrays [m] in the ego frame (x forward, y left). A wall is a segment
start→end; a set of M walls is given as two (M, 2) arrays. The crossing rule matches
:func:`xnlos_core.geometry.segments_intersect` (touching at the ends of the first segment does
not count), so "hidden" and "mirror path" here mean what they mean to the image forward model.
"""
from __future__ import annotations

import math

import numpy as np

from xnlos_core.scene import ObjectSpec, WallSpec

DEFAULT_WALL_THICKNESS = 0.3  # m, footprint of a wall without a thickness (a half-space facade)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def crosses(p0, p1, q0, q1, eps: float = 1e-9) -> np.ndarray:
    """Broadcast form of :func:`xnlos_core.geometry.segments_intersect`.

    p0, p1: (…, 2) the segments tested; q0, q1: (…, 2) the walls (e.g. (M, 2) against
    points of shape (K, 1, 2)). True where the open segment p0→p1 crosses q0→q1.
    """
    p0 = np.asarray(p0, dtype=np.float64)
    d = np.asarray(p1, dtype=np.float64) - p0
    q0 = np.asarray(q0, dtype=np.float64)
    e = np.asarray(q1, dtype=np.float64) - q0
    den = _cross(d, e)
    w = q0 - p0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = _cross(w, e) / den
        s = _cross(w, d) / den
    ok = np.abs(den) > 1e-12
    return ok & (t > eps) & (t < 1 - eps) & (s >= -eps) & (s <= 1 + eps)


def blocked(p0, p1, starts: np.ndarray, ends: np.ndarray, skip=None) -> np.ndarray:
    """(K,) True where segment p0→p1 ((2,) or (K, 2) each) crosses any of the M walls.

    skip: a wall index, or a (K,) array of wall indices, not counted (the relay wall itself).
    """
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    k = np.broadcast_shapes(p0.shape, p1.shape)[0]
    if len(starts) == 0:
        return np.zeros(k, dtype=bool)
    hit = crosses(np.broadcast_to(p0, (k, 2))[:, None, :], np.broadcast_to(p1, (k, 2))[:, None, :],
                  starts[None, :, :], ends[None, :, :])
    if skip is not None:
        idx = np.broadcast_to(np.asarray(skip), (k,))
        hit[np.arange(k), idx] = False
    return hit.any(axis=1)


def point_segment_distance(p, a, b) -> np.ndarray:
    """Distance [m] from points p (…, 2) to segments a→b (…, 2), broadcast."""
    p, a, b = (np.asarray(v, dtype=np.float64) for v in (p, a, b))
    ab = b - a
    den = np.einsum("...i,...i->...", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.einsum("...i,...i->...", p - a, ab) / den, 0.0, 1.0)
    t = np.where(den > 0, t, 0.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def segment_distance(a0, a1, b0, b1) -> np.ndarray:
    """Distance [m] between segments a0→a1 and b0→b1 (…, 2), broadcast; 0 where they cross."""
    a0, a1, b0, b1 = (np.asarray(v, dtype=np.float64) for v in (a0, a1, b0, b1))
    da, db = a1 - a0, b1 - b0
    o1, o2 = _cross(da, b0 - a0), _cross(da, b1 - a0)
    o3, o4 = _cross(db, a0 - b0), _cross(db, a1 - b0)
    cut = (o1 * o2 <= 0) & (o3 * o4 <= 0) & ((np.abs(o1) + np.abs(o2) > 0) | (np.abs(o3) + np.abs(o4) > 0))
    dist = np.minimum(np.minimum(point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1)),
                      np.minimum(point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)))
    return np.where(cut, 0.0, dist)


def inside_convex(points, polygon: np.ndarray) -> np.ndarray:
    """(…,) True where points (…, 2) lie inside (or on) the convex polygon (V, 2) (either winding)."""
    p = np.asarray(points, dtype=np.float64)
    if len(polygon) < 3:
        return np.zeros(p.shape[:-1], dtype=bool)
    edge = np.roll(polygon, -1, axis=0) - polygon
    side = _cross(edge, p[..., None, :] - polygon)  # (…, V)
    return np.all(side >= -1e-12, axis=-1) | np.all(side <= 1e-12, axis=-1)


def footprint(obj: ObjectSpec, t: float = 0.0) -> np.ndarray:
    """Object outline from above at time t [s]: (4, 2) box corners (counter-clockwise), (1, 2) for a point."""
    c = obj.center_at(t)
    if obj.shape == "point":
        return c[None, :]
    length, width = obj.size
    heading = obj.heading_at(t)
    u = np.array([math.cos(heading), math.sin(heading)])
    v = np.array([-u[1], u[0]])
    hl, hw = length / 2, width / 2
    return np.stack([c + hl * u + hw * v, c - hl * u + hw * v, c - hl * u - hw * v, c + hl * u - hw * v])


def polygon_segment_distance(polygon: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(M,) distance [m] from a convex polygon (V, 2) (or one point, (1, 2)) to M segments; 0 on contact."""
    if len(starts) == 0:
        return np.zeros(0)
    if len(polygon) == 1:
        return point_segment_distance(polygon[0], starts, ends)
    a0, a1 = polygon, np.roll(polygon, -1, axis=0)
    d = segment_distance(a0[:, None], a1[:, None], starts[None], ends[None]).min(axis=0)
    inside = inside_convex(starts, polygon) | inside_convex(ends, polygon)
    return np.where(inside, 0.0, d)


def polygon_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Distance [m] between two convex polygons (or points), 0 when they touch or overlap."""
    if len(p) == 1 and len(q) == 1:
        return float(np.linalg.norm(p[0] - q[0]))
    if len(p) == 1:
        p, q = q, p
    if len(q) == 1:
        return 0.0 if inside_convex(q[0], p) else float(point_segment_distance(q[0], p, np.roll(p, -1, axis=0)).min())
    d = polygon_segment_distance(p, q, np.roll(q, -1, axis=0))
    return 0.0 if inside_convex(p[0], q) else float(d.min())


def separated(p: np.ndarray, q: np.ndarray, margin: float) -> bool:
    """True if a separating axis (an edge normal of either convex polygon) keeps p and q at least
    ``margin`` [m] apart. Sufficient for distance ≥ margin (corner-to-corner gaps may be refused)."""
    axes = []
    for poly in (p, q):
        if len(poly) > 1:
            e = np.roll(poly, -1, axis=0) - poly
            axes.append(np.stack([-e[:, 1], e[:, 0]], axis=1))
    if not axes:
        return bool(np.linalg.norm(p[0] - q[0]) >= margin)
    a = np.concatenate(axes)
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    pp, qq = p @ a.T, q @ a.T  # (V, A) projections
    gap = np.maximum(qq.min(axis=0) - pp.max(axis=0), pp.min(axis=0) - qq.max(axis=0))
    return bool(gap.max() >= margin)


def wall_arrays(walls: list[WallSpec]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar pieces of ``walls`` as (starts (M, 2), ends (M, 2), half footprint widths (M,) [m])."""
    planar = [f for w in walls for f in w.facets()]
    if not planar:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    starts = np.array([f.start for f in planar], dtype=np.float64)
    ends = np.array([f.end for f in planar], dtype=np.float64)
    half = np.array([(f.thickness or DEFAULT_WALL_THICKNESS) / 2 for f in planar])
    return starts, ends, half


def ray_cast(point, direction, starts: np.ndarray, ends: np.ndarray) -> float:
    """Distance [m] from ``point`` along unit ``direction`` to the first wall it meets (inf if none)."""
    p = np.asarray(point, dtype=np.float64)
    u = np.asarray(direction, dtype=np.float64)
    if len(starts) == 0:
        return math.inf
    e = ends - starts
    den = _cross(u[None, :], e)
    w = starts - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = _cross(w, e) / den
        s = _cross(w, u[None, :]) / den
    ok = (np.abs(den) > 1e-12) & (t > 1e-9) & (s >= 0) & (s <= 1)
    return float(t[ok].min()) if ok.any() else math.inf


def is_hidden(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> bool:
    """True if no point (K, 2) has a direct line of sight from the radar at the origin."""
    return bool(blocked(np.zeros(2), points, starts, ends).all())


def mirror_candidates(points: np.ndarray, normals: np.ndarray, walls: list[WallSpec]):
    """Single-bounce specular paths radar → relay wall → point → same wall → radar (image method).

    points, normals: (K, 2) scatterers and their outward normals (0 for point scatterers);
    walls: planar relay candidates (curved walls already cut into facets). Returns a list of
    (wall index, point indices (P,), images o' (P, 2), incidence angles (P,) [rad]) for every
    wall with at least one path that lands on the wall, is unobstructed on both legs and meets
    a face of the object turned towards the wall: the rules of :mod:`sims.image`, vectorised
    over walls and points (images o' = x − 2(nᵀx + b)n as :func:`~xnlos_core.geometry.mirror_reflect`).
    """
    if not walls or not len(points):
        return []
    starts = np.array([w.start for w in walls], dtype=np.float64)
    ends = np.array([w.end for w in walls], dtype=np.float64)
    e = ends - starts
    n = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.hypot(e[:, 0], e[:, 1])[:, None]
    b = -np.einsum("ij,ij->i", n, starts)
    n = np.where(b[:, None] < 0, -n, n)  # canonical line: radar on the positive side
    b = np.abs(b)
    usable = np.array([w.relay for w in walls]) & (b > 0)
    dist = points @ n.T + b  # (K, M) signed distance to each wall line
    img = points[:, None, :] - 2.0 * dist[..., None] * n[None]  # (K, M, 2)
    den = _cross(img, e[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = _cross(starts[None], e[None]) / den
        s = _cross(starts[None], img) / den
    ok = usable[None] & (dist > 0) & (np.abs(den) > 1e-12) & (s >= 0) & (s <= 1) & (t > 0) & (t < 1)
    k, m = np.nonzero(ok)
    if not len(k):
        return []
    w = t[k, m, None] * img[k, m]
    good = ~blocked(np.zeros(2), w, starts, ends, skip=m) & ~blocked(w, points[k], starts, ends, skip=m)
    point_like = ~np.any(normals[k] != 0, axis=-1)
    good &= point_like | (np.einsum("ij,ij->i", normals[k], w - points[k]) > 0)
    k, m, w = k[good], m[good], w[good]
    inc = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", w, n[m])) / np.linalg.norm(w, axis=1), 0.0, 1.0))
    return [(int(i), k[m == i], img[k[m == i], i], inc[m == i]) for i in np.unique(m)]
