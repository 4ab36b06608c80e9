"""A scene's user meshes (trimesh, placed by :func:`sims.meshes.load_user_mesh`) as hidden Lambertian
patches for the SPAD transport: every triangle is subdivided until no edge is longer than
``patch_size`` (``trimesh.remesh.subdivide_to_size``, the library's own refinement rather than a
hand-written one), and each small triangle becomes one patch at its centroid with its face normal
(outward for a consistently wound mesh) and area [m²]."""
from __future__ import annotations

import numpy as np
import trimesh

from xnlos_core.errors import InputError


def triangle_patches(mesh: trimesh.Trimesh, patch_size: float, max_patches: int, name: str = "mesh"
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres (P, 3) [m], unit normals (P, 3) and areas (P,) [m²] of ``mesh``'s faces cut into
    triangles with edges ≤ ``patch_size`` [m]. Degenerate (zero-area) faces are dropped. Raises
    InputError naming ``name`` when the cut would exceed ``max_patches`` (a large mesh at a small
    patch size: raise patch_size or max_patches)."""
    v = np.asarray(mesh.vertices, float)
    f = np.asarray(mesh.faces, np.int64)
    if not len(f):
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    tri = v[f]
    edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    # each halving of the longest edge quadruples the triangles: the count before subdividing
    est = int(np.sum(4.0 ** np.ceil(np.log2(np.maximum(edges / patch_size, 1.0)))))
    if est > max_patches:
        raise InputError(f"SpadParams.patch_size: mesh {name!r} would become about {est} patches at "
                         f"patch_size = {patch_size:g} m, more than max_patches = {max_patches}; "
                         "raise patch_size or max_patches")
    if edges.max() > patch_size:
        v, f = trimesh.remesh.subdivide_to_size(v, f, max_edge=patch_size)
    tri = np.asarray(v, float)[np.asarray(f, np.int64)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    ok = norm > 1e-12
    return tri[ok].mean(axis=1), cross[ok] / norm[ok, None], 0.5 * norm[ok]
