"""What a map file holds, in WGS84 longitude/latitude [deg]: building footprints and streets, and the
warning for map data that could not be used."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from xnlos_core.errors import XnlosWarning


class MapTagWarning(XnlosWarning):
    """Map data that could not be used (a height that is no number, an unknown material, an open or cut
    building way); the default took its place, or the building was left out."""


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
