"""Building footprints in the radar's frame: heights and materials from map tags, walls and meshes.

Height [m] of a building, first that applies:

1. ``height`` (metres; ``"21"``, ``"21 m"``, or feet ``"70 ft"``/``"70'"``, converted);
2. ``building:levels`` × ``level_height`` (3 m unless given);
3. ``default_height``.

Material (an ITU-R P.2040 name of :mod:`sims.materials`): ``building:material`` (or
``building:facade:material``) through :data:`OSM_MATERIALS` (OpenStreetMap values → the closest
P.2040 class; a P.2040 name is taken as it is), else ``default_material`` (None: the walls' constant
reflectivity and backscatter). A tag that cannot be read falls back to the default with a
:class:`MapTagWarning` naming the building, the tag and its value.

Each footprint edge (outer ring and courtyards) becomes one vertical :class:`~xnlos_core.scene.WallSpec`
of the building's height and material; :func:`building_meshes` extrudes the footprints to closed
trimesh prisms (:func:`prism`) in the same frame [m].
"""
from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.scene import MAX_COORD, WallSpec

from .frame import LocalFrame
from .model import MapTagWarning

FOOT = 0.3048  # m
MAX_HEIGHT = 500.0  # m, WallSpec.height's bound
MIN_EDGE = 1e-3  # m: consecutive footprint nodes closer than this are one corner

#: OpenStreetMap ``building:material`` values → ITU-R P.2040 classes of :mod:`sims.materials`.
OSM_MATERIALS: dict[str, str] = {
    "brick": "brick", "concrete": "concrete", "reinforced_concrete": "concrete", "cement_block": "concrete",
    "plaster": "concrete", "stone": "marble", "sandstone": "marble", "limestone": "marble", "marble": "marble",
    "glass": "glass", "mirror": "glass", "wood": "wood", "timber_framing": "wood", "bamboo": "wood",
    "metal": "metal", "metal_plates": "metal", "steel": "metal", "aluminium": "metal",
}

_LENGTH = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(m|ft|')?\s*$")


@dataclass(frozen=True)
class Building:
    """A footprint in the ego frame: ``outer`` (N, 2) [m] closed ring, ``holes`` closed rings,
    ``height`` [m], ``material`` (P.2040 name or None), ``id`` and the map ``tags``."""

    id: str
    outer: np.ndarray
    height: float
    material: str | None
    holes: tuple[np.ndarray, ...] = ()
    tags: dict[str, str] = field(default_factory=dict)

    def rings(self) -> tuple[np.ndarray, ...]:
        return (self.outer, *self.holes)


def parse_height(tags: dict[str, str], fid: str, default_height: float, level_height: float) -> float:
    """The building's height [m] from its tags (module doc)."""
    h = tags.get("height")
    if h is not None:
        m = _LENGTH.match(h)
        value = float(m.group(1)) * (FOOT if m.group(2) in ("ft", "'") else 1.0) if m else None
        if value is not None and 0 < value <= MAX_HEIGHT:
            return value
        warnings.warn(f"building {fid}: height={h!r} is not a height in (0, {MAX_HEIGHT:g}] m (write e.g. \"21\", "
                      f"\"21 m\" or \"70 ft\"); trying building:levels, else default_height {default_height:g} m",
                      MapTagWarning, stacklevel=3)
    lv = tags.get("building:levels")
    if lv is not None:
        try:
            levels = float(lv)
        except ValueError:
            levels = math.nan
        if math.isfinite(levels) and 0 < levels * level_height <= MAX_HEIGHT:
            return levels * level_height
        warnings.warn(f"building {fid}: building:levels={lv!r} is not a positive number of levels (× {level_height:g} m "
                      f"≤ {MAX_HEIGHT:g} m); using default_height {default_height:g} m", MapTagWarning, stacklevel=3)
    return default_height


def parse_material(tags: dict[str, str], fid: str, default_material: str | None) -> str | None:
    """The building's P.2040 material from ``building:material`` (module doc)."""
    from .. import materials

    value = tags.get("building:material") or tags.get("building:facade:material")
    if value is None:
        return default_material
    key = value.strip().lower().replace("-", "_").replace(" ", "_")
    if key in OSM_MATERIALS:
        return OSM_MATERIALS[key]
    if key in materials.MATERIALS:
        return key
    warnings.warn(f"building {fid}: building:material={value!r} has no ITU-R P.2040 class here (known: "
                  f"{', '.join(sorted(OSM_MATERIALS))}); using default_material {default_material!r}",
                  MapTagWarning, stacklevel=3)
    return default_material


def _clean(ring: np.ndarray) -> np.ndarray:
    """The closed ring without repeated corners (consecutive points closer than MIN_EDGE)."""
    keep = np.concatenate([[True], np.linalg.norm(np.diff(ring, axis=0), axis=1) >= MIN_EDGE])
    out = ring[keep]
    if np.linalg.norm(out[-1] - ring[0]) >= MIN_EDGE:
        out = np.vstack([out, ring[:1]])
    else:
        out[-1] = out[0]
    return out


def buildings_from_footprints(footprints, frame: LocalFrame, *, default_height: float = 10.0,
                              default_material: str | None = "concrete", level_height: float = 3.0,
                              max_distance: float | None = None) -> list[Building]:
    """The footprints (longitude/latitude) as :class:`Building` s in ``frame`` [m] with heights and
    materials from their tags. ``max_distance`` [m]: leave out buildings whose every corner lies
    farther from the radar (None: keep all). All nodes are projected in one pyproj call."""
    footprints = list(footprints)
    rings = [r for f in footprints for r in (f.outer, *f.holes)]
    if not rings:
        return []
    lonlat = np.concatenate(rings)
    xy = frame.to_ego(lonlat[:, 0], lonlat[:, 1])
    if np.any(np.abs(xy) > MAX_COORD):
        far = int(np.argmax(np.abs(xy).max(axis=1)))
        raise InputError(f"map node at lon={lonlat[far, 0]:.7f}, lat={lonlat[far, 1]:.7f} lies {np.abs(xy[far]).max():.0f} m "
                         f"from the radar, beyond the scene bound ±{MAX_COORD:g} m; set max_distance (or crop the map)")
    bounds = np.cumsum([0] + [len(r) for r in rings])
    local = [xy[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    out, k = [], 0
    for f in footprints:
        n = 1 + len(f.holes)
        mine, k = [_clean(r) for r in local[k:k + n]], k + n
        if len(mine[0]) < 4:
            warnings.warn(f"building {f.id}: fewer than 3 distinct corners after removing repeated nodes; left out",
                          MapTagWarning, stacklevel=2)
            continue
        if max_distance is not None and np.linalg.norm(mine[0], axis=1).min() > max_distance:
            continue
        out.append(Building(f.id, mine[0], parse_height(f.tags, f.id, default_height, level_height),
                            parse_material(f.tags, f.id, default_material),
                            tuple(h for h in mine[1:] if len(h) >= 4), dict(f.tags)))
    return out


def walls_of(buildings, *, roughness: float = 0.0, spacing: float = 0.25, relay: bool = True) -> list[WallSpec]:
    """One :class:`WallSpec` per footprint edge (outer ring, then courtyards), start → end in the ring's
    node order, named ``"<building id>:<edge>"`` (courtyard edges ``"<id>:h<k>:<edge>"``)."""
    walls = []
    for b in buildings:
        em = {"material": b.material, "roughness": roughness} if b.material else {}
        for k, ring in enumerate(b.rings()):
            tag = "" if k == 0 else f"h{k - 1}:"
            for i in range(len(ring) - 1):
                walls.append(WallSpec(name=f"{b.id}:{tag}{i}", start=(float(ring[i, 0]), float(ring[i, 1])),
                                      end=(float(ring[i + 1, 0]), float(ring[i + 1, 1])), height=b.height,
                                      spacing=spacing, relay=relay, **em))
    return walls


def building_meshes(buildings) -> list[tuple["trimesh.Trimesh", str | None, str]]:  # noqa: F821
    """[(mesh, material, building id)]: each footprint extruded from the ground (z = 0) to its
    height, a closed trimesh in the ego frame [m] (:func:`prism`); an invalid (self-crossing) outline
    is repaired with shapely's ``make_valid`` first and its largest polygon extruded."""
    import shapely
    from shapely import Polygon

    out = []
    for b in buildings:
        poly = Polygon(b.outer, [h for h in b.holes])
        if not poly.is_valid:
            fixed = shapely.make_valid(poly)
            parts = [g for g in getattr(fixed, "geoms", [fixed]) if isinstance(g, Polygon)]
            if not parts:
                continue
            poly = max(parts, key=lambda g: g.area)
        out.append((prism(poly, b.height), b.material, b.id))
    return out


def prism(poly, height: float) -> "trimesh.Trimesh":  # noqa: F821
    """The shapely polygon ``poly`` (x, y [m], holes allowed) extruded from z = 0 to ``height`` [m]: a
    closed trimesh with outward normals. Caps from shapely's constrained Delaunay triangulation (no
    vertices added), sides one quad (two triangles) per ring edge."""
    import shapely
    import trimesh

    poly = shapely.orient_polygons(poly)  # exterior counter-clockwise, holes clockwise
    tris = np.array([np.asarray(t.exterior.coords)[:3] for t in shapely.constrained_delaunay_triangles(poly).geoms])
    cross = ((tris[:, 1, 0] - tris[:, 0, 0]) * (tris[:, 2, 1] - tris[:, 0, 1])
             - (tris[:, 1, 1] - tris[:, 0, 1]) * (tris[:, 2, 0] - tris[:, 0, 0]))
    tris[cross < 0] = tris[cross < 0][:, ::-1]  # every cap triangle counter-clockwise seen from above
    rings = [np.asarray(r.coords) for r in (poly.exterior, *poly.interiors)]
    a = np.concatenate([r[:-1] for r in rings])
    b = np.concatenate([r[1:] for r in rings])
    z0, z1 = np.zeros((len(a), 1)), np.full((len(a), 1), height)
    a0, b0, a1, b1 = np.hstack([a, z0]), np.hstack([b, z0]), np.hstack([a, z1]), np.hstack([b, z1])
    top = np.concatenate([tris, np.full((len(tris), 3, 1), height)], axis=2)
    bottom = np.concatenate([tris[:, ::-1], np.zeros((len(tris), 3, 1))], axis=2)
    sides = np.concatenate([np.stack([a0, b0, b1], axis=1), np.stack([a0, b1, a1], axis=1)])
    tri = np.concatenate([top, bottom, sides])
    mesh = trimesh.Trimesh(tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3), process=False)
    mesh.merge_vertices()
    return mesh
