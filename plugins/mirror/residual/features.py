"""Inputs of the residual network, in each point's local wall frame (rotation/translation equivariant).

For a virtual point o' anchored to wall w, the reflection point q is where the ray radar → o'
meets w (a line: q = t·o' with t = −b/(nᵀo'); an arc: :func:`xnlos_core.wall.ray_hits`),
n_q the wall's unit normal at q (radar side) and u_q = (−n_q,y, n_q,x) the tangent. When the ray
misses the wall, q is the projection of o' onto the (tangent) line and n_q its normal — the
same local wall the Eq. 7 mirror uses (:func:`xnlos_core.wall.mirror`). A vector v in the
ego frame has local coordinates (u_qᵀv, n_qᵀv)/SCALE.

query (M, 12): local o' − q, radar − q (the radar is the ego origin), ô − q with ô = R_Π(o');
then a local-wall hint: the TLS line through the ``fit_points`` neighbours nearest the ray gives
the mirror ô_loc of o' across it (local ô_loc − ô), its unit normal (local, facing the radar),
its rms residual /SCALE and the fraction of the K neighbour slots filled. The fitted wall of a
corner or a curved wall is a compromise line; the LOS points where the ray radar → o' actually
meets the wall say which local wall reflected it — the network learns when to trust that hint.
neighbours (M, K, 5): the K supporting LOS points p (:func:`plugins.mirror.association.wall_support`)
nearest to the segment radar → o' (where the reflection happens): local p − q, local p − ô,
distance to the segment /SCALE; mask (M, K) True for a real neighbour (fewer than K supporting
points are padded). Everything is relative to q and expressed in (u_q, n_q), so
rotating or translating the whole scene (radar included) leaves the inputs unchanged and rotates
the predicted residual with it.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.types import WallPosterior
from xnlos_core.wall import ray_hits

SCALE = 10.0  # [m]: local coordinates are divided by this


def reflection_frames(points: np.ndarray, walls: list[WallPosterior], wall_index: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(q (M, 2) [m], n_q (M, 2)) of virtual points (M, 2) [m] on their walls ``walls[wall_index]``."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    q, nq = np.empty_like(p), np.empty_like(p)
    for j in np.unique(wall_index):
        m = wall_index == j
        w, pm = walls[j], p[m]
        n, b = w.normal, w.offset
        nqm = np.broadcast_to(n, pm.shape).copy()
        if w.model == "line":
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -b / (pm @ n)
        else:
            t, hit_n = ray_hits(w.model, w.mean, pm, w.anchor)
            ok = np.all(np.isfinite(hit_n), axis=1)
            nqm[ok] = hit_n[ok]
        hit = np.isfinite(t) & (t > 0) & np.all(np.isfinite(nqm), axis=1)
        nqm[~hit] = n
        qm = np.where(hit[:, None], np.where(np.isfinite(t), t, 0.0)[:, None] * pm,
                      pm - (pm @ n + b)[:, None] * n)
        q[m], nq[m] = qm, nqm
    return q, nq


def to_local(v: np.ndarray, nq: np.ndarray) -> np.ndarray:
    """Local coordinates (…, 2) of ego-frame vectors v (…, 2) [m] in the frame (u_q, n_q), / SCALE."""
    u = np.stack([-nq[..., 1], nq[..., 0]], -1)
    if v.ndim == nq.ndim + 1:
        u, nq = u[..., None, :], nq[..., None, :]
    return np.stack([np.sum(v * u, -1), np.sum(v * nq, -1)], -1) / SCALE


def _segment_distance(pts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(R, S) distance [m] of points (S, 2) to the segments origin → ends (R, 2)."""
    ee = np.maximum(np.sum(ends * ends, -1), 1e-12)[:, None]  # (R, 1)
    t = np.clip((ends @ pts.T) / ee, 0.0, 1.0)  # (R, S)
    return np.linalg.norm(pts[None] - t[..., None] * ends[:, None], axis=-1)


def _local_lines(pts: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """TLS lines through each row's valid points (R, F, 2): (centroid (R, 2), unit normal (R, 2)
    facing the origin, rms residual (R,) [m], ok (R,) — at least 2 distinct points)."""
    w = valid.astype(np.float64)[..., None]
    cnt = np.maximum(w.sum(1), 1.0)
    c = (pts * w).sum(1) / cnt
    d = (pts - c[:, None]) * w
    evals, evecs = np.linalg.eigh(np.einsum("rfi,rfj->rij", d, d))
    n = evecs[:, :, 0]
    n = np.where((np.sum(n * c, -1) > 0)[:, None], -n, n)  # the radar (origin) side: nᵀ(0 − c) > 0
    rms = np.sqrt(np.maximum(evals[:, 0], 0) / cnt[:, 0])
    ok = (valid.sum(1) >= 2) & (evals[:, 1] > 1e-12)
    return c, n, rms, ok


def build_inputs(points: np.ndarray, walls: list[WallPosterior], wall_index: np.ndarray, los_points: np.ndarray,
                 support: list[np.ndarray], neighbours: int, fit_points: int = 16) -> dict[str, np.ndarray]:
    """Network inputs of the module doc for virtual points (M, 2) [m] anchored to ``wall_index``
    (M,), with ``support[j]`` the indices into ``los_points`` (N, 2) [m] supporting wall j.

    Returns float32 arrays query (M, 12), neigh (M, K, 5), mask (M, K) bool, and float64 normal
    (M, 2) = n_q, mirror (M, 2) = ô [m] (the local-wall mirror of o').
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    los = np.asarray(los_points, dtype=np.float64).reshape(-1, 2)
    q, nq = reflection_frames(p, walls, wall_index)
    mir = p - 2 * np.sum((p - q) * nq, -1)[:, None] * nq
    k = neighbours
    neigh = np.zeros((len(p), k, 5))
    mask = np.zeros((len(p), k), dtype=bool)
    hint = np.zeros((len(p), 6))
    hint[:, 3] = 1.0  # local normal = n_q when there is no local fit
    for j in np.unique(wall_index):
        rows = np.flatnonzero(wall_index == j)
        sup = los[support[j]] if j < len(support) else np.empty((0, 2))
        if len(sup) == 0:
            continue
        d = _segment_distance(sup, p[rows])  # (R, S)
        kk = min(k, len(sup))
        nn = np.argsort(d, axis=1, kind="stable")[:, :kk]
        pts = sup[nn]  # (R, kk, 2)
        neigh[rows, :kk, 0:2] = to_local(pts - q[rows, None], nq[rows])
        neigh[rows, :kk, 2:4] = to_local(pts - mir[rows, None], nq[rows])
        neigh[rows, :kk, 4] = np.take_along_axis(d, nn, 1) / SCALE
        mask[rows, :kk] = True
        f = min(fit_points, kk)
        c, n_loc, rms, ok = _local_lines(pts[:, :f], np.ones((len(rows), f), dtype=bool))
        o_loc = p[rows] - 2 * np.sum((p[rows] - c) * n_loc, -1)[:, None] * n_loc
        h = np.concatenate([to_local(o_loc - mir[rows], nq[rows]), to_local(n_loc, nq[rows]) * SCALE,
                            (rms / SCALE)[:, None], np.full((len(rows), 1), kk / k)], -1)
        h[~ok, :4] = [0.0, 0.0, 0.0, 1.0]
        hint[rows] = h
    query = np.concatenate([to_local(p - q, nq), to_local(-q, nq), to_local(mir - q, nq), hint], -1)
    return {"query": query.astype(np.float32), "neigh": neigh.astype(np.float32), "mask": mask,
            "normal": nq, "mirror": mir}
