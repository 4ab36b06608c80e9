"""Map files by type: OpenStreetMap XML (``.osm``, ``.xml``: :mod:`.osm`) or GeoJSON (``.geojson``,
``.json``: :mod:`.geojson`), read as data only — regular files of at most :data:`MAX_MAP_BYTES`
(:func:`xnlos_core.files.read_file_bytes`)."""
from __future__ import annotations

from pathlib import Path

from xnlos_core.errors import ConfigError, InputError
from xnlos_core.files import read_file_bytes

from .geojson import parse_geojson
from .model import MapData
from .osm import parse_osm

MAX_MAP_BYTES = 64 * 1024 * 1024  # a city district's extract; larger files are refused unread
OSM_SUFFIXES = (".osm", ".xml")
GEOJSON_SUFFIXES = (".geojson", ".json")


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
        return parse_geojson(data, str(path))
    return parse_osm(data, str(path))
