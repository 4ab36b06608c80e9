"""First-hit ray casting on a triangle mesh: embreex when installed, trimesh's pure-numpy fallback.

Both backends only report which triangle a ray hits first; the hit distance is recomputed here
in float64 from that triangle's plane (embree works in float32), so ranges stay exact at 10 GHz.
"""
from __future__ import annotations

import importlib.util
import logging
from typing import Literal

import numpy as np

from xnlos_core.errors import InputError

log = logging.getLogger(__name__)
Backend = Literal["auto", "embree", "triangle"]


def embree_available() -> bool:
    """True when the embreex extension (trimesh's fast backend) imports."""
    return importlib.util.find_spec("embreex") is not None


class Caster:
    """Casts rays against a fixed ``trimesh.Trimesh`` (faces' unit normals and a vertex per face kept).

    backend: "embree" (embreex), "triangle" (trimesh.ray.ray_triangle, numpy + rtree) or "auto"
    (embree when available). ``rays_cast`` counts every ray and ``casts`` every call that cast at
least one ray (rays per call: how well the tracer batches), for throughput figures.
    """

    def __init__(self, mesh, backend: Backend = "auto"):
        if backend not in ("auto", "embree", "triangle"):
            raise InputError(f"ray-casting backend must be 'auto', 'embree' or 'triangle', got {backend!r}")
        if backend == "embree" and not embree_available():
            raise InputError("ray-casting backend 'embree' requested but embreex is not installed "
                             "(pip install embreex, x86-64 only); use 'triangle' or 'auto'")
        use_embree = backend == "embree" or (backend == "auto" and embree_available())
        if use_embree:
            from trimesh.ray.ray_pyembree import RayMeshIntersector
        else:
            from trimesh.ray.ray_triangle import RayMeshIntersector
        self.backend = "embree" if use_embree else "triangle"
        self.mesh = mesh
        self.n_faces = len(mesh.faces)
        self._ray = RayMeshIntersector(mesh) if self.n_faces else None
        self.normals = np.asarray(mesh.face_normals, dtype=np.float64) if self.n_faces else np.zeros((0, 3))
        self.anchor = np.asarray(mesh.vertices, dtype=np.float64)[mesh.faces[:, 0]] if self.n_faces else np.zeros((0, 3))
        self.rays_cast = 0
        self.casts = 0

    def first_hit(self, origins, directions) -> tuple[np.ndarray, np.ndarray]:
        """(tri (N,) int, −1 for a miss; dist (N,) float64 [m] along the unit direction, inf for a miss)."""
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        self.rays_cast += len(o)
        if self._ray is None or len(o) == 0:
            return np.full(len(o), -1, dtype=np.int64), np.full(len(o), np.inf)
        self.casts += 1
        tri = np.asarray(self._ray.intersects_first(o, d), dtype=np.int64)
        dist = np.full(len(o), np.inf)
        hit = tri >= 0
        n = self.normals[tri[hit]]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.einsum("ij,ij->i", n, self.anchor[tri[hit]] - o[hit]) / np.einsum("ij,ij->i", n, d[hit])
        dist[hit] = np.where(np.isfinite(t) & (t >= 0), t, 0.0)
        return tri, dist
