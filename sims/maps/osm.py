"""Map files → building footprints and street ways, in WGS84 longitude/latitude [deg].

:func:`read_map` reads OpenStreetMap XML (``.osm``, ``.xml``) or GeoJSON (``.geojson``, ``.json``,
:mod:`.geojson`). Untrusted files are read as data only: at most :data:`MAX_MAP_BYTES`, regular
files only (:func:`xnlos_core.files.read_file_bytes`); an XML document with a DOCTYPE or ENTITY
declaration is refused before parsing (no entity expansion, no external resources), so a file
cannot make the parser fetch anything or blow up memory. Every refusal is an
:class:`xnlos_core.errors.InputError` naming the file.

OSM XML: ``<node id lat lon>``; a building is a closed ``<way>`` (first node = last, ≥ 3 distinct
nodes) tagged ``building=*`` (not ``building=no``), or a ``<relation>`` tagged ``type=multipolygon``
and ``building=*`` whose closed ``outer`` member ways are footprints (its closed ``inner`` ways are
courtyards of the outer that holds them). Ways tagged ``highway=*`` are kept as streets (road users
placed by lane). Elements marked ``visible="false"`` or ``action="delete"`` are left out; a building
way that is not closed or names a node the file lacks (cut at the download's edge) is skipped with a
:class:`~sims.maps.buildings.MapTagWarning`.
"""
from __future__ import annotations

import math
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from xnlos_core.errors import ConfigError, InputError
from xnlos_core.files import read_file_bytes

MAX_MAP_BYTES = 64 * 1024 * 1024  # a city district's extract; larger files are refused unread
OSM_SUFFIXES = (".osm", ".xml")
GEOJSON_SUFFIXES = (".geojson", ".json")
_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


@dataclass(frozen=True)
class Footprint:
    """One building outline: ``outer`` (N, 2) longitude, latitude [deg], a closed ring (first point =
    last), ``holes`` the closed inner rings, ``tags`` the map's key → value, ``id`` e.g. ``"way/12"``."""

    id: str
    outer: np.ndarray
    tags: dict[str, str] = field(default_factory=dict)
    holes: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True)
class Street:
    """A street centre line: ``points`` (N, 2) longitude, latitude [deg] in the way's node order."""

    id: str
    points: np.ndarray
    tags: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class MapData:
    """What a map file holds: building footprints and streets (by id, e.g. ``"way/7"`` or ``"7"``)."""

    source: str
    footprints: tuple[Footprint, ...]
    streets: dict[str, Street] = field(default_factory=dict)


def read_map(path: str | Path) -> MapData:
    """The footprints and streets of the map file ``path`` (format from its suffix, module doc)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in OSM_SUFFIXES + GEOJSON_SUFFIXES:
        raise InputError(f"map file {path}: unknown type {suffix or '(none)'!r}; expected OpenStreetMap XML "
                         f"({', '.join(OSM_SUFFIXES)}) or GeoJSON ({', '.join(GEOJSON_SUFFIXES)})")
    try:
        data = read_file_bytes(path, what=f"map file {path}", max_bytes=MAX_MAP_BYTES)
    except ConfigError as exc:
        raise InputError(str(exc)) from None
    if suffix in GEOJSON_SUFFIXES:
        from .geojson import parse_geojson

        return parse_geojson(data, str(path))
    return parse_osm(data, str(path))


def _root(data: bytes, source: str) -> ET.Element:
    """The parsed document element, after refusing DTD and entity declarations."""
    m = _DECLARATION.search(data)
    if m:
        raise InputError(f"map file {source}: holds a <!{m.group(1).decode().upper()} …> declaration at byte "
                         f"{m.start()}; DTDs and entities are refused in map files (they can expand without bound "
                         "or fetch other files). OpenStreetMap XML needs neither: remove it")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        line, col = getattr(exc, "position", (0, 0))
        raise InputError(f"map file {source}: not well-formed XML at line {line}, column {col}: {exc}") from None
    if root.tag != "osm":
        raise InputError(f"map file {source}: the document element is <{root.tag[:40]}>, not <osm>; expected "
                         "OpenStreetMap XML")
    return root


def _live(el: ET.Element) -> bool:
    return el.get("visible", "true") != "false" and el.get("action") != "delete"


def _tags(el: ET.Element) -> dict[str, str]:
    return {t.get("k", ""): t.get("v", "") for t in el.iterfind("tag")}


def _nodes(root: ET.Element, source: str) -> dict[str, tuple[float, float]]:
    nodes = {}
    for n in root.iterfind("node"):
        if not _live(n):
            continue
        nid = n.get("id")
        try:
            lat, lon = float(n.get("lat")), float(n.get("lon"))
        except (TypeError, ValueError):
            raise InputError(f"map file {source}: node {nid!r} has lat={n.get('lat')!r}, lon={n.get('lon')!r}; "
                             "expected decimal degrees") from None
        if not (math.isfinite(lat) and math.isfinite(lon) and abs(lat) <= 90 and abs(lon) <= 180):
            raise InputError(f"map file {source}: node {nid!r} at lat={lat}, lon={lon} is outside ±90°/±180°")
        nodes[nid] = (lon, lat)
    return nodes


def _ring(refs: list[str], nodes: dict, what: str, source: str) -> np.ndarray | None:
    """(N, 2) closed ring of the node refs, or None (with a warning) when it cannot be one."""
    from .buildings import MapTagWarning

    missing = [r for r in refs if r not in nodes]
    if missing:
        warnings.warn(f"map file {source}: {what} names {len(missing)} node(s) the file lacks (e.g. {missing[0]}; "
                      "cut at the download's edge?); the building is left out — download a larger area to keep it",
                      MapTagWarning, stacklevel=4)
        return None
    if len(refs) < 4 or refs[0] != refs[-1] or len(set(refs)) < 3:
        warnings.warn(f"map file {source}: {what} is not a closed ring of ≥ 3 nodes ({len(refs)} refs, first "
                      f"{refs[0] if refs else None}, last {refs[-1] if refs else None}); the building is left out",
                      MapTagWarning, stacklevel=4)
        return None
    return np.array([nodes[r] for r in refs], dtype=np.float64)


def _is_building(tags: dict[str, str]) -> bool:
    return tags.get("building", "no") != "no"


def parse_osm(data: bytes, source: str = "<osm>") -> MapData:
    """:class:`MapData` of OpenStreetMap XML ``data`` (module doc); ``source`` names it in errors."""
    root = _root(data, source)
    nodes = _nodes(root, source)
    ways: dict[str, tuple[list[str], dict[str, str]]] = {}
    for w in root.iterfind("way"):
        if _live(w):
            ways[w.get("id", "")] = ([nd.get("ref", "") for nd in w.iterfind("nd")], _tags(w))
    footprints, streets = [], {}
    for wid, (refs, tags) in ways.items():
        if _is_building(tags):
            ring = _ring(refs, nodes, f"building way {wid}", source)
            if ring is not None:
                footprints.append(Footprint(f"way/{wid}", ring, tags))
        elif "highway" in tags and len(refs) >= 2 and all(r in nodes for r in refs):
            streets[wid] = Street(f"way/{wid}", np.array([nodes[r] for r in refs], dtype=np.float64), tags)
    for rel in root.iterfind("relation"):
        tags = _tags(rel)
        if not (_live(rel) and tags.get("type") == "multipolygon" and _is_building(tags)):
            continue
        rings = {"outer": [], "inner": []}
        for m in rel.iterfind("member"):
            role = m.get("role") or "outer"
            if m.get("type") == "way" and role in rings and m.get("ref") in ways:
                ring = _ring(ways[m.get("ref")][0], nodes, f"relation {rel.get('id')} member way {m.get('ref')}",
                             source)
                if ring is not None:
                    rings[role].append(ring)
        footprints.extend(_with_holes(f"relation/{rel.get('id')}", rings["outer"], rings["inner"], tags))
    return MapData(source, tuple(footprints), streets)


def _with_holes(fid: str, outers: list[np.ndarray], inners: list[np.ndarray], tags: dict) -> list[Footprint]:
    """One footprint per outer ring, each with the inner rings that lie inside it (shapely)."""
    from shapely import Point, Polygon

    out = []
    for k, ring in enumerate(outers):
        poly = Polygon(ring)
        holes = tuple(h for h in inners if poly.contains(Point(h[0])))
        out.append(Footprint(fid if len(outers) == 1 else f"{fid}#{k}", ring, tags, holes))
    return out
