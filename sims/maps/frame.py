"""The radar's local metric frame on the map: WGS84 longitude/latitude [deg] → (x, y) [m].

A pyproj azimuthal equidistant projection centred on the radar (``+proj=aeqd`` on the WGS84
ellipsoid) gives east/north metres E, N; distances from the centre are true and, within the
few hundred metres of a street scene, the scale error of any direction is below 1e-6. The
radar's heading β (compass bearing of its boresight, degrees clockwise from north) then turns
them into the ego frame of :mod:`xnlos_core.scene` (x forward, y left):

    x = E·sin β + N·cos β,   y = −E·cos β + N·sin β.

A direction of compass bearing γ has the ego-frame angle (β − γ) in radians (counter-clockwise
from +x).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from xnlos_core.errors import InputError


@dataclass(frozen=True)
class LocalFrame:
    """The ego frame of a radar at ``lat``, ``lon`` [deg, WGS84] looking along compass ``heading``
    [deg clockwise from north]."""

    lat: float
    lon: float
    heading: float = 0.0
    _forward: object = field(init=False, repr=False, compare=False)  # pyproj Transformers
    _inverse: object = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        from pyproj import CRS, Transformer  # imported where used: registering the generator stays light

        if not (math.isfinite(self.lat) and -89.0 <= self.lat <= 89.0):
            raise InputError(f"radar latitude must be finite and within ±89°, got {self.lat!r}")
        if not (math.isfinite(self.lon) and -180.0 <= self.lon <= 180.0):
            raise InputError(f"radar longitude must be finite and within ±180°, got {self.lon!r}")
        if not math.isfinite(self.heading):
            raise InputError(f"radar heading must be a finite compass bearing [deg], got {self.heading!r}")
        crs = CRS.from_proj4(f"+proj=aeqd +lat_0={self.lat!r} +lon_0={self.lon!r} +ellps=WGS84 +units=m +no_defs")
        object.__setattr__(self, "_forward", Transformer.from_crs("EPSG:4326", crs, always_xy=True))
        object.__setattr__(self, "_inverse", Transformer.from_crs(crs, "EPSG:4326", always_xy=True))

    def east_north(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """East, north [m] of points (arrays of the same shape, degrees) from the radar."""
        e, n = self._forward.transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(e, float), np.asarray(n, float)

    def to_ego(self, lon, lat) -> np.ndarray:
        """(..., 2) ego-frame (x forward, y left) [m] of points given in degrees."""
        e, n = self.east_north(lon, lat)
        b = math.radians(self.heading)
        out = np.stack([e * math.sin(b) + n * math.cos(b), -e * math.cos(b) + n * math.sin(b)], axis=-1)
        if not np.all(np.isfinite(out)):
            raise InputError("map coordinates do not project to finite metres around the radar (a point on the far "
                             "side of the Earth?)")
        return out

    def to_lonlat(self, xy) -> np.ndarray:
        """(..., 2) longitude, latitude [deg] of ego-frame points (..., 2) [m] (the inverse of :meth:`to_ego`)."""
        xy = np.asarray(xy, float)
        b = math.radians(self.heading)
        e = xy[..., 0] * math.sin(b) - xy[..., 1] * math.cos(b)
        n = xy[..., 0] * math.cos(b) + xy[..., 1] * math.sin(b)
        lon, lat = self._inverse.transform(e, n)
        return np.stack([np.asarray(lon, float), np.asarray(lat, float)], axis=-1)

    def angle(self, bearing_deg: float) -> float:
        """Ego-frame angle [rad] (counter-clockwise from +x) of a compass bearing [deg]."""
        return math.remainder(math.radians(self.heading - bearing_deg), 2 * math.pi)
