"""Forward model ``raytrace``: scenes as triangle meshes, SBR-guided exact multipath (:mod:`.tracer`).

Per frame: build the mesh world at time t, check the radar is outside every solid, shoot the
ray fan (diffuse wall strips, seen directly and in mirrors, and the specular chains), trace
image paths from every object scattering centre through every chain, optionally add mixed
out-and-back paths (:class:`sims.paths.Paths`), then render them as every forward model does
(:func:`sims.render.render_paths`). Ground truth lists LOS points (wall strips and object centres
seen directly) and mNLOS points (object centres and strips via one mirror) whose resolution cell
reaches ``min_snr_db`` inside the field of view; other multipath is clutter, not ground truth.

Models only what the scene needs (as ``image``): the diffuse lobe of material walls when they
are rough, the diffuse three-bounce NLOS path via mostly diffuse relay walls (:mod:`.diffuse`,
same switch and ``auto`` rule as ``image``), the P.676 atmosphere when declared and above
``tolerance_db``, coupling when the radar has it. Slab transmission is not modelled by the ray tracer (use ``image``).
"""
from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame

from sims import diffuse_nlos
from sims import walls as wall_em
from sims.motion_paths import mirror_velocity, object_velocity
from sims.ground import centre_height
from sims.params import ForwardParams, components_needed
from sims.paths import OTHER, PathList
from sims.propagation import received_power
from sims.render import render_paths

from .diffuse import diffuse_paths
from .tracer import Trace, bistatic_power, em_groups, image_paths_chains, shoot
from .world import build_world, check_radar_outside


class RaytraceParams(ForwardParams):
    """``raytrace``'s parameters: the shared ones (:class:`sims.params.ForwardParams`) and the ray fan's."""

    az_step: float = Field(math.radians(0.2), gt=1e-5, le=0.1, description="ray fan spacing [rad]")
    max_bounces: int = Field(3, ge=0, le=10, description="specular bounces one way (cap; depth adapts)")
    depth_margin_db: float = Field(10.0, ge=0, le=100, description="a ray stops bouncing when the brightest "
                                   "scatterer would fall this far below min_snr_db [dB]")
    mixed_paths: bool = Field(True, description="add mixed paths: out along one chain, back along another "
                                               "(bistatic)")
    radar_height: float = Field(0.75, gt=0, le=100, description="antenna mounting height above ground [m]")
    backend: Literal["auto", "embree", "triangle"] = Field(
        "auto", description="ray-casting backend: 'embree' (embreex), 'triangle' (trimesh, numpy + rtree) or "
                            "'auto' (embree when available)")
    transmission: Literal["off"] = Field("off", description="not modelled by the ray tracer (use 'image')")

    dump_always = frozenset({"radar_height"})  # a raytrace field before it was shared


class RaytraceForwardModel(ForwardModel):
    """Mesh ray tracer with exact image paths to scattering centres (module doc)."""

    Params = RaytraceParams

    def components(self, scene, radar: RadarConfig) -> dict[str, str]:
        """Optional components this scene and radar need: name → "on" or "off: reason"."""
        return {**components_needed(self.params, scene, radar),
                "diffuse_nlos": diffuse_nlos.decide(self.params.diffuse_nlos, scene, radar)}

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
        """Geometry only: (world, Paths without random phases, Trace, components in use). For pictures and tests."""
        p = self.params
        use = self.components(scene, radar)
        world = build_world(scene, timestamp, p.backend)
        origin = np.array([0.0, 0.0, p.radar_height])
        check_radar_outside(world, origin, scene)
        heights = np.array([_height(world, s) for s in range(len(world.surfaces))])
        centres = [o.scatterers(timestamp) for o in scene.objects]
        sigma_bound = max([float(np.sum(c[2])) for c in centres] + [1.0])
        paths = PathList()
        tr = shoot(world, radar, origin, heights, az_step=p.az_step, max_bounces=p.max_bounces,
                   snr_floor_db=p.min_snr_db - p.depth_margin_db, sigma_bound=sigma_bound,
                   reflection=p.reflection, diffuse=use["diffuse"] == "on", paths=paths,
                   keep_segments=keep_segments)
        self._object_paths(world, radar, origin, scene, centres, tr, paths, timestamp)
        if use["diffuse_nlos"] == "on":  # last: Trace.diffuse_cells rows are the last paths
            z = [centre_height(o, p.radar_height) for o in scene.objects]
            c3 = [(np.column_stack([c[0], np.full(len(c[0]), zj)]), np.column_stack([c[1], np.zeros(len(c[1]))]),
                   c[2]) for c, zj in zip(centres, z)]
            vel = [np.append(object_velocity(o, timestamp), 0.0) for o in scene.objects]
            tr.diffuse_cells, tr.n_cells, record = diffuse_paths(world, scene, radar, origin, c3, vel, p, paths)
            use = {**use, "diffuse_nlos_cut": record}
        return world, paths.paths(), tr, use

    def _object_paths(self, world, radar, origin, scene, centres, tr: Trace, paths: PathList,
                      timestamp: float) -> None:
        p = self.params
        chains = {(): None, **tr.chains}
        points = [np.column_stack([pts2, np.full(len(pts2), centre_height(scene.objects[j], p.radar_height))])
                  for j, (pts2, _, _) in enumerate(centres)]
        normals = [np.column_stack([nrm2, np.zeros(len(nrm2))]) for _, nrm2, _ in centres]
        # every centre through every chain, one cast per leg and chain length (not per object and chain)
        images = image_paths_chains(world, origin, points, normals, chains, p.az_step)
        alphas = self._chain_alphas(world, radar, chains, images, [len(x) for x in points])
        for j, (_, _, rcs) in enumerate(centres):
            pts = points[j]
            v3 = np.append(object_velocity(scene.objects[j], timestamp), 0.0)
            found = []  # (order, mask, one-way length, departure azimuth, complex α, one-way range rate)
            for planes in chains:
                ok, virt, _ = images[j, planes]
                if not ok.any():
                    continue
                rel = virt - origin
                L = np.linalg.norm(rel, axis=1)
                az = np.arctan2(rel[:, 1], rel[:, 0])
                alpha = alphas[j, planes]
                # the virtual point moves at the velocity reflected like the point (image_paths' order)
                vv = mirror_velocity(v3, [world.plane_n[pl] for pl in reversed(planes)]) if planes else v3
                rate = rel @ vv / np.maximum(L, 1e-12)
                found.append((len(planes), ok, L, az, alpha, rate))
                P = received_power(radar, L[ok], az[ok], rcs[ok], np.abs(alpha[ok]))
                amp = np.sqrt(P) * np.exp(2j * np.angle(alpha[ok]))
                paths.add(length=2 * L[ok], azimuth=az[ok], amp=amp, power=P,
                          kind=np.where(len(planes) == 0, 0, np.where(len(planes) == 1, 1, 2)), order=len(planes),
                          pos=virt[ok, :2], hidden=pts[ok, :2], obj=j, centre=np.flatnonzero(ok), velocity=vv[:2],
                          height=pts[ok, 2])
            if p.mixed_paths:
                for a in range(len(found)):
                    for b in range(len(found)):
                        if a == b:
                            continue
                        ka, oka, La, aza, ala, ra = found[a]
                        kb, okb, Lb, azb, alb, rb = found[b]
                        both = oka & okb
                        if not both.any():
                            continue
                        P = bistatic_power(radar, La[both], Lb[both], aza[both], azb[both], rcs[both])
                        P = P * np.abs(ala[both] * alb[both]) ** 2
                        amp = np.sqrt(P) * np.exp(1j * np.angle(ala[both] * alb[both]))
                        Lr = La[both] + Lb[both]
                        u = np.stack([np.cos(azb[both]), np.sin(azb[both])], axis=1)
                        paths.add(length=Lr, azimuth=azb[both], amp=amp, power=P, kind=OTHER, order=ka + kb,
                                  pos=u * (Lr / 2)[:, None], hidden=pts[both, :2], obj=j,
                                  centre=np.flatnonzero(both), height=pts[both, 2],
                                  velocity=u * ((ra[both] + rb[both]) / 2)[:, None])  # d(Lr/2)/dt along pos

    def _chain_alphas(self, world, radar, chains, images, sizes) -> dict:
        """{(j, planes): α (K_j,) complex}: the chain reflectivity Π_k α(θ_k) of object j's centres,
        one α evaluation per group of electromagnetically equal surfaces over every object's
        centres, chains and bounces (element-wise, so the same numbers as per object and chain);
        chains no centre takes are left out."""
        used = [c for c in chains if any(images[j, c][0].any() for j in range(len(sizes)))]
        th = {c: np.concatenate([images[j, c][2] for j in range(len(sizes))]) for c in used}
        # α(θ) of every (chain, bounce) column, one evaluation per group of equal surfaces
        group = em_groups(world)
        cols = [(c, k, int(world.plane_surface[pl])) for c in used for k, pl in enumerate(c)]
        one = {}
        for g in sorted({group[s] for _, _, s in cols}):
            mine = [(c, k, s) for c, k, s in cols if group[s] == g]
            a = wall_em.specular_alpha(world.surfaces[mine[0][2]], radar,
                                       np.concatenate([th[c][:, k] for c, k, _ in mine]), self.params.reflection)
            for (c, k, _), part in zip(mine, np.split(a, np.cumsum([len(th[c]) for c, _, _ in mine])[:-1])):
                one[c, k] = part
        out = {}
        for c in used:
            alpha = np.ones(len(th[c]), dtype=np.complex128)
            for k in range(len(c)):
                alpha *= one[c, k]
            for j, part in enumerate(np.split(alpha, np.cumsum(sizes)[:-1])):
                out[j, c] = part
        return out

    def simulate_adc(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                     index: int = 0) -> tuple[np.ndarray, Frame]:
        """Like :meth:`simulate`, also returning the noisy ADC cube (n_samples, n_channels) [√W]."""
        p = self.params
        t0 = time.perf_counter()
        world, paths, tr, use = self.trace(scene, radar, timestamp)
        t_trace = time.perf_counter() - t0
        # phases: one per object scattering centre (fixed order, all paths of a centre share it),
        # one per wall strip
        n_obj = [len(o.scatterers(timestamp)[0]) for o in scene.objects]
        obj_phase = [rng.uniform(0, 2 * np.pi, n) if p.random_phase else np.zeros(n) for n in n_obj]
        strip = paths.centre < 0
        phase = np.zeros(len(paths))
        if p.random_phase:
            phase[strip] = rng.uniform(0, 2 * np.pi, int(strip.sum()))
        for j, ph in enumerate(obj_phase):
            m = (~strip) & (paths.obj == j)
            phase[m] = ph[paths.centre[m]]
        if p.random_phase and tr.n_cells:  # diffuse NLOS: one phase per wall cell, drawn after the others
            cell_phase = rng.uniform(0, 2 * np.pi, tr.n_cells)
            tail = slice(len(paths) - len(tr.diffuse_cells), len(paths))
            phase[tail] += cell_phase[tr.diffuse_cells[:, 0]] + cell_phase[tr.diffuse_cells[:, 1]]

        def describe(live):
            return {"n_other_paths": int((live & (paths.kind == OTHER)).sum()), "max_bounce": int(tr.max_order),
                    "max_order": int(paths.order[live].max()) if live.any() else 0, "rays": int(tr.rays),
                    "chains": len(tr.chains), "faces": int(world.caster.n_faces), "backend": world.caster.backend,
                    "trace_s": round(t_trace, 6)}

        return render_paths(paths.with_phase(phase), scene, radar, rng, p, use, forward_model="raytrace",
                            walls=scene.wall_segments(), timestamp=timestamp, index=index, cell_snr=True,
                            surface_names=[s.name for s in world.surfaces], describe=describe)


def _height(world, s: int) -> float:
    """Vertical extent [m] a static surface's strip stands for: its faces' z range."""
    tri = np.flatnonzero(world.tri_surface == s)
    if len(tri) == 0:
        return 0.0
    z = np.asarray(world.caster.mesh.vertices)[world.caster.mesh.faces[tri]][..., 2]
    return float(z.max() - z.min())
