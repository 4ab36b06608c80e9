"""The ray tracer's diffuse three-bounce NLOS paths: radar → rough relay wall → object → wall → radar.

Physics, power and the importance cut are :func:`sims.diffuse_nlos.wall_paths` (shared with the
``image`` model); this module gives it the ray tracer's geometry. Cells are those of
:func:`sims.diffuse_nlos.cells` on each planar relay wall's front face at the radar height h_r
(a cell stands for the wall's full height, as the fan's strips do); object centres sit at
min(h_r, object height) as in the image paths of :mod:`.tracer`. Visibility comes from ray casting
in the mesh world: the radar → cell ray must first hit that wall at the cell, and the cell → centre
leg must be unobstructed (walls, meshes, object occluder boxes) with the centre facing the cell.
Relay surfaces of user meshes carry no diffuse NLOS path (not modelled).
"""
from __future__ import annotations

import numpy as np

from xnlos_core.radar import RadarConfig
from sims import diffuse_nlos
from sims.paths import OTHER, PathList

from .tracer import START
from .world import World


def rough_relay_walls(scene) -> list[int]:
    """Indices of the planar walls (= world surfaces) that carry the path: relay, material, rough, radar in front."""
    return [i for i, w in enumerate(scene.planar_walls())
            if w.relay and w.material is not None and w.roughness > 0 and w.segment().offset > 0]


def _lit(world: World, origin: np.ndarray, cells: np.ndarray, surface: int) -> np.ndarray:
    """(K,) True where the ray radar → cell first hits ``surface`` at the cell."""
    rel = cells - origin
    dist = np.linalg.norm(rel, axis=1)
    tri, hit = world.caster.first_hit(np.repeat(origin[None], len(cells), 0), rel / dist[:, None])
    return (tri >= 0) & (world.tri_surface[np.maximum(tri, 0)] == surface) & (np.abs(hit - dist) < 1e-4 + 1e-6 * dist)


def _sees(world: World, cells: np.ndarray, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(O, K) True where the leg cell k → centre o is unobstructed and the centre faces the cell."""
    leg = points[:, None, :] - cells[None, :, :]
    dist = np.linalg.norm(leg, axis=2)
    u = leg / np.maximum(dist, 1e-12)[..., None]
    facing = ~np.any(normals != 0, axis=1)[:, None] | (np.einsum("oj,okj->ok", normals, -u) > 0)
    ok = facing & (dist > 1e-6)
    if ok.any():
        _, hit = world.caster.first_hit(cells[None].repeat(len(points), 0)[ok] + START * u[ok], u[ok])
        sub = np.zeros_like(ok)
        sub[ok] = hit + START >= dist[ok] - 1e-6
        ok &= sub
    return ok


def diffuse_paths(world: World, scene, radar: RadarConfig, origin: np.ndarray, centres, velocities, params,
                  paths: PathList) -> tuple[np.ndarray, int, str]:
    """Append the diffuse NLOS paths of every rough relay wall to ``paths`` (last, in wall order).

    centres: per object (pos (K, 3) [m], normal (K, 3), rcs (K,) [m²]); velocities: per object (3,)
    [m/s]; params: the model's ForwardParams (diffuse_nlos_cell, _floor_db, _max_paths). Returns
    (cells (P_d, 2) int, the cell numbers (a, b) of each path; the number of cells; the importance
    cut's record for meta["components"]["diffuse_nlos_cut"]).
    """
    planar = scene.planar_walls()
    rough = rough_relay_walls(scene)
    budget = diffuse_nlos.noise_equivalent_power(radar) * 10 ** (params.diffuse_nlos_floor_db / 10) / max(len(rough), 1)
    cap = max(1, params.diffuse_nlos_max_paths // max(len(rough), 1))
    owner = np.concatenate([np.full(len(c[0]), j) for j, c in enumerate(centres)] + [np.zeros(0, dtype=int)])
    index = np.concatenate([np.arange(len(c[0])) for c in centres] + [np.zeros(0, dtype=int)])
    pts = np.concatenate([c[0] for c in centres] + [np.zeros((0, 3))])
    nrm = np.concatenate([c[1] for c in centres] + [np.zeros((0, 3))])
    rcs = np.concatenate([c[2] for c in centres] + [np.zeros(0)])
    out_cells, n_cells, cut = [], 0, [0, 0, 0.0, 0.0, False]
    for s in rough:
        spec, seg = planar[s], planar[s].segment()
        a2, ds = diffuse_nlos.cells(spec, params.diffuse_nlos_cell)
        a = np.column_stack([a2, np.full(len(a2), origin[2])])
        first, n_cells = n_cells, n_cells + len(a)
        lit = np.flatnonzero(_lit(world, origin, a, s))
        near = np.flatnonzero(pts[:, :2] @ seg.normal + seg.offset > 0)
        if len(lit) == 0 or len(near) == 0:
            continue
        sees = _sees(world, a[lit], pts[near], nrm[near])
        v3 = np.array([velocities[owner[o]] for o in near])
        w = diffuse_nlos.wall_paths(radar, world.surfaces[s], np.append(seg.normal, 0.0), a[lit],
                                    ds * spec.height, origin, pts[near], rcs[near], sees, v3, budget, cap)
        cut = [cut[0] + len(w.power), cut[1] + w.pairs, cut[2] + w.total, cut[3] + w.neglected,
               cut[4] or w.capped]
        o = near[w.centre]
        u = np.column_stack([np.cos(w.azimuth), np.sin(w.azimuth)])
        paths.add(length=w.length, azimuth=w.azimuth, power=w.power, amp=np.sqrt(w.power).astype(np.complex128),
                  kind=OTHER, order=1, pos=w.pos, hidden=w.hidden, obj=owner[o], centre=index[o],
                  velocity=u * w.rate[:, None])
        out_cells.append(np.column_stack([first + lit[w.ia], first + lit[w.ib]]))
    cells = np.concatenate(out_cells) if out_cells else np.zeros((0, 2), dtype=np.int64)
    return cells, n_cells, diffuse_nlos.describe_cut(*cut, radar)
