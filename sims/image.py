"""Image-method forward model (paper Sec. 3.1, Eq. 3–5): LOS returns plus specular mirror paths.

Each relay wall is a mirror (Eq. 2): a hidden scatterer o seen via wall Π appears at its virtual
image o' = R_Π(o) (Eq. 5), with unfolded round trip L = 2|o'| and path loss 1/L² per leg (Eq. 4).
Walls also return diffusely in line of sight (extended targets sampled at ``wall.spacing``).
Every path is then rendered through the FMCW chain of :mod:`xnlos_core.signal_chain`.

Simplifications (deliberate, first-order model): only walls occlude (objects do not shadow
walls or each other); one relay bounce on each side of an object (no wall–wall or multi-wall
chains); the specular reflectivity α does not depend on incidence angle; the scene is 2-D with
wall height entering only the diffuse wall RCS.
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.antenna import element_gain
from xnlos_core.geometry import cartesian_to_polar, mirror_reflect, ray_segment_intersection, segments_intersect
from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.signal_chain import add_noise, dechirp, processing_gain, ra_map_from_cube
from xnlos_core.types import Frame, GroundTruth

_ORIGIN = np.zeros(2)


def received_power(radar: RadarConfig, r, theta, sigma, alpha=1.0) -> np.ndarray:
    """Radar equation per path [W] (Eq. 4 per leg, unfolded leg lengths r_t = r_r = r):

        P_r = P_t·G(θ)²·λ²·σ·|α|⁴ / ((4π)³·r⁴·L_sys)

    r [m] (unfolded one-way range, |o| direct or |o'| mirrored); θ arrival azimuth [rad];
    σ [m²]; α specular amplitude reflectivity of the relay wall (two bounces → |α|⁴ in power).
    """
    g = element_gain(radar, theta)
    loss = 10.0 ** (radar.system_loss_db / 10.0)
    num = radar.transmit_power * g * g * radar.wavelength**2 * np.asarray(sigma) * np.abs(alpha) ** 4
    return num / ((4 * np.pi) ** 3 * np.asarray(r, dtype=np.float64) ** 4 * loss)


def _blocked(p0, p1, segments, skip: int | None = None) -> np.ndarray:
    """True where segment p0→p1 (…, 2) crosses any wall segment except index ``skip``."""
    p1 = np.asarray(p1, dtype=np.float64)
    out = np.zeros(p1.shape[:-1], dtype=bool)
    for i, seg in enumerate(segments):
        if i != skip:
            out |= segments_intersect(p0, p1, seg.start, seg.end)
    return out


def _faces(normals: np.ndarray, points: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """Back-face culling: a face sees ``towards`` if n·(towards − p) > 0; point scatterers (n = 0) always do."""
    point_like = ~np.any(normals != 0, axis=-1)
    return point_like | (np.einsum("ij,ij->i", normals, towards - points) > 0)


def _cat(parts: list[np.ndarray], empty_shape=(0,)) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(empty_shape)


def _wall_scatterers(spec) -> tuple[np.ndarray, float]:
    """Cell centres (K, 2) [m] of a wall cut into K ≈ length/spacing cells, and the cell length [m]."""
    start, end = np.asarray(spec.start, float), np.asarray(spec.end, float)
    k = max(1, int(round(math.dist(spec.start, spec.end) / spec.spacing)))
    s = (np.arange(k) + 0.5) / k
    return start + s[:, None] * (end - start), math.dist(spec.start, spec.end) / k


class ImageForwardModel(ForwardModel):
    """Image-method NLOS forward model: LOS walls/objects plus relay-wall mirror paths (Eq. 3–5)."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        noise: bool = Field(True, description="add receiver thermal noise (radar.noise_power per sample)")
        random_phase: bool = Field(True, description="uniform random phase per scatterer (speckle)")
        min_snr_db: float = Field(0.0, ge=-100, le=200,
                                  description="ground truth lists a path only above this RA-map SNR [dB]")
        mirror_paths: bool = Field(True, description="model relay-wall (mNLOS) mirror paths")

    def simulate(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                 index: int = 0) -> Frame:
        """Render ``scene`` at ``timestamp`` [s] into a Frame with its RA map and ground truth."""
        p = self.params
        segs = scene.wall_segments()
        objs = [o.scatterers(timestamp) for o in scene.objects]  # (pos (K,2), normal (K,2), rcs (K,))

        # Random phases first, in a fixed order (walls, then objects), one per scatterer: the rng
        # stream then does not depend on visibility, and an object keeps its phase on every path.
        walls = [_wall_scatterers(w) for w in scene.walls]
        sizes = [len(pts) for pts, _ in walls] + [len(o[0]) for o in objs]
        drawn = [rng.uniform(0, 2 * np.pi, n) if p.random_phase else np.zeros(n) for n in sizes]
        wall_phase, obj_phase = drawn[:len(walls)], drawn[len(walls):]

        # Each path: unfolded one-way range r [m], arrival azimuth [rad], power [W], phase,
        # ground-truth kind (0 LOS, 1 mNLOS), GT position (LOS point or o'), hidden o, object index.
        cols = {k: [] for k in ("r", "th", "power", "phase", "kind", "pos", "hidden", "obj")}

        def emit(points, power, phase, kind, hidden=None, obj=-1):
            r, th = cartesian_to_polar(points)
            row = dict(r=r, th=th, power=power, phase=phase, kind=np.full(len(r), kind), pos=points,
                       hidden=points if hidden is None else hidden, obj=np.full(len(r), obj))
            for k, v in row.items():
                cols[k].append(v)

        # --- LOS: diffuse wall returns, σ = σ⁰·cos²ψ·Δs·h per cell ---------------------------
        for i, (spec, seg, (pts, ds)) in enumerate(zip(scene.walls, segs, walls)):
            if seg.offset <= 0:  # radar on the wall line: grazing, no return
                continue
            r, th = cartesian_to_polar(pts)
            cos_psi = (-pts @ seg.normal) / r  # incidence angle from the wall normal (towards radar)
            vis = (cos_psi > 0) & ~_blocked(_ORIGIN, pts, segs, skip=i)
            sigma = 10 ** (spec.backscatter_db / 10) * cos_psi**2 * ds * spec.height
            emit(pts[vis], received_power(radar, r[vis], th[vis], sigma[vis]), wall_phase[i][vis], 0)

        # --- LOS: objects seen directly -------------------------------------------------------
        for j, (pts, nrm, rcs) in enumerate(objs):
            vis = _faces(nrm, pts, _ORIGIN) & ~_blocked(_ORIGIN, pts, segs)
            r, th = cartesian_to_polar(pts[vis])
            emit(pts[vis], received_power(radar, r, th, rcs[vis]), obj_phase[j][vis], 0, obj=j)

        # --- mNLOS: one specular bounce on each side of the object (Eq. 3, 5) ------------------
        if p.mirror_paths:
            for i, (spec, seg) in enumerate(zip(scene.walls, segs)):
                if not spec.relay or seg.offset <= 0:
                    continue
                n, b = seg.normal, seg.offset
                for j, (pts, nrm, rcs) in enumerate(objs):
                    near = pts @ n + b > 0  # object on the radar side of the mirror
                    img = mirror_reflect(pts, n, b)  # o' (Eq. 7 without residual)
                    t, s = ray_segment_intersection(img, seg.start, seg.end)
                    ok = near & (s >= 0) & (s <= 1) & (t > 0) & (t < 1)  # specular point on the wall
                    w = np.where(ok[:, None], np.nan_to_num(t)[:, None] * img, 0.0)
                    ok &= ~_blocked(_ORIGIN, w, segs, skip=i) & ~_blocked(w, pts, segs, skip=i)
                    ok &= _faces(nrm, pts, w)
                    r, th = cartesian_to_polar(img[ok])
                    power = received_power(radar, r, th, rcs[ok], spec.reflectivity)
                    emit(img[ok], power, obj_phase[j][ok], 1, hidden=pts[ok], obj=j)

        r, th, power, phase = (_cat(cols[k]) for k in ("r", "th", "power", "phase"))
        kind, gt_obj = _cat(cols["kind"]).astype(int), _cat(cols["obj"]).astype(int)
        pos, hidden = _cat(cols["pos"], (0, 2)), _cat(cols["hidden"], (0, 2))
        live = power > 0  # drop paths behind the array (zero element gain)

        cube = dechirp(radar, 2 * r[live], th[live], np.sqrt(power[live]) * np.exp(1j * phase[live]))
        if p.noise:
            cube = add_noise(cube, radar, rng)
        ra = ra_map_from_cube(cube, radar)

        # Ground truth: paths a radar could see in this map (inside FOV and range, above SNR).
        with np.errstate(divide="ignore"):
            snr_db = 10 * np.log10(power * processing_gain(radar) / radar.noise_power)
        seen = live & (snr_db >= p.min_snr_db) & (np.abs(th) <= radar.field_of_view) & (r <= radar.max_range)
        los, mn = seen & (kind == 0), seen & (kind == 1)
        gt = GroundTruth(los_points=pos[los], mnlos_points=pos[mn], hidden_points=hidden[mn],
                         mnlos_object=gt_obj[mn], object_names=tuple(o.name for o in scene.objects),
                         walls=segs)
        meta = {"scene": scene.name, "n_paths": int(live.sum()), "n_los_paths": int((live & (kind == 0)).sum()),
                "n_mnlos_paths": int((live & (kind == 1)).sum()), "forward_model": "image"}
        return Frame(ra, timestamp=float(timestamp), ground_truth=gt, index=int(index), meta=meta)
