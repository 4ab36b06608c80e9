"""Image-method forward model (paper Sec. 3.1, Eq. 3–5): LOS returns plus specular mirror paths.

Each relay wall is a mirror (Eq. 2): a hidden scatterer o seen via wall Π appears at its virtual
image o' = R_Π(o) (Eq. 5), with unfolded round trip L = 2|o'| and path loss 1/L² per leg (Eq. 4).
Walls also return diffusely in line of sight (extended targets sampled at ``wall.spacing``).
Every path is then rendered through the FMCW chain of :mod:`xnlos_core.signal_chain`.

Components are added only when the scene or configuration asks for them (``Params``: each
"auto", "on" or "off"; the frame's ``meta["components"]`` says what was used and why):

* ``diffuse``: LOS echoes of walls with a material from the roughness lobe (:mod:`sims.walls`);
  walls given by constants always return σ⁰·cos²ψ.
* ``transmission``: objects behind walls of finite thickness seen through them, power ×|T|⁴
  per crossed wall (direct paths only); opaque walls (no material or no thickness) block.
* ``atmosphere``: ITU-R P.676 gaseous loss over each round trip, when the scene declares an
  atmosphere and the loss over the longest path reaches ``tolerance_db``.
* ``coupling``: the radar's mutual-coupling matrix mixes the channels (:mod:`xnlos_core.antenna`).

Simplifications (deliberate, first-order model): only walls occlude (objects do not shadow
walls or each other); one relay bounce on each side of an object (no wall–wall or multi-wall
chains); the scene is 2-D (all paths in the horizontal plane, ε = 0) with wall height entering
only the diffuse wall RCS.
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from typing import Literal

from xnlos_core.errors import InputError
from xnlos_core.geometry import cartesian_to_polar, mirror_reflect, ray_segment_intersection, segments_intersect
from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.signal_chain import add_noise, dechirp, ra_map_from_cube
from xnlos_core.types import Frame, GroundTruth

from . import walls as wall_em
from .atmosphere import attenuation_db
from .propagation import DETECTABLE_SNR_DB, ra_snr_db, received_power

_ORIGIN = np.zeros(2)
Switch = Literal["auto", "on", "off"]
COMPONENTS = ("diffuse", "transmission", "atmosphere", "coupling")


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
        min_snr_db: float = Field(DETECTABLE_SNR_DB, ge=-100, le=200,
                                  description="ground truth lists a path only above this RA-map SNR [dB] "
                                              "(default: detectable at pd 0.5, pfa 1e-5)")
        mirror_paths: bool = Field(True, description="model relay-wall (mNLOS) mirror paths")
        reflection: Literal["analytic", "fdtd"] = Field(
            "analytic", description="wall reflection coefficients from the slab formula or the cached FDTD solver")
        diffuse: Switch = Field("auto", description="diffuse roughness lobe of material walls (LOS echoes)")
        transmission: Switch = Field("auto", description="direct paths through walls of finite thickness")
        atmosphere: Switch = Field("auto", description="ITU-R P.676 gaseous loss")
        coupling: Switch = Field("auto", description="the radar's mutual-coupling matrix")
        tolerance_db: float = Field(0.1, ge=0, le=60, description="'auto' leaves out a loss term whose "
                                                                   "largest effect stays below this [dB]")

    def components(self, scene, radar: RadarConfig) -> dict[str, str]:
        """Which optional components this scene and radar need: name → "on" or "off: reason"."""
        return components_needed(self.params, scene, radar)

    def check(self, scene, radar: RadarConfig) -> None:
        """InputError for a scene with meshes (the image method models walls and objects only) or a
        wall of unknown material."""
        wall_em.check_materials(scene)
        if scene.meshes:
            raise InputError(f"image forward model: scene {scene.name!r} has {len(scene.meshes)} mesh(es); the "
                             "image method handles walls and objects only (use the 'raytrace' forward model)")
        self.components(scene, radar)

    def simulate(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                 index: int = 0) -> Frame:
        """Render ``scene`` at ``timestamp`` [s] into a Frame with its RA map and ground truth."""
        return self.simulate_adc(scene, radar, rng, timestamp, index)[1]

    def simulate_adc(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                     index: int = 0) -> tuple[np.ndarray, Frame]:
        """Like :meth:`simulate`, also returning the noisy ADC cube (n_samples, n_channels) [√W]
        the RA map was formed from (what a hardware emulator sends)."""
        p = self.params
        use = self.components(scene, radar)
        on = {k: v == "on" for k, v in use.items()}
        if not on["coupling"] and radar.has_coupling:
            radar_syn = radar.model_copy(update={"coupling_db": None, "coupling_file": None})
        else:
            radar_syn = radar
        self.check(scene, radar)
        planar = scene.planar_walls()  # curved walls as planar facets, each its own mirror
        segs = tuple(w.segment() for w in planar)
        objs = [o.scatterers(timestamp) for o in scene.objects]  # (pos (K,2), normal (K,2), rcs (K,))

        # Random phases first, in a fixed order (walls, then objects), one per scatterer: the rng
        # stream then does not depend on visibility, and an object keeps its phase on every path.
        walls = [_wall_scatterers(w) for w in planar]
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

        # --- LOS: diffuse wall returns, σ = σ⁰(ψ)·Δs·h per cell --------------------------------
        for i, (spec, seg, (pts, ds)) in enumerate(zip(planar, segs, walls)):
            if seg.offset <= 0 or (spec.material is not None and not on["diffuse"]):
                continue  # radar on the wall line (grazing), or the lobe is not modelled
            r, th = cartesian_to_polar(pts)
            cos_psi = (-pts @ seg.normal) / r  # incidence angle from the wall normal (towards radar)
            vis = (cos_psi > 0) & ~_blocked(_ORIGIN, pts, segs, skip=i)
            psi = np.arccos(np.clip(cos_psi[vis], -1.0, 1.0))
            sigma = wall_em.backscatter_sigma0(spec, radar, psi) * ds * spec.height
            emit(pts[vis], received_power(radar, r[vis], th[vis], sigma), wall_phase[i][vis], 0)

        # --- LOS: objects seen directly, or through thin walls -----------------------------------
        for j, (pts, nrm, rcs) in enumerate(objs):
            face = _faces(nrm, pts, _ORIGIN)
            gain = np.where(_blocked(_ORIGIN, pts, segs), 0.0, 1.0)
            if on["transmission"]:
                gain = _through_walls(planar, segs, radar, pts)
            vis = face & (gain > 0)
            r, th = cartesian_to_polar(pts[vis])
            emit(pts[vis], received_power(radar, r, th, rcs[vis] * gain[vis]), obj_phase[j][vis], 0, obj=j)

        # --- mNLOS: one specular bounce on each side of the object (Eq. 3, 5) ------------------
        if p.mirror_paths:
            for i, (spec, seg) in enumerate(zip(planar, segs)):
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
                    inc = np.arccos(np.clip(np.abs(w[ok] @ n) / np.linalg.norm(w[ok], axis=1), 0.0, 1.0))
                    alpha = wall_em.specular_alpha(spec, radar, inc, p.reflection)
                    power = received_power(radar, r, th, rcs[ok], alpha)
                    emit(img[ok], power, obj_phase[j][ok], 1, hidden=pts[ok], obj=j)

        r, th, power, phase = (_cat(cols[k]) for k in ("r", "th", "power", "phase"))
        kind, gt_obj = _cat(cols["kind"]).astype(int), _cat(cols["obj"]).astype(int)
        pos, hidden = _cat(cols["pos"], (0, 2)), _cat(cols["hidden"], (0, 2))
        if on["atmosphere"] and len(r):
            conditions = (scene.atmosphere.model_dump() if scene.atmosphere is not None else {})
            power = power * 10 ** (-attenuation_db(radar.carrier_frequency, 2 * r, **conditions) / 10)
        live = power > 0  # drop paths behind the array (zero element gain)

        cube = dechirp(radar_syn, 2 * r[live], th[live], np.sqrt(power[live]) * np.exp(1j * phase[live]))
        if p.noise:
            cube = add_noise(cube, radar_syn, rng)
        ra = ra_map_from_cube(cube, radar)

        # Ground truth: paths a radar could see in this map (inside FOV and range, above SNR).
        snr_db = ra_snr_db(radar, power)
        seen = live & (snr_db >= p.min_snr_db) & (np.abs(th) <= radar.field_of_view) & (r <= radar.max_range)
        los, mn = seen & (kind == 0), seen & (kind == 1)
        gt = GroundTruth(los_points=pos[los], mnlos_points=pos[mn], hidden_points=hidden[mn],
                         mnlos_object=gt_obj[mn], object_names=tuple(o.name for o in scene.objects),
                         walls=segs, los_snr_db=snr_db[los], mnlos_snr_db=snr_db[mn])
        meta = {"scene": scene.name, "n_paths": int(live.sum()), "n_los_paths": int((live & (kind == 0)).sum()),
                "n_mnlos_paths": int((live & (kind == 1)).sum()), "forward_model": "image",
                "components": use}
        return cube, Frame(ra, timestamp=float(timestamp), ground_truth=gt, index=int(index), meta=meta)


def _through_walls(planar, segs, radar: RadarConfig, pts: np.ndarray) -> np.ndarray:
    """(K,) round-trip power factor Π|T(θ_i)|⁴ over the walls the segment radar → pts crosses
    (1 where none, 0 where an opaque wall is crossed)."""
    gain = np.ones(len(pts))
    for spec, seg in zip(planar, segs):
        cross = segments_intersect(_ORIGIN, pts, seg.start, seg.end)
        if not cross.any():
            continue
        r = np.linalg.norm(pts[cross], axis=1)
        inc = np.arccos(np.clip(np.abs(pts[cross] @ seg.normal) / r, 0.0, 1.0))
        gain[cross] *= np.abs(wall_em.transmission(spec, radar, inc)) ** 4
    return gain


def components_needed(p, scene, radar: RadarConfig) -> dict[str, str]:
    """Decide the optional components (module doc) from switches ``p`` (fields named as
    COMPONENTS, each "auto"/"on"/"off", and tolerance_db): name → "on" or "off: reason"."""
    mat = [w for w in scene.walls if w.material is not None]
    need = {
        "diffuse": (any(w.roughness > 0 for w in mat)
                    or any(m.roughness > 0 and (m.material or m.materials) for m in scene.meshes),
                    "no rough material wall"),
        "transmission": (bool(scene.objects) and any(w.thickness is not None for w in mat),
                         "no object and finite-thickness material wall"),
        "coupling": (radar.has_coupling, "radar has no coupling matrix"),
    }
    if scene.atmosphere is None:
        need["atmosphere"] = (False, "scene declares no atmosphere")
    else:
        worst = float(attenuation_db(radar.carrier_frequency, 2 * radar.max_range, **scene.atmosphere.model_dump()))
        need["atmosphere"] = (worst >= p.tolerance_db,
                              f"≤ {worst:.3g} dB over the longest round trip < tolerance {p.tolerance_db} dB")
    out = {}
    for name in COMPONENTS:
        switch = getattr(p, name)
        on, why = need[name]
        out[name] = "on" if switch == "on" or (switch == "auto" and on) else (
            "off: switched off" if switch == "off" else f"off: {why}")
    return out
