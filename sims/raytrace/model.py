"""Forward model ``raytrace``: scenes as triangle meshes, SBR-guided exact multipath (:mod:`.tracer`).

Per frame: build the mesh world at time t, check the radar is outside every solid, shoot the
ray fan (diffuse wall strips, seen directly and in mirrors, and the specular chains), trace
image paths from every object scattering centre through every chain, optionally add mixed
out-and-back paths, then render all paths through the shared FMCW chain
(:func:`xnlos_core.signal_chain.dechirp`) with receiver noise. Ground truth lists LOS points
(wall strips and object centres seen directly) and mNLOS points (object centres via one mirror)
that reach ``min_snr_db`` inside the field of view; other multipath is clutter, not ground truth.

Models only what the scene needs (as ``image``): the diffuse lobe of material walls when they
are rough, the P.676 atmosphere when declared and above ``tolerance_db``, coupling when the
radar has it. Slab transmission is not modelled by the ray tracer (use ``image``).
"""
from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.interfaces import ForwardModel
from xnlos_core.metrics import resolution_cell
from xnlos_core.radar import RadarConfig
from xnlos_core.signal_chain import add_noise, dechirp, ra_map_from_cube
from xnlos_core.types import Frame, GroundTruth

from sims.atmosphere import attenuation_db
from sims.image import Switch, components_needed
from sims.propagation import DETECTABLE_SNR_DB, ra_snr_db, received_power
from sims import walls as wall_em

from .tracer import Paths, Trace, bistatic_power, image_paths, shoot
from .world import build_world, check_radar_outside


class RaytraceParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    noise: bool = Field(True, description="add receiver thermal noise")
    random_phase: bool = Field(True, description="uniform random phase per scatterer and wall strip (speckle)")
    min_snr_db: float = Field(DETECTABLE_SNR_DB, ge=-100, le=200,
                              description="ground truth lists a path whose resolution cell reaches this RA SNR [dB] "
                                          "(default: detectable at pd 0.5, pfa 1e-5)")
    az_step: float = Field(math.radians(0.2), gt=1e-5, le=0.1, description="ray fan spacing [rad]")
    max_bounces: int = Field(3, ge=0, le=10, description="specular bounces one way (cap; depth adapts)")
    depth_margin_db: float = Field(10.0, ge=0, le=100, description="a ray stops bouncing when the brightest "
                                   "scatterer would fall this far below min_snr_db")
    mixed_paths: bool = Field(True, description="out along one chain, back along another")
    radar_height: float = Field(0.75, gt=0, le=100, description="antenna height above ground [m]")
    backend: Literal["auto", "embree", "triangle"] = Field("auto", description="ray-casting backend")
    reflection: Literal["analytic", "fdtd"] = "analytic"
    diffuse: Switch = "auto"
    transmission: Literal["off"] = Field("off", description="not modelled by the ray tracer")
    atmosphere: Switch = "auto"
    coupling: Switch = "auto"
    tolerance_db: float = Field(0.1, ge=0, le=60)


class RaytraceForwardModel(ForwardModel):
    """Mesh ray tracer with exact image paths to scattering centres (module doc)."""

    Params = RaytraceParams

    def components(self, scene, radar: RadarConfig) -> dict[str, str]:
        """Optional components this scene and radar need: name → "on" or "off: reason"."""
        return components_needed(self.params, scene, radar)

    def check(self, scene, radar: RadarConfig) -> None:
        """What :meth:`trace` refuses at t = 0: unreadable or unsupported meshes, the radar inside a
        wall or mesh, objects against walls, walls of unknown material (InputError)."""
        wall_em.check_materials(scene)
        self.components(scene, radar)
        world = build_world(scene, 0.0, self.params.backend)
        check_radar_outside(world, np.array([0.0, 0.0, self.params.radar_height]), scene)

    def simulate(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                 index: int = 0) -> Frame:
        """Render ``scene`` at ``timestamp`` [s] into a Frame with ground truth."""
        return self.simulate_adc(scene, radar, rng, timestamp, index)[1]

    def trace(self, scene, radar: RadarConfig, timestamp: float = 0.0, keep_segments: bool = False):
        """Geometry only: (world, Paths without phases, Trace, object centres). For pictures and tests."""
        p = self.params
        use = self.components(scene, radar)
        world = build_world(scene, timestamp, p.backend)
        origin = np.array([0.0, 0.0, p.radar_height])
        check_radar_outside(world, origin, scene)
        heights = np.array([_height(world, s) for s in range(len(world.surfaces))])
        centres = [o.scatterers(timestamp) for o in scene.objects]
        sigma_bound = max([float(np.sum(c[2])) for c in centres] + [1.0])
        paths = Paths()
        tr = shoot(world, radar, origin, heights, az_step=p.az_step, max_bounces=p.max_bounces,
                   snr_floor_db=p.min_snr_db - p.depth_margin_db, sigma_bound=sigma_bound,
                   reflection=p.reflection, diffuse=use["diffuse"] == "on", paths=paths,
                   keep_segments=keep_segments)
        self._object_paths(world, radar, origin, scene, centres, tr, paths)
        return world, paths, tr, use

    def _object_paths(self, world, radar, origin, scene, centres, tr: Trace, paths: Paths) -> None:
        p = self.params
        chains = {(): None, **tr.chains}
        for j, (pts2, nrm2, rcs) in enumerate(centres):
            z = min(p.radar_height, scene.objects[j].height)
            pts = np.column_stack([pts2, np.full(len(pts2), z)])
            nrm = np.column_stack([nrm2, np.zeros(len(nrm2))])
            found = []  # (order, mask, one-way length, departure azimuth, complex α)
            for planes, sector in chains.items():
                ok, virt, _, th = image_paths(world, origin, pts, nrm, planes, sector, p.az_step)
                if not ok.any():
                    continue
                rel = virt - origin
                L = np.linalg.norm(rel, axis=1)
                az = np.arctan2(rel[:, 1], rel[:, 0])
                alpha = np.ones(len(pts), dtype=np.complex128)
                for k, pl in enumerate(planes):
                    spec = world.surfaces[world.plane_surface[pl]]
                    alpha *= wall_em.specular_alpha(spec, radar, th[:, k], p.reflection)
                found.append((len(planes), ok, L, az, alpha))
                P = received_power(radar, L[ok], az[ok], rcs[ok], np.abs(alpha[ok]))
                amp = np.sqrt(P) * np.exp(2j * np.angle(alpha[ok]))
                paths.add(length=2 * L[ok], azimuth=az[ok], amp=amp, power=P,
                          kind=np.where(len(planes) == 0, 0, np.where(len(planes) == 1, 1, 2)), order=len(planes),
                          pos=virt[ok, :2], hidden=pts[ok, :2], obj=j, centre=np.flatnonzero(ok))
            if p.mixed_paths:
                for a in range(len(found)):
                    for b in range(len(found)):
                        if a == b:
                            continue
                        ka, oka, La, aza, ala = found[a]
                        kb, okb, Lb, azb, alb = found[b]
                        both = oka & okb
                        if not both.any():
                            continue
                        P = bistatic_power(radar, La[both], Lb[both], aza[both], azb[both], rcs[both])
                        P = P * np.abs(ala[both] * alb[both]) ** 2
                        amp = np.sqrt(P) * np.exp(1j * np.angle(ala[both] * alb[both]))
                        Lr = La[both] + Lb[both]
                        u = np.stack([np.cos(azb[both]), np.sin(azb[both])], axis=1)
                        paths.add(length=Lr, azimuth=azb[both], amp=amp, power=P, kind=2, order=ka + kb,
                                  pos=u * (Lr / 2)[:, None], hidden=pts[both, :2], obj=j,
                                  centre=np.flatnonzero(both))

    def simulate_adc(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                     index: int = 0) -> tuple[np.ndarray, Frame]:
        """Like :meth:`simulate`, also returning the noisy ADC cube (n_samples, n_channels) [√W]."""
        p = self.params
        t0 = time.perf_counter()
        world, paths, tr, use = self.trace(scene, radar, timestamp)
        t_trace = time.perf_counter() - t0
        a = paths.arrays()
        # phases: one per object scattering centre (fixed order, all paths of a centre share it),
        # one per wall strip
        n_obj = [len(o.scatterers(timestamp)[0]) for o in scene.objects]
        obj_phase = [rng.uniform(0, 2 * np.pi, n) if p.random_phase else np.zeros(n) for n in n_obj]
        strip = a["centre"] < 0
        phase = np.zeros(len(a["length"]))
        if p.random_phase:
            phase[strip] = rng.uniform(0, 2 * np.pi, int(strip.sum()))
        for j, ph in enumerate(obj_phase):
            m = (~strip) & (a["obj"] == j)
            phase[m] = ph[a["centre"][m].astype(int)]
        power = a["power"]
        amp = a["amp"] * np.exp(1j * phase)
        if use["atmosphere"] == "on" and len(power):
            cond = scene.atmosphere.model_dump() if scene.atmosphere is not None else {}
            att = 10 ** (-attenuation_db(radar.carrier_frequency, a["length"], **cond) / 10)
            power, amp = power * att, amp * np.sqrt(att)
        radar_syn = radar
        if use["coupling"] != "on" and radar.has_coupling:
            radar_syn = radar.model_copy(update={"coupling_db": None, "coupling_file": None})
        live = power > 0
        cube = dechirp(radar_syn, a["length"][live], a["azimuth"][live], amp[live])
        if p.noise:
            cube = add_noise(cube, radar_syn, rng)
        ra = ra_map_from_cube(cube, radar)
        snr = ra_snr_db(radar, _cell_power(radar, a, power))
        r_one = a["length"] / 2
        seen = live & (snr >= p.min_snr_db) & (np.abs(a["azimuth"]) <= radar.field_of_view) & (r_one <= radar.max_range)
        kind, obj = a["kind"].astype(int), a["obj"].astype(int)
        los, mn = seen & (kind == 0), seen & (kind == 1)
        names, owner = _mnlos_owners(scene, world, obj[mn])
        gt = GroundTruth(los_points=a["pos"][los], mnlos_points=a["pos"][mn], hidden_points=a["hidden"][mn],
                         mnlos_object=owner, object_names=names,
                         walls=scene.wall_segments(), los_snr_db=snr[los], mnlos_snr_db=snr[mn])
        order = a["order"].astype(int)
        meta = {"scene": scene.name, "forward_model": "raytrace", "n_paths": int(live.sum()),
                "n_los_paths": int((live & (kind == 0)).sum()), "n_mnlos_paths": int((live & (kind == 1)).sum()),
                "n_other_paths": int((live & (kind == 2)).sum()),
                "max_bounce": int(tr.max_order), "max_order": int(order[live].max()) if live.any() else 0,
                "rays": int(tr.rays),
                "chains": len(tr.chains), "faces": int(world.caster.n_faces), "backend": world.caster.backend,
                "trace_s": round(t_trace, 6), "components": use}
        return cube, Frame(ra, timestamp=float(timestamp), ground_truth=gt, index=int(index), meta=meta)


def _mnlos_owners(scene, world, obj: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """(object_names, (M,) owner index) for mNLOS paths of ``obj`` (object index ≥ 0, or −1 − s for a
    strip of surface s): the scene's objects, then ``"wall:<surface>"`` for each surface seen in a mirror."""
    names = [o.name for o in scene.objects]
    surfaces = np.unique(-1 - obj[obj < 0])
    owner = obj.copy()
    for k, s in enumerate(surfaces):
        owner[obj == -1 - s] = len(names) + k
    names += [f"wall:{world.surfaces[s].name}" for s in surfaces]
    return tuple(names), owner


def _cell_power(radar: RadarConfig, a: dict, power: np.ndarray) -> np.ndarray:
    """(P,) power [W] summed over the paths of the same kind and object that fall into the same
    resolution cell (c/2B in range, the −3 dB beamwidth in azimuth,
    :func:`xnlos_core.metrics.resolution_cell`): the expected power a detector sees of that
    object there (random phases add in power)."""
    if len(power) == 0:
        return power
    dr, da = resolution_cell(radar)
    rb = np.floor(a["length"] / 2 / dr).astype(np.int64)
    ab = np.floor(a["azimuth"] / da).astype(np.int64)
    key = np.column_stack([a["kind"].astype(np.int64), a["obj"].astype(np.int64), rb, ab])
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    return np.bincount(inv, weights=power)[inv]


def _height(world, s: int) -> float:
    """Vertical extent [m] a static surface's strip stands for: its faces' z range."""
    tri = np.flatnonzero(world.tri_surface == s)
    if len(tri) == 0:
        return 0.0
    z = np.asarray(world.caster.mesh.vertices)[world.caster.mesh.faces[tri]][..., 2]
    return float(z.max() - z.min())
