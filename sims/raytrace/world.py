"""A scene as one triangle mesh with per-face electromagnetics and planes (the ray tracer's world).

* Walls (planar facets of :meth:`Scene.planar_walls`) become boxes: the front face on the BEV
  segment, from the ground (z = 0) to ``height``, extruded away from the radar by the slab
  ``thickness`` (0.3 m when none is given).
* User meshes (:class:`xnlos_core.scene.MeshSpec`) are loaded by :func:`sims.meshes.load_user_mesh`,
  one surface per material tag.
* Objects are boxes (length × width × height, yawed by ``heading``) shrunk by ``OBJECT_MARGIN``
  so that their scattering centres (:meth:`ObjectSpec.scatterers`, on the box outline) lie just
  outside their own occluder; point objects occlude nothing.
* Every triangle carries its surface (or object) index and a plane id: coplanar faces of one
  surface share a plane (n, d) with nᵀx + d = 0, the mirrors of the image paths.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from xnlos_core.errors import InputError

from .caster import Caster

if TYPE_CHECKING:
    import trimesh

OBJECT_MARGIN = 0.05  # [m] occluder boxes are this much smaller than the scattering outline
DEFAULT_DEPTH = 0.3  # [m] wall box depth when the wall has no slab thickness


@dataclass(frozen=True)
class Surface:
    """Electromagnetic description of one static surface, duck-typed like WallSpec for :mod:`sims.walls`."""

    name: str
    material: str | None
    thickness: float | None
    roughness: float
    lobe: str
    lobe_exponent: int
    relay: bool
    alpha: float
    sigma0_db: float

    @classmethod
    def from_wall(cls, w) -> "Surface":
        return cls(w.name, w.material, w.thickness, w.roughness, w.lobe, int(w.lobe_exponent), w.relay,
                   w.alpha, w.sigma0_db)

    @classmethod
    def from_mesh(cls, spec, material: str | None, tag: str) -> "Surface":
        alpha = 0.6 if spec.reflectivity is None else spec.reflectivity
        s0 = -12.0 if spec.backscatter_db is None else spec.backscatter_db
        return cls(f"{spec.name}:{tag}" if tag else spec.name, material, None, spec.roughness if material else 0.0,
                   "lambertian", 4, spec.relay, alpha, s0)


def _depth(w) -> float:
    return w.thickness if w.thickness is not None else DEFAULT_DEPTH


def wall_box(w) -> trimesh.Trimesh:
    """Watertight box of a planar wall facet (module doc); the front face is on the BEV segment,
    the box extends ``thickness`` (or DEFAULT_DEPTH) away from the radar side."""
    import trimesh  # here, not at module level: trimesh (and networkx) cost ~0.2–0.6 s, and registering
    # the ray-tracing forward model (every `xnlos` start) imports this module

    seg = w.segment()
    a, b = np.asarray(w.start, float), np.asarray(w.end, float)
    u = (b - a) / np.linalg.norm(b - a)
    centre = (a + b) / 2 - seg.normal * _depth(w) / 2
    tf = np.eye(4)
    tf[:2, 0], tf[:2, 1] = u, (-u[1], u[0])  # box x along the wall, y across it (a proper rotation)
    tf[:3, 3] = (centre[0], centre[1], w.height / 2)
    return trimesh.creation.box(extents=(float(np.linalg.norm(b - a)), _depth(w), w.height), transform=tf)


@functools.cache
def _unit_box() -> tuple[np.ndarray, np.ndarray]:
    """The unit cube's vertices (8, 3) and faces (12, 3), as trimesh.creation.box makes them."""
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    v, f = np.array(box.vertices), np.array(box.faces)
    v.flags.writeable = f.flags.writeable = False  # shared by every call
    return v, f


def wall_boxes(walls) -> trimesh.Trimesh:
    """All walls' boxes (same geometry as :func:`wall_box`) as one mesh, built without per-wall
    trimesh objects: the unit cube's outward faces, scaled, rotated and moved per wall.
    Faces are wall-major, 12 per wall."""
    import trimesh

    v0, f0 = _unit_box()
    verts, faces = [], []
    for i, w in enumerate(walls):
        seg = w.segment()
        a, b = np.asarray(w.start, float), np.asarray(w.end, float)
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        rot = np.array([[u[0], -u[1], 0.0], [u[1], u[0], 0.0], [0.0, 0.0, 1.0]])
        centre = (a + b) / 2 - seg.normal * _depth(w) / 2
        verts.append((v0 * (length, _depth(w), w.height)) @ rot.T + (centre[0], centre[1], w.height / 2))
        faces.append(f0 + 8 * i)
    if not verts:
        return trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64))
    return trimesh.Trimesh(vertices=np.concatenate(verts), faces=np.concatenate(faces), process=False)


def inside_wall_box(w, point: np.ndarray) -> bool:
    """True when ``point`` (3,) [m] lies strictly inside :func:`wall_box` of w (analytic)."""
    seg = w.segment()
    a, b = np.asarray(w.start, float), np.asarray(w.end, float)
    u = (b - a) / np.linalg.norm(b - a)
    along, behind = (point[:2] - a) @ u, -(point[:2] @ seg.normal + seg.offset)
    return bool(0 < along < np.linalg.norm(b - a) and 0 < behind < _depth(w) and 0 < point[2] < w.height)


def object_box(obj, t: float) -> trimesh.Trimesh | None:
    """Occluder box of an object at time t [s] (None for point objects)."""
    import trimesh

    if obj.shape == "point":
        return None
    length, width = obj.size
    dims = (max(length - 2 * OBJECT_MARGIN, 0.01), max(width - 2 * OBJECT_MARGIN, 0.01), obj.height)
    m = trimesh.creation.box(extents=dims)
    c = obj.center_at(t)
    m.apply_transform(trimesh.transformations.rotation_matrix(obj.heading_at(t), (0, 0, 1)))
    m.apply_translation((c[0], c[1], obj.height / 2))
    return m


@dataclass
class World:
    """Concatenated mesh and per-face bookkeeping (module doc).

    tri_surface (F,): surface index, −1 for object faces; tri_object (F,): object index or −1;
    tri_plane (F,): plane index; plane_n (P, 3), plane_d (P,): planes nᵀx + d = 0 with n the
    outward face normal; plane_surface (P,): owning surface (−1 for objects); em_group: filled
    on first use by :func:`sims.raytrace.tracer.em_groups`.
    """

    caster: Caster
    surfaces: list[Surface]
    tri_surface: np.ndarray
    tri_object: np.ndarray
    tri_plane: np.ndarray
    plane_n: np.ndarray
    plane_d: np.ndarray
    plane_surface: np.ndarray
    em_group: np.ndarray | None = None


def build_world(scene, t: float = 0.0, backend: str = "auto") -> World:
    """The triangle world of ``scene`` at time t [s] (walls, user meshes, object occluders)."""
    import trimesh

    parts: list[tuple[trimesh.Trimesh, int, int]] = []  # (mesh, surface index, object index)
    surfaces: list[Surface] = []
    planar = scene.planar_walls()
    if planar:
        boxes = wall_boxes(planar)
        surfaces.extend(Surface.from_wall(w) for w in planar)
        parts.append((boxes, np.repeat(np.arange(len(planar)), 12), -1))
    if scene.meshes:
        from sims.meshes import load_user_mesh

        for spec in scene.meshes:
            for mesh, material, tag in load_user_mesh(spec, scene.base_dir):
                surfaces.append(Surface.from_mesh(spec, material, tag))
                parts.append((mesh, len(surfaces) - 1, -1))
    for j, obj in enumerate(scene.objects):
        box = object_box(obj, t)
        if box is not None:
            parts.append((box, -1, j))
    if parts:
        mesh = trimesh.util.concatenate([p[0] for p in parts]) if len(parts) > 1 else parts[0][0]
        tri_surface = np.concatenate([np.broadcast_to(p[1], (len(p[0].faces),)) for p in parts])
        tri_object = np.concatenate([np.broadcast_to(p[2], (len(p[0].faces),)) for p in parts])
    else:
        mesh = trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64))
        tri_surface = tri_object = np.zeros(0, dtype=np.int64)
    n = np.asarray(mesh.face_normals, dtype=np.float64) if len(mesh.faces) else np.zeros((0, 3))
    d = -np.einsum("ij,ij->i", n, np.asarray(mesh.vertices)[mesh.faces[:, 0]]) if len(mesh.faces) else np.zeros(0)
    # plane id: same owner, normal and offset (rounded to 1e-6 / 1 µm)
    key = np.column_stack([tri_surface, tri_object, np.round(n, 6), np.round(d, 6)])
    uniq, tri_plane = np.unique(key, axis=0, return_inverse=True)
    tri_plane = tri_plane.reshape(-1).astype(np.int64)
    # exact plane of each group: the first face's own float64 normal and offset (not the rounded key)
    first = np.zeros(len(uniq), dtype=np.int64)
    first[tri_plane[::-1]] = np.arange(len(tri_plane))[::-1]
    return World(caster=Caster(mesh, backend), surfaces=surfaces, tri_surface=tri_surface.astype(np.int64),
                 tri_object=tri_object.astype(np.int64), tri_plane=tri_plane,
                 plane_n=n[first] if len(uniq) else np.zeros((0, 3)), plane_d=d[first] if len(uniq) else np.zeros(0),
                 plane_surface=uniq[:, 0].astype(np.int64) if len(uniq) else np.zeros(0, dtype=np.int64))


def reflect_points(points: np.ndarray, n: np.ndarray, d: float) -> np.ndarray:
    """Mirror image of points (…, 3) across the plane nᵀx + d = 0 (unit n): x − 2(nᵀx + d)n (Eq. 7 in 3-D)."""
    return points - 2.0 * (points @ n + d)[..., None] * n


def check_radar_outside(world: World, radar: np.ndarray, scene) -> None:
    """InputError when the radar stands inside a wall (its footprint or its extruded box) or a closed
    mesh, or an object touches a wall or lies inside a mesh (:func:`sims.meshes.check_scene_geometry`)."""
    from sims.meshes import check_scene_geometry

    check_scene_geometry(scene, radar_position=tuple(radar))
    for w in scene.planar_walls():
        if inside_wall_box(w, radar):
            raise InputError(f"scene {scene.name!r}: the radar at {tuple(np.round(radar, 3))} stands inside "
                             f"wall {w.name!r}")
