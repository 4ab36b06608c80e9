"""OpenStreetMap XML → building footprints and street ways, in WGS84 longitude/latitude [deg].

Untrusted data is read as data only (the file's size is bounded by :func:`sims.maps.reader.read_map`):
an XML document with a DOCTYPE or ENTITY declaration is refused before parsing (no entity
expansion, no external resources), so a file cannot make the parser fetch anything or blow up
memory. Every refusal is an :class:`xnlos_core.errors.InputError` naming the file.

OSM XML: ``<node id lat lon>``; a building is a closed ``<way>`` (first node = last, ≥ 3 distinct
nodes) tagged ``building=*`` (not ``building=no``), or a ``<relation>`` tagged ``type=multipolygon``
and ``building=*`` whose closed ``outer`` member ways are footprints (its closed ``inner`` ways are
courtyards of the outer that holds them). Ways tagged ``highway=*`` are kept as streets (road users
placed by lane). Elements marked ``visible="false"`` or ``action="delete"`` are left out; a building
way that is not closed or names a node the file lacks (cut at the download's edge) is skipped with a
:class:`~sims.maps.model.MapTagWarning`.
"""
from __future__ import annotations

import math
import re
import warnings
import xml.etree.ElementTree as ET

import numpy as np

from xnlos_core.errors import InputError

from .model import Footprint, MapData, MapTagWarning, Street

_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


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
