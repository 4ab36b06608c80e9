"""Occlusion of hidden patches seen from the SPAD scan grid (world frame, metres).

A patch contributes photons only when the straight segment from the scan-grid centre C (on the
relay wall, at the grid's height) to the patch centre p is not blocked. Tested from the grid
centre only, not from each scan point: the grid (~2 m) is small against the distances to hidden
objects, so only patches at the edge of a shadow would differ (a penumbra this neglects).

Blockers and the tests used:

* vertical walls (every planar wall piece except the relay wall, from the ground up to its
  ``height``) and box objects (their footprint's sides, from 0 up to ``height``): a 2-D top-view
  segment–segment intersection, then the segment's height at the crossing point compared with the
  blocker's height. Exact for vertical planes and for boxes (a straight segment inside a convex
  prism must leave it through a side, where its height is below the roof, since z is linear along
  the segment and both ends lie above the ground). A box never blocks its own patches (its
  self-occlusion is the transport's cosine).
* meshes: first hit of the ray C → p with :class:`sims.raytrace.caster.Caster` (embree when
  installed, trimesh's numpy intersector otherwise); blocked when the hit is nearer than p by more
  than ``SELF_HIT`` [m]. A mesh is not tested against its own patches: as for a box, its
  self-occlusion is left to the transport's cosine per scan point, exact for a convex mesh (a test
  from C alone would hide a box's side faces that off-centre scan points see); a non-convex
  mesh's shadow on itself is not modelled.
"""
from __future__ import annotations

import numpy as np

SELF_HIT = 1e-3  # [m] hits this close to the patch are the patch's own surface
_EPS = 1e-9


def blocked_by_segments(c: np.ndarray, p: np.ndarray, a: np.ndarray, b: np.ndarray, height: np.ndarray
                        ) -> np.ndarray:
    """(P,) bool: does the segment from ``c`` (3,) to each ``p`` (P, 3) cross one of the vertical
    rectangles over the top-view segments a (K, 2) → b (K, 2), from z = 0 to ``height`` (K,) [m]?
    Crossings at the segment's ends (within 1e-9 of its parameter range) do not count."""
    p = np.asarray(p, float).reshape(-1, 3)
    a = np.asarray(a, float).reshape(-1, 2)
    if not len(a) or not len(p):
        return np.zeros(len(p), bool)
    b = np.asarray(b, float).reshape(-1, 2)
    d = p[:, None, :2] - c[None, None, :2]  # (P, 1, 2)
    e = (b - a)[None]  # (1, K, 2)
    w = a[None] - c[None, None, :2]
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den  # along c → p
        s = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / den  # along a → b
        z = c[2] + t * (p[:, None, 2] - c[2])
    hit = (np.abs(den) > _EPS) & (t > _EPS) & (t < 1 - _EPS) & (s >= 0) & (s <= 1) & (z < height[None])
    return hit.any(axis=1)


def blocked_by_mesh(c: np.ndarray, p: np.ndarray, caster) -> np.ndarray:
    """(P,) bool: does the ray from ``c`` (3,) toward each ``p`` (P, 3) hit ``caster``'s mesh more
    than SELF_HIT [m] before reaching p?"""
    p = np.asarray(p, float).reshape(-1, 3)
    if not len(p):
        return np.zeros(0, bool)
    v = p - c
    r = np.linalg.norm(v, axis=1)
    _, dist = caster.first_hit(np.broadcast_to(c, p.shape), v / np.maximum(r, 1e-12)[:, None])
    return dist < r - SELF_HIT
