"""Scenes from map data: building footprints of OpenStreetMap XML (``.osm``) or GeoJSON, projected
into the radar's frame, as scene walls and extruded 3-D meshes.

* :mod:`.frame`: the local metric frame (pyproj azimuthal equidistant projection centred on the
  radar, turned to x forward along the radar's heading, y left);
* :mod:`.reader`, :mod:`.osm`, :mod:`.geojson`: safe readers of the two formats (size-limited, no DTD
  or entities) into :mod:`.model`'s footprints and streets;
* :mod:`.buildings`: footprints → heights and materials from tags → walls and trimesh meshes;
* :mod:`.generator`: the ``osm`` scene generator (``[scene] family = "osm"``) with road users
  placed by coordinates or by lane.
"""
from .buildings import Building, building_meshes, buildings_from_footprints, walls_of
from .frame import LocalFrame
from .generator import OsmSceneGenerator
from .model import Footprint, MapData, MapTagWarning
from .reader import read_map

__all__ = ["Building", "Footprint", "LocalFrame", "MapData", "MapTagWarning", "OsmSceneGenerator", "building_meshes",
           "buildings_from_footprints", "read_map", "walls_of"]
