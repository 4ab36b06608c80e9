"""GeoJSON (RFC 7946) building footprints: ``Polygon`` and ``MultiPolygon`` features, coordinates
[longitude, latitude] in degrees (WGS84), their ``properties`` read as map tags (``height``,
``building:levels``, ``building:material``; values turned to text). Every polygon feature is a
building unless its properties say ``building = "no"``; ``LineString`` features with a ``highway``
property are streets. The feature's ``id`` (or its index) names it."""
from __future__ import annotations

import json
import math

import numpy as np

from xnlos_core.errors import InputError

from .model import Footprint, MapData, Street


def _ring(coords, what: str, source: str) -> np.ndarray:
    try:
        ring = np.asarray(coords, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"map file {source}: {what} is not a list of [lon, lat] positions") from None
    if ring.ndim != 2 or ring.shape[1] < 2 or len(ring) < 4:
        raise InputError(f"map file {source}: {what} needs ≥ 4 [lon, lat] positions (a closed ring), got shape "
                         f"{ring.shape}")
    ring = ring[:, :2]
    if not np.all(np.isfinite(ring)) or np.any(np.abs(ring[:, 0]) > 180) or np.any(np.abs(ring[:, 1]) > 90):
        raise InputError(f"map file {source}: {what} has positions outside ±180° longitude / ±90° latitude")
    if not np.array_equal(ring[0], ring[-1]):
        raise InputError(f"map file {source}: {what} is not closed (its first and last positions differ; "
                         "RFC 7946 §3.1.6)")
    return ring


def _text(v) -> str:
    return v if isinstance(v, str) else json.dumps(v)


def parse_geojson(data: bytes, source: str = "<geojson>") -> MapData:
    """:class:`MapData` of a GeoJSON FeatureCollection (or one Feature) in ``data``."""
    try:
        doc = json.loads(data, parse_constant=lambda c: math.nan)
    except (ValueError, RecursionError) as exc:
        raise InputError(f"map file {source}: not valid JSON: {exc}") from None
    if isinstance(doc, dict) and doc.get("type") == "Feature":
        doc = {"type": "FeatureCollection", "features": [doc]}
    if not (isinstance(doc, dict) and doc.get("type") == "FeatureCollection" and isinstance(doc.get("features"), list)):
        raise InputError(f"map file {source}: expected a GeoJSON FeatureCollection (or Feature) object")
    footprints, streets = [], {}
    for i, feat in enumerate(doc["features"]):
        geom = feat.get("geometry") if isinstance(feat, dict) else None
        if not isinstance(geom, dict):
            continue
        props = feat.get("properties") or {}
        tags = {str(k): _text(v) for k, v in props.items()} if isinstance(props, dict) else {}
        fid = str(feat.get("id", i))
        kind, coords = geom.get("type"), geom.get("coordinates")
        if kind in ("Polygon", "MultiPolygon") and tags.get("building", "yes") != "no":
            polys = [coords] if kind == "Polygon" else coords
            if not isinstance(polys, list):
                raise InputError(f"map file {source}: feature {fid} has no coordinate list")
            for k, poly in enumerate(polys):
                if not isinstance(poly, list) or not poly:
                    raise InputError(f"map file {source}: feature {fid} polygon {k} has no rings")
                name = fid if len(polys) == 1 else f"{fid}#{k}"
                rings = [_ring(r, f"feature {name} ring {j}", source) for j, r in enumerate(poly)]
                footprints.append(Footprint(name, rings[0], tags, tuple(rings[1:])))
        elif kind == "LineString" and "highway" in tags:
            try:
                pts = np.asarray(coords, dtype=np.float64)[:, :2]
            except (TypeError, ValueError, IndexError):
                raise InputError(f"map file {source}: feature {fid} LineString is not a list of [lon, lat]") from None
            streets[fid] = Street(fid, pts, tags)
    return MapData(source, tuple(footprints), streets)
