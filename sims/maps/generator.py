"""The ``osm`` scene generator: a scene from a map file (OpenStreetMap XML or GeoJSON) seen by a
radar placed on that map, with road users placed by coordinates or by lane.

In a pipeline::

    [scene]
    family = "osm"
    [scene.overrides]
    map = "../maps/intersection.osm"          # relative to this config file
    radar = { lat = 41.39, lon = 2.16, heading = 44.0 }   # WGS84 [deg]; heading: compass bearing [deg]
    default_height = 12.0                      # m, buildings without height / building:levels
    default_material = "concrete"              # ITU-R P.2040 name, buildings without building:material
    [[scene.overrides.road_users]]
    name = "hidden_car"
    lat = 41.3901
    lon = 2.1603
    bearing = 134.0                            # compass bearing of its heading [deg]
    [[scene.overrides.road_users]]
    name = "cyclist"
    kind = "bicycle"
    lane = { way = 100, offset = 25.0, side = "right" }   # 25 m along street way 100 from its first node
    speed = 4.0

The scene is the same for every seed (a map is no random draw). Walls are the footprint edges
(:func:`~sims.maps.buildings.walls_of`), heights and materials from the tags
(:mod:`sims.maps.buildings`); :meth:`OsmSceneGenerator.buildings` and :meth:`OsmSceneGenerator.meshes`
give the buildings and their extruded trimesh prisms in the same frame.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from xnlos_core.errors import InputError
from xnlos_core.interfaces import SceneGenerator
from xnlos_core.motion import MAX_SPEED
from xnlos_core.param_paths import RELATIVE_TO_CONFIG, ConfigPath
from xnlos_core.scene import ObjectSpec, Scene

from ..generators.params import KINDS
from .buildings import Building, building_meshes, buildings_from_footprints, walls_of
from .frame import LocalFrame
from .model import MapData
from .reader import read_map


class RadarSite(BaseModel):
    """Where the radar stands on the map and where it looks."""

    model_config = ConfigDict(extra="forbid")
    lat: float = Field(..., ge=-89, le=89, allow_inf_nan=False, description="latitude [deg, WGS84]")
    lon: float = Field(..., ge=-180, le=180, allow_inf_nan=False, description="longitude [deg, WGS84]")
    heading: float = Field(0.0, ge=-360, le=360, allow_inf_nan=False,
                           description="compass bearing of the boresight [deg clockwise from north]")


class Lane(BaseModel):
    """A place on a street way of the map: ``offset`` metres along its centre line from its first
    node, then ``lateral`` metres to its ``side`` (right or left of the way's direction, or on it)."""

    model_config = ConfigDict(extra="forbid")
    way: int | str = Field(..., description="id of a highway=* way (GeoJSON: the feature id)")
    offset: float = Field(0.0, ge=0, le=10_000, allow_inf_nan=False, description="distance along the way [m]")
    side: Literal["right", "left", "centre"] = "right"
    lateral: float = Field(1.75, ge=0, le=50, allow_inf_nan=False,
                           description="distance from the centre line [m] (half a 3.5 m lane)")


class RoadUser(BaseModel):
    """A car, bicycle, pedestrian or other scatterer placed on the map by ``lat``/``lon`` or by ``lane``.

    ``bearing``: compass bearing of its heading [deg]; default: along the lane (the way's direction
    on its right side, against it on its left) or, placed by coordinates, the radar's heading.
    Size, height and RCS default to the class's nominal values (the scene families' presets).
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "road_user"
    kind: Literal["car", "bicycle", "pedestrian", "generic"] = "car"
    lat: float | None = Field(None, ge=-89, le=89, allow_inf_nan=False)
    lon: float | None = Field(None, ge=-180, le=180, allow_inf_nan=False)
    lane: Lane | None = None
    bearing: float | None = Field(None, ge=-360, le=360, allow_inf_nan=False)
    speed: float = Field(0.0, ge=0, le=MAX_SPEED, allow_inf_nan=False, description="along its heading [m/s]")
    size: tuple[float, float] | None = Field(None, description="(length, width) [m]")
    height: float | None = Field(None, gt=0, le=50)
    rcs: float | None = Field(None, gt=0, le=1e6, description="[m²]")

    @model_validator(mode="after")
    def _place(self):
        by_coords = self.lat is not None or self.lon is not None
        if by_coords and (self.lat is None or self.lon is None):
            raise ValueError(f"road user {self.name!r}: give both lat and lon")
        if by_coords == (self.lane is not None):
            raise ValueError(f"road user {self.name!r}: place it by lat/lon or by lane, exactly one")
        return self


class Params(BaseModel):
    """A scene from a map file seen from a radar placed on it (module doc)."""

    model_config = ConfigDict(extra="forbid")
    map: ConfigPath = Field(..., min_length=1, description="OpenStreetMap XML (.osm) or GeoJSON map file"
                                                          + RELATIVE_TO_CONFIG)
    radar: RadarSite = Field(..., description="{lat, lon} [deg, WGS84] of the radar and the compass heading "
                                                 "of its boresight [deg clockwise from north]")
    name: str | None = Field(None, description="scene name (default: the map file's stem)")
    default_height: float = Field(10.0, gt=0, le=500, description="height of buildings without height or "
                                                                  "building:levels tags [m]")
    level_height: float = Field(3.0, gt=0, le=20, description="height of one building:levels level [m]")
    default_material: str | None = Field("concrete", description="ITU-R P.2040 material of buildings without "
                                                                 "building:material (None: constant reflectivity)")
    roughness: float = Field(0.0, ge=0, le=0.5, description="rms surface height of the walls [m]")
    spacing: float = Field(0.25, gt=0.005, le=10, description="scatterer spacing along the walls [m]")
    max_distance: float = Field(300.0, gt=0, le=10_000, description="leave out buildings farther from the radar [m]")
    road_users: list[RoadUser] = Field(default_factory=list)

    @field_validator("default_material")
    @classmethod
    def _material(cls, v):
        if v is None:
            return v
        from ..materials import get_material

        try:
            return get_material(v).name
        except InputError as exc:
            raise ValueError(str(exc)) from None


@functools.lru_cache(maxsize=8)
def _read(path: str, mtime_ns: int, size: int) -> MapData:
    return read_map(path)


def load_map(path: str | Path) -> MapData:
    """:func:`~sims.maps.osm.read_map`, cached by path, modification time and size."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        raise InputError(f"map file {p}: cannot read: {exc.strerror or exc}") from None
    return _read(str(p.resolve()), st.st_mtime_ns, st.st_size)


class OsmSceneGenerator(SceneGenerator):
    """Scene from an OpenStreetMap (.osm) or GeoJSON map: building footprints → walls with heights
    and materials from tags, a radar placed by latitude, longitude and heading, road users by
    coordinates or lane."""

    Params = Params

    @property
    def frame(self) -> LocalFrame:
        r = self.params.radar
        return LocalFrame(r.lat, r.lon, r.heading)

    def map_data(self) -> MapData:
        return load_map(self.params.map)

    def buildings(self) -> list[Building]:
        """The map's buildings within ``max_distance`` in the radar's frame [m]."""
        p = self.params
        return buildings_from_footprints(self.map_data().footprints, self.frame, default_height=p.default_height,
                                         default_material=p.default_material, level_height=p.level_height,
                                         max_distance=p.max_distance)

    def meshes(self):
        """[(trimesh, material, building id)]: the buildings extruded to their heights (ego frame [m])."""
        return building_meshes(self.buildings())

    def generate(self, seed: int) -> Scene:
        """The map's scene (the same for every ``seed`` ≥ 0)."""
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"scene family 'osm': seed must be an integer ≥ 0, got {seed!r}")
        p = self.params
        data = self.map_data()
        frame = self.frame
        buildings = self.buildings()
        objects = [self._road_user(u, frame, data) for u in p.road_users]
        return Scene(name=p.name or Path(p.map).stem, walls=walls_of(buildings, roughness=p.roughness,
                                                                       spacing=p.spacing),
                     objects=objects,
                     meta={"map": str(p.map), "radar": p.radar.model_dump(), "buildings": len(buildings),
                           "frame": "aeqd"})

    def _road_user(self, u: RoadUser, frame: LocalFrame, data: MapData) -> ObjectSpec:
        if u.lane is not None:
            xy, along = _lane_point(u, frame, data)
        else:
            xy, along = frame.to_ego(u.lon, u.lat), 0.0
        heading = frame.angle(u.bearing) if u.bearing is not None else along
        preset = KINDS.get(u.kind)
        size = u.size or (preset.size if preset else (1.0, 1.0))
        height = u.height or (preset.height if preset else 1.5)
        rcs = u.rcs or (float(np.mean(preset.rcs)) if preset else 10.0)
        vel = (u.speed * math.cos(heading), u.speed * math.sin(heading))
        try:
            return ObjectSpec(name=u.name, shape="box", kind=u.kind, center=(float(xy[0]), float(xy[1])),
                              size=size, height=height, heading=heading, rcs=rcs, velocity=vel)
        except ValueError as exc:
            raise InputError(f"road user {u.name!r}: {exc}") from None


def _lane_point(u: RoadUser, frame: LocalFrame, data: MapData) -> tuple[np.ndarray, float]:
    """Ego position [m] and heading [rad] of a road user placed by lane."""
    from shapely import LineString

    lane = u.lane
    key = str(lane.way)
    street = data.streets.get(key) or data.streets.get(key.removeprefix("way/"))
    if street is None:
        known = ", ".join(sorted(data.streets)[:20]) or "(none)"
        raise InputError(f"road user {u.name!r}: lane.way {lane.way!r} is no street (highway=*) way of "
                         f"{data.source}; its streets: {known}")
    pts = frame.to_ego(street.points[:, 0], street.points[:, 1])
    line = LineString(pts)
    if lane.offset > line.length:
        raise InputError(f"road user {u.name!r}: lane.offset {lane.offset} m is beyond the end of way {lane.way} "
                         f"({line.length:.1f} m long)")
    p = np.array(line.interpolate(lane.offset).coords[0])
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    i = int(np.clip(np.searchsorted(cum, lane.offset, side="right") - 1, 0, len(pts) - 2))
    t = pts[i + 1] - pts[i]
    t = t / np.linalg.norm(t)
    left = np.array([-t[1], t[0]])
    heading = math.atan2(t[1], t[0])
    if lane.side == "right":
        return p - lane.lateral * left, heading
    if lane.side == "left":
        return p + lane.lateral * left, math.remainder(heading + math.pi, 2 * math.pi)
    return p, heading
