"""Shooting and bouncing rays (SBR) over the world, and exact image paths to scattering centres.

Geometry is 2.5-D: walls are vertical, rays travel in the horizontal plane at the radar height
h_r, and a wall hit stands for the wall's whole vertical extent (as in the image model).

1. **Fan.** Rays leave the radar every ``az_step`` over the field of view (plus a margin). At
   each hit on a static surface a ray contributes a diffuse echo of the strip it covers:
   σ = σ⁰(θ_i)·(L·Δθ/cos θ_i)·h, at its unfolded length L (ray-tube width L·Δθ behind planar
   mirrors) and with the chain's specular reflectivities α (out and back the same way, |α|⁴ in
   power). On a relay surface the ray then reflects (d ← d − 2(dᵀn)n) and goes on, up to
   ``max_bounces``, and stops early once even the strongest scatterer of the scene could not
   rise above ``min_snr_db − 10 dB`` at its unfolded length (adaptive depth).
2. **Chains.** The ordered planes a ray reflected from, (p₁ … p_k), and the azimuth sector its rays
   left in, are the specular chains the scene supports (beam splitting at corners and curved
   walls show up as several chains).
3. **Image paths.** For every chain (and the direct view, k = 0) and every object scattering
   centre o: the virtual point o' = R_{p₁}∘…∘R_{p_k}(o) (Eq. 5/7 per plane); if its azimuth lies in
   the chain's sector, the reflection points q_j are found by unfolding (q₁ on the segment
   radar → o', then recursively) and every leg is checked by ray casting (the first hit must be
   on plane p_j at q_j; nothing may block the last leg; the centre must face its last leg).
   The round trip retraces the chain: unfolded one-way length |o' − radar|, α = Π α_j(θ_j).
4. **Mixed paths** (optional): a centre reached by two chains a ≠ b also returns out along a and
   back along b: round trip L_a + L_b, arrival from b, amplitude with |α_a||α_b| (bistatic
   radar equation).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from xnlos_core.signal.antenna import element_gain, transmit_gain
from xnlos_core.radar import RadarConfig
from sims import walls as wall_em
from sims.paths import PathList
from sims.propagation import ra_snr_db, received_power

from .world import World

START = 1e-4  # [m] a leg leaving a reflection point is cast from this far along it (not from the surface)


@dataclass
class Trace:
    """What the fan did, for pictures and statistics: segments (S, 2, 3) of every ray leg and
    their bounce order (S,), chains {planes: (az_min, az_max)}, rays cast, deepest bounce reached;
    diffuse_cells (P_d, 2): wall cells (a, b) of the diffuse NLOS paths, which are the last P_d paths
    of the trace (:mod:`.diffuse`), numbered 0 … n_cells − 1 over all relay walls."""

    segments: np.ndarray
    segment_order: np.ndarray
    chains: dict
    rays: int
    max_order: int
    diffuse_cells: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    n_cells: int = 0


def _angle(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Incidence angle [rad] between directions d (N, 3) and plane normals n (N, 3)."""
    return np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", d, n)), 0.0, 1.0))


def em_groups(world: World) -> np.ndarray:
    """(n_surfaces,) int: surfaces with the same electromagnetic description (every
    :class:`~sims.raytrace.world.Surface` field but name and relay) share a group number, so
    α(θ) and σ⁰(θ), evaluated element by element, are computed once per group and bounce."""
    if world.em_group is None:
        keys: dict = {}
        world.em_group = np.array([keys.setdefault(replace(s, name="", relay=False), len(keys))
                                   for s in world.surfaces], dtype=np.int64)
    return world.em_group


def shoot(world: World, radar: RadarConfig, origin: np.ndarray, heights: np.ndarray, *, az_step: float,
          max_bounces: int, snr_floor_db: float, sigma_bound: float, reflection: str, diffuse: bool,
          paths: PathList, keep_segments: bool = False) -> Trace:
    """Step 1–2 of the module doc. Appends diffuse strip paths to ``paths``; returns the Trace.

    heights (n_surfaces,): vertical extent [m] each static surface stands for.
    """
    margin = 2 * az_step
    az0 = np.arange(-radar.field_of_view - margin, radar.field_of_view + margin + 1e-12, az_step)
    n = len(az0)
    dirs = np.stack([np.cos(az0), np.sin(az0), np.zeros(n)], axis=1)
    org = np.repeat(origin[None, :], n, axis=0)
    length = np.zeros(n)  # unfolded one-way length so far [m]
    alpha = np.ones(n, dtype=np.complex128)  # chain amplitude reflectivity
    chain = np.full((n, max_bounces), -1, dtype=np.int64)
    alive = np.arange(n)
    skip = np.zeros(n)  # a relaunched ray starts START along its new direction (no self-hit)
    chains: dict[tuple, list] = {}
    segments = []
    deepest = 0
    for k in range(max_bounces + 1):
        if len(alive) == 0:
            break
        tri, dist = world.caster.first_hit(org[alive] + skip[alive, None] * dirs[alive], dirs[alive])
        dist = dist + skip[alive]
        if keep_segments:
            far = np.where(np.isfinite(dist), dist, 2 * radar.max_range)
            seg_end = org[alive] + far[:, None] * dirs[alive]
            segments.append((k, np.stack([org[alive], seg_end], axis=1)))
        hit = tri >= 0
        idx, tri, dist = alive[hit], tri[hit], dist[hit]
        surf = world.tri_surface[tri]
        static = surf >= 0
        idx, tri, dist, surf = idx[static], tri[static], dist[static], surf[static]  # objects stop rays
        if len(idx) == 0:
            break
        deepest = k
        p = org[idx] + dist[:, None] * dirs[idx]
        L = length[idx] + dist
        n_tri = world.caster.normals[tri]
        th_i = _angle(dirs[idx], n_tri)
        a_i = np.empty(len(idx), dtype=np.complex128)
        s0 = np.zeros(len(idx))
        em = em_groups(world)[surf]  # surfaces of equal electromagnetics share one evaluation
        for g in np.unique(em):
            m = em == g
            spec = world.surfaces[surf[m][0]]
            a_i[m] = wall_em.specular_alpha(spec, radar, th_i[m], reflection)
            if diffuse or spec.material is None:
                s0[m] = wall_em.backscatter_sigma0(spec, radar, th_i[m]) * heights[surf[m]]
        cos_i = np.maximum(np.cos(th_i), 1e-3)
        sigma = s0 * L * az_step / cos_i
        live = sigma > 0
        if live.any():
            i = idx[live]
            P = received_power(radar, L[live], az0[i], sigma[live], np.abs(alpha[i]))
            virt = np.stack([np.cos(az0[i]), np.sin(az0[i])], axis=1) * L[live, None]
            paths.add(length=2 * L[live], azimuth=az0[i], amp=np.sqrt(P) * alpha[i] ** 2 / np.maximum(np.abs(alpha[i]) ** 2, 1e-300),
                      power=P, kind=min(k, 2), order=k,
                      pos=p[live, :2] if k == 0 else virt, hidden=p[live, :2], obj=-1 - surf[live], centre=-1)
        if k == max_bounces:
            break
        relay = np.array([world.surfaces[s].relay for s in surf], dtype=bool)
        # adaptive depth: the brightest scatterer at this unfolded length must stay detectable
        bound = ra_snr_db(radar, received_power(radar, L, az0[idx], sigma_bound, np.abs(alpha[idx] * a_i)))
        go = relay & (bound >= snr_floor_db)
        idx, p, L, n_tri, a_i, tri = idx[go], p[go], L[go], n_tri[go], a_i[go], tri[go]
        d_in = dirs[idx]
        dirs[idx] = d_in - 2 * np.einsum("ij,ij->i", d_in, n_tri)[:, None] * n_tri
        org[idx] = p
        skip[idx] = START
        length[idx] = L
        alpha[idx] *= a_i
        chain[idx, k] = world.tri_plane[tri]
        _add_chains(chains, chain[idx, :k + 1], az0[idx])
        alive = idx
    segs = np.concatenate([s for _, s in segments]) if segments else np.zeros((0, 2, 3))
    seg_order = np.concatenate([np.full(len(s), k) for k, s in segments]) if segments else np.zeros(0, dtype=int)
    return Trace(segs, seg_order, {k: tuple(v) for k, v in chains.items()}, world.caster.rays_cast, deepest)


def _add_chains(chains: dict, keys: np.ndarray, az: np.ndarray) -> None:
    """Record the chains (rows of keys (R, k) int, all of one length k, new to ``chains``) with the
    azimuth range [min, max] [rad] of the rays az (R,) that took each, in order of first appearance
    (the dict's order is the order image paths, hence rendered paths, are summed)."""
    if not len(keys):
        return
    uniq, first, inv = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    lo, hi = np.full(len(uniq), np.inf), np.full(len(uniq), -np.inf)
    np.minimum.at(lo, inv, az)
    np.maximum.at(hi, inv, az)
    for g in np.argsort(first, kind="stable"):
        chains[tuple(uniq[g])] = [lo[g], hi[g]]


def image_paths(world: World, origin: np.ndarray, points: np.ndarray, normals: np.ndarray,
                planes: tuple, sector: tuple | None, az_step: float):
    """Step 3 for one chain ``planes`` (() = direct view) and centres ``points`` (K, 3).

    Returns (ok (K,) bool, virtual (K, 3) o', reflection points (K, k, 3), incidence angles (K, k)
    [rad]). ``normals`` (K, 3): outward normals of the centres (zeros: omnidirectional).
    One chain of :func:`image_paths_rows` (every row the same planes and sector).
    """
    K, k = len(points), len(planes)
    rows = np.broadcast_to(np.asarray(planes, dtype=np.int64).reshape(1, k), (K, k))
    sec = None if sector is None else np.broadcast_to(np.asarray(sector, dtype=np.float64).reshape(1, 2), (K, 2))
    return image_paths_rows(world, origin, points, normals, rows, sec, az_step)


def image_paths_chains(world: World, origin: np.ndarray, points: list[np.ndarray], normals: list[np.ndarray],
                       chains: dict[tuple, tuple | None], az_step: float) -> dict[tuple[int, tuple], tuple]:
    """Step 3 for every object's centres through every chain, batched: all (centre, chain) rows of
    one chain length go through :func:`image_paths_rows` together (k + 1 casts per length).

    points[j] (K_j, 3), normals[j] (K_j, 3): object j's scattering centres; chains: planes →
    departure sector (None: no check). Returns {(j, planes): (ok, virtual, incidence angles)} with
    the arrays of :func:`image_paths` for object j and that chain.
    """
    out: dict[tuple[int, tuple], tuple] = {}
    sizes = [len(x) for x in points]
    if not sum(sizes):
        return {(j, c): (np.zeros(0, dtype=bool), np.zeros((0, 3)), np.zeros((0, len(c))))
                for j in range(len(points)) for c in chains}
    for k in sorted({len(c) for c in chains}):
        group = [c for c in chains if len(c) == k]
        pts = np.concatenate([x for _ in group for x in points])
        nrm = np.concatenate([x for _ in group for x in normals])
        rows = np.concatenate([np.broadcast_to(np.asarray(c, dtype=np.int64).reshape(1, k), (sum(sizes), k))
                               for c in group])
        sec = None
        if any(chains[c] is not None for c in group):
            sec = np.concatenate([np.broadcast_to(np.asarray(chains[c] if chains[c] is not None else (np.nan, np.nan),
                                                             dtype=np.float64).reshape(1, 2), (sum(sizes), 2))
                                  for c in group])
        ok, virt, _, th = image_paths_rows(world, origin, pts, nrm, rows, sec, az_step)
        at = 0
        for c in group:
            for j, n in enumerate(sizes):
                sl = slice(at, at + n)
                out[j, c] = (ok[sl], virt[sl], th[sl])
                at += n
    return out


def image_paths_rows(world: World, origin: np.ndarray, points: np.ndarray, normals: np.ndarray,
                     planes: np.ndarray, sectors: np.ndarray | None, az_step: float):
    """Step 3 for K (centre, chain) rows at once, every chain of the same length k.

    points (K, 3), normals (K, 3) as :func:`image_paths`; planes (K, k) int: row r's chain;
    sectors (K, 2) [rad] or None: row r's departure sector (NaN: no sector check, the direct
    view). Each leg of all rows is one cast (k + 1 casts, however many centres and chains), the
    batching that keeps embree busy. Row results equal :func:`image_paths` per chain: the
    arithmetic is row-wise (the same products and sums per row).
    """
    K, k = planes.shape
    pd = world.plane_d[planes]  # (K, k)
    virt = points.copy()
    for j in reversed(range(k)):
        virt = _reflect_rows(world, virt, planes[:, j])
    rel = virt - origin
    ok = np.ones(K, dtype=bool)
    if sectors is not None:
        az = np.arctan2(rel[:, 1], rel[:, 0])
        lo, hi = sectors[:, 0], sectors[:, 1]
        free = np.isnan(lo)
        with np.errstate(invalid="ignore"):
            ok &= free | ((az >= lo - 2 * az_step) & (az <= hi + 2 * az_step))
    q = np.zeros((K, k, 3))
    th = np.zeros((K, k))
    cur = np.repeat(origin[None, :], K, axis=0)
    target = virt.copy()
    for j in range(k):
        pl, d = planes[:, j], pd[:, j]
        seg = target - cur
        denom = _plane_dot(world, seg, pl)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -(_plane_dot(world, cur, pl) + d) / denom
        ok &= np.isfinite(t) & (t > 1e-9) & (t < 1 - 1e-9)
        t = np.where(ok, t, 0.5)
        q[:, j] = cur + t[:, None] * seg
        leg = q[:, j] - cur
        dist = np.linalg.norm(leg, axis=1)
        u = leg / np.maximum(dist, 1e-12)[:, None]
        skip = START if j > 0 else 0.0
        tri, hit = world.caster.first_hit(cur[ok] + skip * u[ok], u[ok])
        hit = hit + skip
        good = ((tri >= 0) & (world.tri_plane[np.maximum(tri, 0)] == planes[ok, j])
                & (np.abs(hit - dist[ok]) < 1e-4 + 1e-6 * dist[ok]))
        sub = np.flatnonzero(ok)
        ok[sub[~good]] = False
        th[:, j] = np.arccos(np.clip(np.abs(_plane_dot(world, u, pl)), 0.0, 1.0))
        cur = q[:, j]
        target = _reflect_rows(world, target, pl)
    # last leg: from the last reflection point (or the radar) to the centre, unobstructed, facing
    leg = points - cur
    dist = np.linalg.norm(leg, axis=1)
    u = leg / np.maximum(dist, 1e-12)[:, None]
    facing = ~np.any(normals != 0, axis=1) | (np.einsum("ij,ij->i", normals, -u) > 0)
    ok &= facing & (dist > 1e-6)
    if ok.any():
        skip = START if k > 0 else 0.0
        _, hit = world.caster.first_hit(cur[ok] + skip * u[ok], u[ok])
        sub = np.flatnonzero(ok)
        ok[sub[hit + skip < dist[ok] - 1e-6]] = False
    return ok, virt, q, th


def _plane_dot(world: World, x: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """n_{planes[r]}ᵀ x_r for x (K, 3): one matvec ``x @ n`` per distinct plane, the product the
    single-chain code takes (BLAS fuses multiply-adds, so a hand-written row sum would differ in
    the last bit and the maps would no longer be bit-identical)."""
    out = np.empty(len(x))
    for p in np.unique(planes):
        m = planes == p
        out[m] = x[m] @ world.plane_n[p]
    return out


def _reflect_rows(world: World, points: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """Row r of points (K, 3) mirrored across its own plane ``planes[r]`` (Eq. 7 in 3-D, as
    :func:`sims.raytrace.world.reflect_points`)."""
    return points - 2.0 * (_plane_dot(world, points, planes) + world.plane_d[planes])[:, None] * world.plane_n[planes]


def bistatic_power(radar: RadarConfig, la, lb, az_a, az_b, sigma) -> np.ndarray:
    """Received power [W] out along a (one-way length la [m], departure az_a) and back along b:
    P_t·G_tx(az_a)·G_e(az_a)·G_e(az_b)·λ²·σ / ((4π)³·la²·lb²·L_sys) — reflectivities excluded."""
    g = element_gain(radar, az_a) * element_gain(radar, az_b) * transmit_gain(radar, az_a)
    loss = 10.0 ** (radar.system_loss_db / 10.0)
    return radar.transmit_power * g * radar.wavelength**2 * sigma / ((4 * np.pi) ** 3 * la**2 * lb**2 * loss)
