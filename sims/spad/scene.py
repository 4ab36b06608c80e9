"""A project Scene (xnlos_core.scene: walls and objects seen from above) as a confocal SPAD scan.

Mapping (world: x forward, y left, z up, sensor at the origin; DESIGN.md conventions):

* relay wall: ``SpadParams.wall`` names a wall (default: the scene's first planar relay facade);
  with start a and end b (top view), u = (b − a)/|b − a| runs along it and n ⟂ u is the normal
  toward the sensor's side — the side the sensor sees, and the hidden side of a confocal NLOS scan
  (the wall relays between the sensor and the objects in front of it).
* scan grid: W × H points over ``grid_width`` × ``grid_height`` [m], centred at the wall's midpoint
  shifted by ``grid_offset`` along u, at height ``grid_elevation`` above ground.
* wall coordinates of a world point P: x = (P_xy − c)·u, y = P_z − grid_elevation,
  z = (P_xy − c)·n (c the grid centre in top view), so the TransientVolume's grid() x runs along
  start→end and y up.
* hidden surfaces: every face of a box object (four sides, height 0 … ``height``, and the roof)
  cut into square-ish patches of about ``patch_size``; a point object is one patch of
  ``point_area`` facing the grid centre. Albedo ``object_albedo`` for all. Faces turned away from
  a scan point get no light (cosine clipped), which is exact self-occlusion for a convex box.
* user meshes (``Scene.meshes``, when ``meshes``): every triangle cut to edges ≤ ``patch_size``
  (:mod:`.mesh_patches`), albedo ``object_albedo``; loaded with :func:`sims.meshes.load_user_mesh`.
* occlusion (when ``occlusion``): a patch is dropped when the segment from the scan-grid centre
  to it is blocked by another wall, another box object or a mesh (:mod:`.occlusion`: 2-D top-view
  segment test for the vertical walls and boxes, trimesh ray casting for meshes).
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.scene import ObjectSpec, Scene, WallSpec
from xnlos_core.transient import TransientVolume

from .detector import background_per_bin, detect
from .transport import Optics, Patches, expected_transient, system_sigma


class SpadParams(BaseModel):
    """Confocal SPAD system of the cross-modality comparison (Sec. 5.1.2: 850 nm, 1.6 mW)."""

    model_config = ConfigDict(extra="forbid")
    power: float = Field(1.6e-3, gt=0, le=10, description="average laser power [W] (Sec. 5.1.2: 1.6 mW)")
    wavelength: float = Field(850e-9, gt=200e-9, lt=2e-6, description="laser wavelength [m]")
    rep_rate: float = Field(5e6, gt=0, le=1e9, description="pulse repetition rate [Hz] (c/(2 f) = 30 m unambiguous)")
    pulse_width: float = Field(50e-12, ge=0, le=1e-8, description="laser pulse FWHM [s]")
    jitter: float = Field(60e-12, ge=0, le=1e-8, description="SPAD timing jitter FWHM [s]")
    efficiency: float = Field(0.3, gt=0, le=1, description="photon detection efficiency at the wavelength")
    dark_count_rate: float = Field(100.0, ge=0, le=1e8, description="dark counts [1/s]")
    ambient_rate: float = Field(1e4, ge=0, le=1e9, description="ambient-light detections [1/s]")
    exposure: float = Field(0.01, gt=0, le=100, description="dwell time per scan point [s]")
    n_bins: int = Field(2048, ge=1, le=65536, description="time bins T")
    bin_width: float = Field(64e-12, gt=0, le=1e-8, description="time bin width Δ [s]")
    t0: float = Field(0.0, ge=0, le=1e-5, description="round-trip time at the centre of bin 0 [s] "
                      "(bin k centred at t0 + k·bin_width, sims/spad/transport.py)")
    grid_points: tuple[int, int] = Field((32, 32), description="scan points (W along the wall, H up)")
    grid_width: float = Field(2.0, gt=0, le=100, description="scan grid extent along the wall [m]")
    grid_height: float = Field(2.0, gt=0, le=100, description="scan grid extent in height [m]")
    grid_elevation: float = Field(1.5, ge=0, le=100, description="height of the grid centre above ground [m]")
    grid_offset: float = Field(0.0, ge=-1e4, le=1e4, description="grid centre along the wall from its midpoint [m]")
    wall: str | None = Field(None, description="relay wall name; None: the first planar relay facade")
    wall_albedo: float = Field(0.8, ge=0, le=1, description="Lambertian albedo ρ_w of the relay wall at λ")
    object_albedo: float = Field(0.5, ge=0, le=1, description="Lambertian albedo ρ of hidden objects at λ")
    aperture_diameter: float = Field(0.025, gt=0, le=1, description="collection lens diameter [m]")
    spot_diameter: float = Field(0.01, gt=0, le=1, description="SPAD's field-of-view spot on the wall [m]")
    collection_distance: float | None = Field(None, gt=0, le=1e4, description="sensor to grid centre [m]; "
                                              "None: from the sensor at the origin, sensor_height up")
    view_cosine: float | None = Field(None, ge=0, le=1, description="cosθ_v of the collection direction from the "
                                      "wall normal; None: from the sensor at the origin, sensor_height up")
    sensor_height: float = Field(1.0, ge=0, le=100, description="sensor height above ground [m]")
    patch_size: float = Field(0.1, gt=0.001, le=10, description="hidden-surface patch edge [m]")
    point_area: float = Field(0.1, gt=0, le=100, description="area of a point object's patch [m²]")
    meshes: bool = Field(True, description="include the scene's user meshes as hidden surfaces")
    occlusion: bool = Field(True, description="drop patches hidden from the scan-grid centre by other walls, "
                                              "objects or meshes")
    max_patches: int = Field(200_000, ge=1, le=10_000_000, description="most patches one mesh may be cut into")
    pile_up: bool = Field(False, description="first-photon (TCSPC) pile-up, Coates; else Poisson counting")
    seed: int = Field(0, ge=0, lt=2**63, description="seed of the photon-counting Generator")

    @property
    def n_pulses(self) -> int:
        """Pulses per scan point: exposure × repetition rate (at least 1)."""
        return max(1, int(round(self.exposure * self.rep_rate)))


def relay_wall(scene: Scene, name: str | None = None) -> WallSpec:
    """The named planar wall piece, or the scene's first planar relay facade."""
    walls = scene.planar_walls()
    if name is not None:
        for w in walls:
            if w.name == name:
                return w
        raise InputError(f"SpadParams.wall: no wall named {name!r}; walls: {', '.join(w.name for w in walls) or 'none'}")
    for w in walls:
        if w.relay:
            return w
    raise InputError(f"scene {scene.name!r}: no relay wall (walls with relay = true) for a SPAD scan")


def wall_frame(wall: WallSpec, params: SpadParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid centre c (2,) [m], along-wall unit u (2,) and normal n (2,) toward the sensor (top view)."""
    a, b = np.asarray(wall.start, float), np.asarray(wall.end, float)
    u = (b - a) / np.linalg.norm(b - a)
    n = np.array([-u[1], u[0]])
    c = (a + b) / 2 + params.grid_offset * u
    if np.dot(-c, n) < 0:  # point n to the origin's side
        n = -n
    return c, u, n


def _box_faces(obj: ObjectSpec) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, float, float]]:
    """World faces (corner o (3,), edge e1 (3,), edge e2 (3,), |e1|, |e2|) of a box object."""
    fp = obj.footprint(0.0)  # 4 corners in order around the box
    h = obj.height
    faces = []
    for i in range(4):
        p, q = fp[i], fp[(i + 1) % 4]
        faces.append((np.array([*p, 0.0]), np.array([*(q - p), 0.0]), np.array([0.0, 0.0, h])))
    faces.append((np.array([*fp[0], h]), np.array([*(fp[1] - fp[0]), 0.0]), np.array([*(fp[3] - fp[0]), 0.0])))
    return faces


def _world_patches(scene: Scene, params: SpadParams, centre: np.ndarray):
    """World patches: centres (P, 3), normals (P, 3), areas (P,), owner (P,) int (object index;
    −1 − k for mesh k), and the meshes placed in the scene."""
    centers, normals, areas, owner = [], [], [], []
    for idx, obj in enumerate(scene.objects):
        if obj.shape == "point":
            p = np.array([*obj.center_at(0.0), params.grid_elevation])
            centers.append(p[None])
            to_grid = centre + np.array([0, 0, params.grid_elevation]) - p
            normals.append((to_grid / max(np.linalg.norm(to_grid), 1e-12))[None])
            areas.append(np.array([params.point_area]))
            owner.append(np.array([idx]))
            continue
        mid = np.array([*obj.center_at(0.0), obj.height / 2])
        for o, e1, e2 in _box_faces(obj):
            l1, l2 = np.linalg.norm(e1), np.linalg.norm(e2)
            k1, k2 = max(1, math.ceil(l1 / params.patch_size)), max(1, math.ceil(l2 / params.patch_size))
            s1, s2 = (np.arange(k1) + 0.5) / k1, (np.arange(k2) + 0.5) / k2
            pts = o + s1[:, None, None] * e1 + s2[None, :, None] * e2
            nrm = np.cross(e1, e2)
            nrm /= np.linalg.norm(nrm)
            if np.dot(o + 0.5 * (e1 + e2) - mid, nrm) < 0:  # outward
                nrm = -nrm
            centers.append(pts.reshape(-1, 3))
            normals.append(np.broadcast_to(nrm, (k1 * k2, 3)))
            areas.append(np.full(k1 * k2, l1 * l2 / (k1 * k2)))
            owner.append(np.full(k1 * k2, idx))
    placed = []
    if params.meshes and scene.meshes:
        from ..meshes import combine, load_user_mesh
        from .mesh_patches import triangle_patches

        for k, spec in enumerate(scene.meshes):
            mesh = combine([m for m, _, _ in load_user_mesh(spec, scene.base_dir, require_watertight=False)])
            placed.append(mesh)
            c, nr, ar = triangle_patches(mesh, params.patch_size, params.max_patches, spec.name)
            centers.append(c)
            normals.append(nr)
            areas.append(ar)
            owner.append(np.full(len(ar), -1 - k))
    if not centers:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, int), placed
    return (np.concatenate(centers), np.concatenate(normals), np.concatenate(areas), np.concatenate(owner),
            placed)


def _visible_from(scene: Scene, params: SpadParams, wall: WallSpec, origin: np.ndarray, P: np.ndarray,
                  owner: np.ndarray, meshes) -> np.ndarray:
    """(P,) bool: patches not hidden from ``origin`` (3,) by other walls, box objects or meshes."""
    from ..raytrace.caster import Caster
    from .occlusion import blocked_by_mesh, blocked_by_segments

    ok = np.ones(len(P), bool)
    others = [w for w in scene.planar_walls() if not (w.start == wall.start and w.end == wall.end)]
    if others:
        ok &= ~blocked_by_segments(origin, P, np.array([w.start for w in others], float),
                                   np.array([w.end for w in others], float), np.array([w.height for w in others]))
    for idx, obj in enumerate(scene.objects):
        if obj.shape == "point":
            continue
        fp = obj.footprint(0.0)
        sel = ok & (owner != idx)
        ok[sel] &= ~blocked_by_segments(origin, P[sel], fp, np.roll(fp, -1, axis=0), np.full(len(fp), obj.height))
    for k, mesh in enumerate(meshes):
        sel = np.flatnonzero(ok & (owner != -1 - k))
        ok[sel] &= ~blocked_by_mesh(origin, P[sel], Caster(mesh))
    return ok


def hidden_patches(scene: Scene, params: SpadParams) -> Patches:
    """Patches (wall coordinates) of every object's and mesh's surfaces, the module docstring's
    mapping, without those occluded from the scan-grid centre (when ``params.occlusion``)."""
    wall = relay_wall(scene, params.wall)
    c, u, n = wall_frame(wall, params)
    centre = np.array([*c, 0.0])
    P, N, a, owner, meshes = _world_patches(scene, params, centre)
    if params.occlusion and len(P):
        keep = _visible_from(scene, params, wall, centre + np.array([0, 0, params.grid_elevation]), P, owner, meshes)
        P, N, a = P[keep], N[keep], a[keep]
    rot = np.stack([np.array([u[0], u[1], 0.0]), np.array([0.0, 0.0, 1.0]), np.array([n[0], n[1], 0.0])])
    wc = (P - centre - np.array([0, 0, params.grid_elevation])) @ rot.T
    wn = N @ rot.T
    return Patches(wc, wn, a, np.full(len(a), params.object_albedo))


def visible_patches(scene: Scene, params: SpadParams) -> Patches:
    """The :func:`hidden_patches` that return light to at least one scan point (their cosines at the
    wall and at the patch both positive somewhere on the grid): the surface the scan can see."""
    from .transport import return_per_pulse

    pt = hidden_patches(scene, params)
    if not len(pt.areas):
        return pt
    x, y = scan_grid(params)
    opt = optics(scene, params)
    seen = np.zeros(len(pt.areas), bool)
    for i in range(0, len(seen), 256):
        j = slice(i, i + 256)
        n, _ = return_per_pulse(x, y, Patches(pt.centers[j], pt.normals[j], pt.areas[j], pt.albedo[j]), opt)
        seen[j] = n.reshape(len(n), -1).max(axis=1) > 0
    return Patches(pt.centers[seen], pt.normals[seen], pt.areas[seen], pt.albedo[seen])


def view_geometry(scene: Scene, params: SpadParams) -> tuple[float, float]:
    """Distance D [m] from the sensor (at the origin, ``sensor_height`` up) to the scan-grid centre
    and cosθ_v of that direction from the relay wall's normal (clipped at 0: a sensor behind the
    wall's plane collects nothing): the collection leg of the transport at the sensor's real view
    angle (sims/spad/transport.py)."""
    c, _, n = wall_frame(relay_wall(scene, params.wall), params)
    v = np.array([-c[0], -c[1], params.sensor_height - params.grid_elevation])
    d = float(np.linalg.norm(v))
    cos = float(np.dot(v[:2], n) / d) if d > 0 else 1.0
    return d, min(max(cos, 0.0), 1.0)


def optics(scene: Scene, params: SpadParams) -> Optics:
    """The transport's Optics from the params: collection distance D and the view cosine cosθ_v
    from the sensor's position (:func:`view_geometry`) unless given (``collection_distance``,
    ``view_cosine``)."""
    d, cos = view_geometry(scene, params)
    if params.collection_distance is not None:
        d = params.collection_distance
    if params.view_cosine is not None:
        cos = params.view_cosine
    return Optics(power=params.power, wavelength=params.wavelength, rep_rate=params.rep_rate,
                  efficiency=params.efficiency, aperture_area=math.pi * params.aperture_diameter**2 / 4,
                  collection_distance=max(d, 1e-3), spot_area=math.pi * params.spot_diameter**2 / 4,
                  wall_albedo=params.wall_albedo, view_cosine=cos)


def scan_grid(params: SpadParams) -> tuple[np.ndarray, np.ndarray]:
    """Scan x (W,), y (H,) [m] in wall coordinates, as TransientVolume.grid() lays them out."""
    w, h = params.grid_points
    x = (np.arange(w) - (w - 1) / 2) * (params.grid_width / w)
    y = (np.arange(h) - (h - 1) / 2) * (params.grid_height / h)
    return x, y


def expected_signal(scene: Scene, params: SpadParams) -> np.ndarray:
    """Expected signal photons (T, H, W) over each scan point's exposure (no background)."""
    x, y = scan_grid(params)
    return expected_transient(x, y, hidden_patches(scene, params), optics(scene, params), n_bins=params.n_bins,
                              bin_width=params.bin_width, n_pulses=params.n_pulses,
                              sigma=system_sigma(params.pulse_width, params.jitter), t0=params.t0)


def expected_volume(scene: Scene, params: SpadParams | None = None) -> TransientVolume:
    """Expected counts (signal + background, no pile-up) over the exposure of each scan point."""
    params = params or SpadParams()
    bg = background_per_bin(params.dark_count_rate, params.ambient_rate, params.bin_width, params.n_pulses)
    return TransientVolume(expected_signal(scene, params) + bg, params.bin_width, params.grid_width,
                           params.grid_height, params.t0)


def simulate(scene: Scene, params: SpadParams | None = None) -> TransientVolume:
    """Photon counts (T, H, W) of a confocal SPAD scan of ``scene``: expected signal
    (:mod:`.transport`), background, optional pile-up and photon counting (:mod:`.detector`),
    seeded by ``params.seed``."""
    params = params or SpadParams()
    counts = detect(expected_signal(scene, params), n_pulses=params.n_pulses, bin_width=params.bin_width,
                    dark_rate=params.dark_count_rate, ambient_rate=params.ambient_rate, pile_up=params.pile_up,
                    rng=np.random.default_rng(params.seed))
    return TransientVolume(counts, params.bin_width, params.grid_width, params.grid_height, params.t0)
