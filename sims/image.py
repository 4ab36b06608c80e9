"""Image-method forward model (paper Sec. 3.1, Eq. 3–5): LOS returns plus specular mirror paths.

Each relay wall is a mirror (Eq. 2): a hidden scatterer o seen via wall Π appears at its virtual
image o' = R_Π(o) (Eq. 5), with unfolded round trip L = 2|o'| and path loss 1/L² per leg (Eq. 4).
Walls also return diffusely in line of sight (extended targets sampled at ``wall.spacing``).
The model finds these paths (:class:`sims.paths.Paths`); :func:`sims.render.render_paths` renders
them through the FMCW chain of :mod:`xnlos_core.signal.chain` into a Frame.

Components are added only when the scene or configuration asks for them (``Params``, shared with
``raytrace`` in :class:`sims.params.ForwardParams`: each "auto", "on" or "off"; the frame's
``meta["components"]`` says what was used and why):

* ``diffuse``: LOS echoes of walls with a material from the roughness lobe (:mod:`sims.walls`);
  walls given by constants always return σ⁰·cos²ψ.
* ``transmission``: objects behind walls of finite thickness seen through them, power ×|T|⁴
  per crossed wall (direct paths only); opaque walls (no material or no thickness) block.
* ``atmosphere``: ITU-R P.676 gaseous loss over each round trip, when the scene declares an
  atmosphere and the loss over the longest path reaches ``tolerance_db``.
* ``coupling``: the radar's mutual-coupling matrix mixes the channels (:mod:`xnlos_core.signal.antenna`).
* ``diffuse_nlos`` (as ``raytrace``): the three-bounce path radar → rough relay wall → object → wall →
  radar through the diffuse lobe (:mod:`sims.diffuse_nlos`), the power a rough wall takes out of the
  mirror path; auto: on when a relay material wall is mostly diffuse at the carrier (ρ_s(0) < ½).

Simplifications (deliberate, first-order model): only walls occlude (objects do not shadow
walls or each other); one relay bounce on each side of an object (no wall–wall or multi-wall
chains); paths are found in plan (vertical walls), an object's scattering centres at its
``centre_height`` (default: the radar's height, capped at the object's) lengthen its direct paths,
and the elevation pattern and ground twins enter when ``dimensions`` asks for them
(:mod:`sims.ground`); wall height enters only the diffuse wall RCS.
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from xnlos_core.errors import InputError
from xnlos_core.geometry import cartesian_to_polar, mirror_reflect, ray_segment_intersection, segments_intersect
from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame

from . import diffuse_nlos
from . import walls as wall_em
from .ground import centre_height
from .params import ForwardParams, components_needed
from .motion_paths import mirror_velocity, object_velocity
from .paths import LOS, MNLOS, OTHER, PathList, Paths
from .propagation import received_power
from .render import render_paths

_ORIGIN = np.zeros(2)


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


def _wall_scatterers(spec) -> tuple[np.ndarray, float]:
    """Cell centres (K, 2) [m] of a wall cut into K ≈ length/spacing cells, and the cell length [m]."""
    start, end = np.asarray(spec.start, float), np.asarray(spec.end, float)
    k = max(1, int(round(math.dist(spec.start, spec.end) / spec.spacing)))
    s = (np.arange(k) + 0.5) / k
    return start + s[:, None] * (end - start), math.dist(spec.start, spec.end) / k


class ImageForwardModel(ForwardModel):
    """Image-method NLOS forward model: LOS walls/objects plus relay-wall mirror paths (Eq. 3–5)."""

    class Params(ForwardParams):
        mirror_paths: bool = Field(True, description="model relay-wall (mNLOS) mirror paths (Eq. 3, 5)")

    def components(self, scene, radar: RadarConfig) -> dict[str, str]:
        """Which optional components this scene and radar need: name → "on" or "off: reason"."""
        return {**components_needed(self.params, scene, radar),
                "diffuse_nlos": diffuse_nlos.decide(self.params.diffuse_nlos, scene, radar)}

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
        use = self.components(scene, radar)
        self.check(scene, radar)
        planar = scene.planar_walls()  # curved walls as planar facets, each its own mirror
        cut: dict[str, str] = {}
        paths = self._paths(scene, planar, radar, rng, timestamp, {k: v == "on" for k, v in use.items()}, cut)
        use = {**use, **cut}
        return render_paths(paths, scene, radar, rng, self.params, use, forward_model="image",
                            walls=tuple(w.segment() for w in planar), timestamp=timestamp, index=index,
                            surface_names=[w.name for w in planar])

    def _paths(self, scene, planar, radar: RadarConfig, rng: np.random.Generator, timestamp: float,
               on: dict[str, bool], cut_out: dict | None = None) -> Paths:
        """The LOS and mirror paths of ``scene`` (walls as the planar facets ``planar``) at
        ``timestamp`` [s], with their random phases (drawn from ``rng`` first); ``on``: component
        name → in use; ``cut_out``: receives "diffuse_nlos_cut" (the importance cut's record) when given."""
        p = self.params
        segs = tuple(w.segment() for w in planar)
        objs = [o.scatterers(timestamp) for o in scene.objects]  # (pos (K,2), normal (K,2), rcs (K,))

        # Random phases first, in a fixed order (walls, then objects), one per scatterer: the rng
        # stream then does not depend on visibility, and an object keeps its phase on every path.
        walls = [_wall_scatterers(w) for w in planar]
        sizes = [len(pts) for pts, _ in walls] + [len(o[0]) for o in objs]
        drawn = [rng.uniform(0, 2 * np.pi, n) if p.random_phase else np.zeros(n) for n in sizes]
        wall_phase, obj_phase = drawn[:len(walls)], drawn[len(walls):]
        out = PathList()

        vel = [object_velocity(o, timestamp) for o in scene.objects]

        rise = [centre_height(o, p.radar_height) - p.radar_height for o in scene.objects]  # h_t − h_r [m]

        def emit(points, power, phase, kind, hidden=None, obj=-1, centre=-1, velocity=(0.0, 0.0)):
            r, th = cartesian_to_polar(points)
            dh = rise[obj] if obj >= 0 else 0.0
            out.add(length=2 * slant(r, dh), azimuth=th, power=power, phase=phase, kind=kind,
                    order=kind,  # image paths: LOS direct, mNLOS one bounce
                    pos=points, hidden=points if hidden is None else hidden, obj=obj, centre=centre,
                    velocity=velocity, height=p.radar_height + dh if obj >= 0 else np.nan)

        # --- LOS: diffuse wall returns, σ = σ⁰(ψ)·Δs·h per cell --------------------------------
        for i, (spec, seg, (pts, ds)) in enumerate(zip(planar, segs, walls)):
            if seg.offset <= 0 or (spec.material is not None and not on["diffuse"]):
                continue  # radar on the wall line (grazing), or the lobe is not modelled
            r, th = cartesian_to_polar(pts)
            cos_psi = (-pts @ seg.normal) / r  # incidence angle from the wall normal (towards radar)
            vis = (cos_psi > 0) & ~_blocked(_ORIGIN, pts, segs, skip=i)
            psi = np.arccos(np.clip(cos_psi[vis], -1.0, 1.0))
            sigma = wall_em.backscatter_sigma0(spec, radar, psi) * ds * spec.height
            emit(pts[vis], received_power(radar, r[vis], th[vis], sigma), wall_phase[i][vis], LOS, obj=-1 - i)

        # --- LOS: objects seen directly, or through thin walls -----------------------------------
        for j, (pts, nrm, rcs) in enumerate(objs):
            face = _faces(nrm, pts, _ORIGIN)
            gain = np.where(_blocked(_ORIGIN, pts, segs), 0.0, 1.0)
            if on["transmission"]:
                gain = _through_walls(planar, segs, radar, pts)
            vis = face & (gain > 0)
            r, th = cartesian_to_polar(pts[vis])
            power = received_power(radar, slant(r, rise[j]), th, rcs[vis] * gain[vis])
            emit(pts[vis], power, obj_phase[j][vis], LOS, obj=j,
                 centre=np.flatnonzero(vis), velocity=vel[j])

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
                    power = received_power(radar, slant(r, rise[j]), th, rcs[ok], alpha)
                    emit(img[ok], power, obj_phase[j][ok], MNLOS, hidden=pts[ok], obj=j, centre=np.flatnonzero(ok),
                         velocity=mirror_velocity(vel[j], n))  # the echo's Doppler is the virtual target's

        # --- diffuse NLOS: radar → rough relay wall → object → wall → radar (sims.diffuse_nlos) ---
        if on.get("diffuse_nlos"):
            rough = [i for i, (spec, seg) in enumerate(zip(planar, segs))
                     if spec.relay and seg.offset > 0 and spec.material is not None and spec.roughness > 0]
            budget = diffuse_nlos.noise_equivalent_power(radar) * 10 ** (p.diffuse_nlos_floor_db / 10)
            cut = [0, 0, 0.0, 0.0, False]  # kept paths, candidate pairs, total, neglected power [W], capped
            for i in rough:
                _diffuse_nlos(out, planar[i], segs[i], segs, i, radar, objs, obj_phase, walls[i], wall_phase[i], vel,
                              p.diffuse_nlos_cell, budget / len(rough), max(1, p.diffuse_nlos_max_paths // len(rough)),
                              cut)
            if cut_out is not None:
                cut_out["diffuse_nlos_cut"] = diffuse_nlos.describe_cut(*cut, radar)
        return out.paths()


def _diffuse_nlos(out: PathList, spec, seg, segs, i: int, radar: RadarConfig, objs, obj_phase, fine, fine_phase,
                  vel, cell_length: float, budget: float, cap: int, cut: list) -> None:
    """Append the three-bounce diffuse paths (:func:`sims.diffuse_nlos.wall_paths`) of relay wall ``i``
    for every object centre on its radar side; cell phases are those of the nearest LOS wall cell (no
    new draws). Visibility: 2-D segment tests against the other walls. ``cut`` accumulates
    [kept paths, candidate pairs, total power, neglected power, path cap reached]."""
    n, b = seg.normal, seg.offset
    a, ds = diffuse_nlos.cells(spec, cell_length)
    phase_a = fine_phase[np.argmin(np.linalg.norm(fine[0][None, :, :] - a[:, None, :], axis=2), axis=1)]
    lit = ((-a @ n) > 0) & ~_blocked(_ORIGIN, a, segs, skip=i)
    a, phase_a = a[lit], phase_a[lit]
    if len(a) == 0:
        return
    n3, a3 = np.append(n, 0.0), np.column_stack([a, np.zeros(len(a))])
    owner = np.concatenate([np.full(len(o[0]), j) for j, o in enumerate(objs)])  # object of each centre
    index = np.concatenate([np.arange(len(o[0])) for o in objs])
    pts = np.concatenate([o[0] for o in objs])
    nrm = np.concatenate([o[1] for o in objs])
    rcs = np.concatenate([o[2] for o in objs])
    near = np.flatnonzero(pts @ n + b > 0)  # centres on the radar side of the wall
    if len(near) == 0:
        return
    sees = np.stack([_faces(np.repeat(nrm[o][None], len(a), 0), np.repeat(pts[o][None], len(a), 0), a)
                     & (np.linalg.norm(pts[o] - a, axis=1) > 1e-6)
                     & ~_blocked(a, np.repeat(pts[o][None], len(a), 0), segs, skip=i) for o in near])
    v3 = np.array([np.append(vel[owner[o]], 0.0) for o in near])
    w = diffuse_nlos.wall_paths(radar, spec, n3, a3, ds * spec.height, np.zeros(3),
                                np.column_stack([pts[near], np.zeros(len(near))]), rcs[near], sees, v3, budget, cap)
    cut[:] = [cut[0] + len(w.power), cut[1] + w.pairs, cut[2] + w.total, cut[3] + w.neglected,
              cut[4] or w.capped]
    o = near[w.centre]
    obj_ph = np.array([obj_phase[owner[k]][index[k]] for k in o])
    u = np.column_stack([np.cos(w.azimuth), np.sin(w.azimuth)])
    out.add(length=w.length, azimuth=w.azimuth, power=w.power, phase=phase_a[w.ia] + obj_ph + phase_a[w.ib],
            kind=OTHER, order=1, pos=w.pos, hidden=w.hidden, obj=owner[o], centre=index[o],
            velocity=u * w.rate[:, None])


def slant(r: np.ndarray, rise: float) -> np.ndarray:
    """Direct one-way length √(r² + Δh²) [m] of horizontal length r [m] to a point Δh [m] above the
    radar (r itself where Δh = 0, so 2-D scenes keep their lengths to the bit)."""
    return r if rise == 0 else np.sqrt(np.asarray(r) ** 2 + rise**2)


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
