"""User meshes in scenes (OBJ, STL, PLY, GLB/GLTF through trimesh) and geometric checks of a scene.

A :class:`~xnlos_core.scene.MeshSpec` names a file, its placement (``scale``, then ``yaw`` about z,
then ``translation``) and its electromagnetics: one ``material`` for every part, a ``materials``
map from part tags to materials (``material`` then covers untagged parts), or neither (the
constants ``reflectivity``/``backscatter_db``, material None). Part tags are

* OBJ: the ``usemtl`` material names (trimesh splits the file by material; the ``mtllib``
  library must sit beside the file, ``newmtl NAME`` lines suffice);
* STL, PLY, GLB, GLTF: the geometry names of the loaded trimesh scene (glTF mesh names; the
  file name for single-mesh formats).

Loading is data-only (trimesh parsers; no pickles, no remote resources). Files are cached by
path, modification time and size, so checking many scenes that share a mesh stays cheap. Every
file is read through :func:`xnlos_core.files.read_file_bytes` (regular files only, never blocking
on a FIFO); files a mesh references (an OBJ's ``mtllib``, textures, glTF buffers) must sit in the
mesh file's folder or below it, symlinks resolved (:class:`ConfinedResolver`), so a mesh cannot
read ``../../../etc/passwd``.
"""
from __future__ import annotations

import difflib
import functools
import io
import math
import re
from pathlib import Path

import numpy as np
import trimesh

from xnlos_core.errors import ConfigError, InputError
from xnlos_core.files import read_file_bytes
from xnlos_core.scene import MAX_COORD, MAX_UNDECLARED_EXTENT, MeshSpec, Scene

from .generators import geometry as g

SUPPORTED = {".obj": "obj", ".stl": "stl", ".ply": "ply", ".glb": "glb", ".gltf": "gltf"}
UNIT_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # metres per file unit (MeshSpec.unit)
RADAR_HEIGHT = 1.0  # m, default mounting height of the radar above ground for the 3-D checks


def mesh_path(spec: MeshSpec, base_dir: str | Path = ".") -> Path:
    """The file of ``spec`` (relative paths are taken from ``base_dir``), checked to be a readable
    file of a supported type."""
    path = Path(spec.file)
    if not path.is_absolute():
        path = Path(base_dir) / path
    ext = path.suffix.lower()
    if ext not in SUPPORTED:
        raise InputError(f"mesh {spec.name!r}: unsupported file type {ext or '(none)'!r} ({path}); supported: "
                         f"{', '.join(SUPPORTED)}")
    if not path.is_file():
        what = "is a directory, not a file" if path.is_dir() else "not found"
        raise InputError(f"mesh {spec.name!r}: file {path} {what} (file = {spec.file!r}, relative to {base_dir})")
    return path


class ConfinedResolver(trimesh.resolvers.Resolver):
    """The assets a mesh file references, read only from the mesh's folder (and below it).

    trimesh's FilePathResolver confines paths only from trimesh 5 on and reads FIFOs blockingly;
    this one refuses any name that resolves outside ``folder`` and reads regular files only.
    A refusal is an OSError, which trimesh treats as a missing asset (the part tags then lack the
    material names; :func:`load_user_mesh` checks ``mtllib`` lines itself to name the cause).
    """

    def __init__(self, folder: str | Path):
        self.parent = Path(folder).resolve()

    def absolute(self, name: str) -> Path:
        """The resolved path of asset ``name``; OSError when it leaves the folder or cannot be resolved."""
        try:
            path = (self.parent / str(name).strip()).resolve()
        except (OSError, RuntimeError, ValueError) as exc:
            raise OSError(f"asset {name!r}: {exc}") from None
        if not path.is_relative_to(self.parent):
            raise OSError(f"asset {name!r} resolves to {path}, outside the mesh's folder {self.parent}")
        return path

    def get(self, name: str) -> bytes:
        try:
            return read_file_bytes(self.absolute(name), what=f"mesh asset {name!r}")
        except ConfigError as exc:
            raise OSError(str(exc)) from None

    def write(self, name: str, data):
        raise OSError("a ConfinedResolver only reads")

    def namespaced(self, namespace: str) -> "ConfinedResolver":
        return ConfinedResolver(self.absolute(namespace))

    def keys(self):
        return (str(p.relative_to(self.parent)) for p in self.parent.rglob("*") if p.is_file())


def _check_mtllib(spec: MeshSpec, path: Path, data: bytes) -> None:
    """InputError when an OBJ's ``mtllib`` names a file outside the mesh's folder."""
    resolver = ConfinedResolver(path.parent)
    for lib in re.findall(rb"^[ \t]*mtllib[ \t]+(.+?)[ \t]*$", data, flags=re.MULTILINE):
        name = lib.decode("utf-8", errors="replace")
        try:
            resolver.absolute(name)
        except OSError:
            raise InputError(f"mesh {spec.name!r} ({path}): mtllib {name!r} leaves the mesh's folder; the material "
                             "library must sit beside the OBJ file (or in a folder below it)") from None


@functools.lru_cache(maxsize=32)
def _read(path: str, mtime_ns: int, size: int) -> tuple[tuple[str, str, trimesh.Trimesh], ...]:
    """(tag, node, mesh in file coordinates) for every triangle mesh instance in the file; the key
    includes mtime and size so an edited file is read again. Raises what trimesh raises."""
    ext = Path(path).suffix.lower()
    data = read_file_bytes(path, what=f"mesh file {path}")
    # file_type as the whole path: trimesh then names single-mesh geometry after the file (the part tag)
    # absurd coordinates (1e308) overflow trimesh's processing: quietly, load_user_mesh refuses them by name
    with np.errstate(over="ignore", invalid="ignore"):
        scene = trimesh.load_scene(io.BytesIO(data), file_type=str(path), resolver=ConfinedResolver(Path(path).parent))
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry.get(geom_name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        mesh = geom.copy()
        with np.errstate(over="ignore", invalid="ignore"):
            mesh.apply_transform(transform)
        material = getattr(getattr(geom.visual, "material", None), "name", None) if ext == ".obj" else None
        parts.append((str(material or geom_name), str(node), mesh))
    return tuple(sorted(parts, key=lambda p: (p[0], p[1])))


def _placement(spec: MeshSpec) -> np.ndarray:
    """(4, 4) homogeneous transform: the unit (file units → m) and scale, then yaw about z, then translation."""
    c, s = math.cos(spec.yaw), math.sin(spec.yaw)
    m = np.eye(4)
    m[:3, :3] = UNIT_M[spec.unit or "m"] * spec.scale * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    m[:3, 3] = spec.translation
    return m


def combine(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The meshes as one bare mesh (no visuals) with coincident vertices merged, faces in order."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    combined = trimesh.Trimesh(np.concatenate([m.vertices for m in meshes]),
                               np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]), process=False)
    combined.merge_vertices()
    return combined


def edge_defects(meshes: list[trimesh.Trimesh]) -> tuple[np.ndarray, np.ndarray]:
    """Per mesh: the number of open edges (used by one face) and of non-manifold edges (by more
    than two), with the meshes taken together (vertices merged, so seams between parts close)."""
    combined = combine(meshes)
    _, inverse, counts = np.unique(combined.edges_sorted, axis=0, return_inverse=True, return_counts=True)
    per_edge = counts[inverse.reshape(-1)]
    owner = np.searchsorted(np.cumsum([len(m.faces) for m in meshes]), combined.edges_face, side="right")
    n = len(meshes)
    # each open edge appears once; each non-manifold edge is counted once over its faces
    open_ = np.bincount(owner[per_edge == 1], minlength=n)
    bad = per_edge > 2
    nonmanifold = np.bincount(owner[bad], weights=1.0 / per_edge[bad], minlength=n)
    return open_, np.round(nonmanifold).astype(int)


def _material(spec: MeshSpec, tag: str, path: Path, tags) -> str | None:
    from .materials import get_material

    if spec.materials and tag in spec.materials:
        name, key = spec.materials[tag], f"materials[{tag!r}]"
    elif spec.material is not None:
        name, key = spec.material, "material"
    elif spec.materials:
        raise InputError(f"mesh {spec.name!r} ({path}): part {tag!r} has no entry in materials (mapped: "
                         f"{', '.join(sorted(spec.materials))}) and there is no default material; add "
                         f"materials.{tag} = \"…\" or material = \"…\"{_obj_hint(path, tags)}")
    else:
        return None  # constant reflectivity / backscatter
    try:
        return get_material(name).name
    except InputError as err:
        raise InputError(f"mesh {spec.name!r} ({path}): {key}: {err}") from None


def _obj_hint(path: Path, tags) -> str:
    """For an OBJ whose usemtl names did not become part tags: say that its material library is missing."""
    if path.suffix.lower() != ".obj":
        return ""
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return ""
    names = sorted(set(re.findall(r"^\s*usemtl\s+(\S+)", text, flags=re.MULTILINE)))
    libs = re.findall(r"^\s*mtllib\s+(.+?)\s*$", text, flags=re.MULTILINE)
    if not names or set(names) <= set(tags):
        return ""
    return (f" (the file uses usemtl {', '.join(names)}; these become part tags only when its material library "
            f"{' '.join(libs) or '(no mtllib line)'} is present beside it with matching newmtl entries)")


def load_user_mesh(spec: MeshSpec, base_dir: str | Path = ".", *,
                   require_watertight: bool = True) -> list[tuple[trimesh.Trimesh, str | None, str]]:
    """The parts of the mesh file of ``spec`` placed in scene coordinates [m].

    Returns [(mesh, material, tag)]: a trimesh in the scene frame (after scale, yaw, translation),
    the sims.materials name of the part (None for constant reflectivity/backscatter), and the
    part's tag (module doc), sorted by tag. Raises InputError for a missing or unreadable file,
    an unsupported extension, a mesh without faces, vertices that are not finite or lie beyond
    ±MAX_COORD (10 km) once placed (:func:`check_coordinates`), a non-watertight mesh when
    ``require_watertight`` (naming the parts and their open edges), a ``materials`` key that is
    no part of the file, a part without a mapping and no default ``material``, and an unknown
    material name (with a did-you-mean).
    """
    path = mesh_path(spec, base_dir)
    stat = path.stat()
    try:
        if path.suffix.lower() == ".obj":
            _check_mtllib(spec, path, read_file_bytes(path, what=f"mesh {spec.name!r}: file {path}"))
        parts = _read(str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    except InputError:
        raise
    except ConfigError as err:
        raise InputError(str(err)) from None
    except Exception as err:  # trimesh raises many kinds on malformed data
        raise InputError(f"mesh {spec.name!r}: cannot read {path} as {SUPPORTED[path.suffix.lower()].upper()}: "
                         f"{type(err).__name__}: {err}") from None
    if not parts:
        raise InputError(f"mesh {spec.name!r}: {path} holds no triangles (empty mesh or a point cloud); a scene "
                         "mesh needs faces")
    tags = sorted({t for t, _, _ in parts})
    unknown = sorted(set(spec.materials) - set(tags))
    if unknown:
        hints = [f"{k!r}" + (f" (did you mean {c[0]!r}?)" if (c := difflib.get_close_matches(k, tags, n=1)) else "")
                 for k in unknown]
        raise InputError(f"mesh {spec.name!r} ({path}): materials names part(s) {', '.join(hints)} that the file "
                         f"does not have; its parts: {', '.join(tags)}{_obj_hint(path, tags)}")
    check_units(spec, path, [m for _, _, m in parts])
    placement = _placement(spec)
    placed = []
    for tag, _, mesh in parts:
        m = mesh.copy()
        with np.errstate(over="ignore", invalid="ignore"):
            m.apply_transform(placement)
        check_coordinates(spec, path, tag, mesh, m)
        placed.append(m)
    if require_watertight:
        open_, nonmanifold = edge_defects([m for _, _, m in parts])
        if open_.sum() or nonmanifold.sum():
            where = ", ".join(f"{t!r}: {o} open" + (f", {n} non-manifold" if n else "")
                              for (t, _, _), o, n in zip(parts, open_, nonmanifold) if o or n)
            raise InputError(f"mesh {spec.name!r} ({path}) is not watertight: {int(open_.sum())} open edge(s) and "
                             f"{int(nonmanifold.sum())} non-manifold edge(s) (part {where}); the ray tracer needs "
                             "closed surfaces to tell inside from outside. Close the holes (e.g. "
                             "trimesh.repair.fill_holes) or load with require_watertight=False")
    return [(m, _material(spec, tag, path, tags), tag) for (tag, _, _), m in zip(parts, placed)]


def check_units(spec: MeshSpec, path: Path, meshes: list[trimesh.Trimesh]) -> None:
    """InputError when ``spec`` declares no ``unit`` and the mesh (all parts, × scale) is larger than
    MAX_UNDECLARED_EXTENT [m] on some axis: STL, OBJ and PLY carry no unit, and such a mesh is far more
    likely millimetres (a 4.5 m car written as 4500) or centimetres than a kilometre-sized object.
    The message gives its size read as m, cm and mm."""
    if spec.unit is not None:
        return
    with np.errstate(over="ignore", invalid="ignore"):
        v = np.concatenate([np.asarray(m.vertices, dtype=np.float64) for m in meshes])
        extent = float(np.max(np.ptp(v, axis=0))) * spec.scale if len(v) else 0.0
    if not math.isfinite(extent) or not MAX_UNDECLARED_EXTENT < extent <= 1000 * MAX_COORD:
        return  # absurd or non-finite vertices (no unit explains them) are refused, by name, in check_coordinates
    raise InputError(f"mesh {spec.name!r} ({path}) is {extent:.6g} units across (× scale {spec.scale:g}); read as "
                     f"metres that is {extent / 1000:.3g} km, as centimetres {extent / 100:.4g} m, as millimetres "
                     f"{extent / 1000:.4g} m. The file looks like millimetres or centimetres (STL, OBJ and PLY carry no "
                     f"unit): declare unit = \"mm\" or unit = \"cm\" in the mesh's table, or unit = \"m\" if it truly is "
                     f"larger than {MAX_UNDECLARED_EXTENT:g} m")


def check_coordinates(spec: MeshSpec, path: Path, tag: str, raw: trimesh.Trimesh, placed: trimesh.Trimesh) -> None:
    """InputError unless every vertex of part ``tag``, ``placed`` in the scene frame (scale, yaw,
    translation of ``spec``), is finite and within ±MAX_COORD [m] on each axis — the scene bound that
    walls, objects and the mesh's translation already obey (:mod:`xnlos_core.scene`; beyond it the
    ray tracer's squares overflow). ``raw``: the part in file coordinates, quoted in the message."""
    v = np.asarray(placed.vertices, dtype=np.float64)
    bad = ~np.all(np.isfinite(v) & (np.abs(v) <= MAX_COORD), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"mesh {spec.name!r} ({path}): part {tag!r} has {int(bad.sum())} of {len(v)} vertices beyond "
                         f"±{MAX_COORD:g} m in the scene frame, e.g. vertex {i} at {np.asarray(raw.vertices)[i].tolist()} "
                         f"in the file, {v[i].tolist()} m placed (scale {spec.scale:g}, translation "
                         f"{list(spec.translation)}); scene coordinates must be finite and within ±{MAX_COORD:g} m "
                         "(xnlos_core.scene.MAX_COORD)")


def check_scene_geometry(scene: Scene, radar_position=(0.0, 0.0, RADAR_HEIGHT)) -> None:
    """Refuse scenes whose geometry cannot be simulated: InputError when the radar stands inside a
    wall's footprint or a closed mesh, or an object (its footprint at t = 0) touches a wall's
    footprint or lies inside a closed mesh.

    A wall's footprint is its segment thickened to ``thickness`` (0.3 m without one), centred on
    the segment; curved walls are checked facet by facet. radar_position: (x, y, z) [m]; the
    radar is inside a wall only below the wall's height. Meshes are tested with ``contains``
    (ray parity) when their parts together are watertight; open meshes are skipped.
    """
    rp = np.asarray(radar_position, dtype=np.float64)
    if rp.shape != (3,) or not np.all(np.isfinite(rp)):
        raise InputError(f"check_scene_geometry: radar_position must be a finite (x, y, z) in metres, got "
                         f"{radar_position!r}")
    planar = scene.planar_walls()
    starts, ends, half = g.wall_arrays(scene.walls)
    if len(planar):
        heights = np.array([w.height for w in planar])
        d = g.point_segment_distance(rp[:2], starts, ends)
        inside = np.flatnonzero((d < half) & (rp[2] <= heights))
        if len(inside):
            w = planar[inside[0]]
            raise InputError(f"scene {scene.name!r}: the radar at {tuple(rp.tolist())} stands inside wall {w.name!r} "
                             f"(segment {w.start}→{w.end}, footprint {2 * half[inside[0]]:.2f} m thick); move the "
                             "wall or the radar")
        for o in scene.objects:
            dist = g.polygon_segment_distance(g.footprint(o), starts, ends)
            hit = np.flatnonzero(dist < half)
            if len(hit):
                names = ", ".join(repr(planar[i].name) for i in hit[:3]) + (" …" if len(hit) > 3 else "")
                raise InputError(f"scene {scene.name!r}: object {o.name!r} at {o.center} (size {o.size} m, heading "
                                 f"{o.heading:.3g} rad) is inside or against wall(s) {names}; objects must stand "
                                 "clear of the wall footprints")
    for spec in scene.meshes:
        parts = load_user_mesh(spec, scene.base_dir, require_watertight=False)
        meshes = [m for m, _, _ in parts]
        open_, nonmanifold = edge_defects(meshes)
        if open_.sum() or nonmanifold.sum():
            continue  # an open surface has no inside
        combined = combine(meshes)
        if bool(combined.contains(rp[None, :])[0]):
            raise InputError(f"scene {scene.name!r}: the radar at {tuple(rp.tolist())} is inside mesh {spec.name!r} "
                             f"({spec.file}); move the mesh (translation) or the radar")
        for o in scene.objects:
            fp = g.footprint(o)
            pts = np.concatenate([fp, fp.mean(axis=0, keepdims=True)])
            probe = np.column_stack([pts, np.full(len(pts), o.height / 2)])
            if np.any(combined.contains(probe)):
                raise InputError(f"scene {scene.name!r}: object {o.name!r} at {o.center} is inside mesh "
                                 f"{spec.name!r} ({spec.file})")
