"""Scenes from map files (sims.maps): footprint walls against an independent projection, heights and
materials from tags, lanes, GeoJSON, refused files, and the unit check of user meshes."""
from __future__ import annotations

import json
import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
from pyproj import Transformer

from sims.maps import LocalFrame, MapTagWarning, read_map
from sims.maps.buildings import buildings_from_footprints, parse_height, parse_material
from sims.maps.generator import OsmSceneGenerator
from sims.meshes import load_user_mesh
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.scene import MeshSpec

MAP = Path(__file__).parents[2] / "configs" / "maps" / "intersection.osm"
RADAR = {"lat": 41.393, "lon": 2.161, "heading": 44.0}


def _scene(**kw):
    return OsmSceneGenerator({"map": str(MAP), "radar": RADAR, "default_height": 12.0, **kw})


def _footprint_edges():
    """The building ways' edges of the fixture, read with ElementTree and projected with a transverse
    Mercator (not the importer's azimuthal equidistant) centred on the radar, turned by the heading."""
    root = ET.parse(MAP).getroot()
    nodes = {n.get("id"): (float(n.get("lon")), float(n.get("lat"))) for n in root.iter("node")}
    tm = Transformer.from_crs("EPSG:4326", f"+proj=tmerc +lat_0={RADAR['lat']} +lon_0={RADAR['lon']} +k=1 "
                              "+ellps=WGS84 +units=m", always_xy=True)
    b = math.radians(RADAR["heading"])
    edges = {}
    for way in root.iter("way"):
        if not any(t.get("k") == "building" for t in way.iter("tag")):
            continue
        lon, lat = np.array([nodes[nd.get("ref")] for nd in way.iter("nd")]).T
        e, n = tm.transform(lon, lat)
        xy = np.column_stack([e * math.sin(b) + n * math.cos(b), -e * math.cos(b) + n * math.sin(b)])
        for i in range(len(xy) - 1):
            edges[f"way/{way.get('id')}:{i}"] = (xy[i], xy[i + 1])
    return edges


def test_fixture_walls_match_the_footprint_edges_within_1_cm():
    scene = _scene().generate(0)
    edges = _footprint_edges()
    assert len(edges) == 19 and sorted(w.name for w in scene.walls) == sorted(edges)
    worst = max(max(np.linalg.norm(np.subtract(w.start, edges[w.name][0])),
                    np.linalg.norm(np.subtract(w.end, edges[w.name][1]))) for w in scene.walls)
    assert worst < 0.01, worst
    # the near-right block's street corner lies 10 m ahead and 5 m to the right, as the map was drawn
    corner = [w for w in scene.walls if w.name == "way/101:1"][0]
    assert corner.start == pytest.approx((10.0, -5.0), abs=0.02)


def test_heights_and_materials_come_from_the_tags():
    walls = {w.name.split(":")[0]: w for w in _scene(default_material="brick").generate(0).walls}
    assert (walls["way/101"].height, walls["way/101"].material) == (pytest.approx(18.0), "brick")  # 6 levels × 3 m
    assert (walls["way/102"].height, walls["way/102"].material) == (12.0, "brick")  # no tags: the defaults
    assert (walls["way/103"].height, walls["way/103"].material) == (24.0, "glass")  # height = "24"
    assert (walls["way/104"].height, walls["way/104"].material) == (18.0, "concrete")  # height = "18 m"
    assert parse_height({"height": "70 ft"}, "b", 10.0, 3.0) == pytest.approx(21.336)
    assert parse_height({"building:levels": "4"}, "b", 10.0, 3.5) == 14.0
    with pytest.warns(MapTagWarning, match=r"building b: height='tall' .* building:levels"):
        assert parse_height({"height": "tall", "building:levels": "2"}, "b", 10.0, 3.0) == 6.0
    with pytest.warns(MapTagWarning, match=r"building:material='adobe'.*default_material 'concrete'"):
        assert parse_material({"building:material": "adobe"}, "b", "concrete") == "concrete"
    assert parse_material({"building:material": "timber_framing"}, "b", None) == "wood"
    no_material = _scene(default_material=None).generate(0)
    assert {w.material for w in no_material.walls if w.name.startswith("way/102")} == {None}


def test_meshes_are_closed_prisms_of_the_footprints():
    gen = _scene()
    meshes = gen.meshes()
    assert len(meshes) == 4
    for (mesh, material, bid), b in zip(meshes, gen.buildings()):
        assert mesh.is_watertight and bid == b.id and material == b.material
        assert mesh.bounds[:, 2] == pytest.approx([0.0, b.height])
        x, y = b.outer[:-1].T
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))  # shoelace
        assert mesh.volume == pytest.approx(area * b.height, rel=1e-9)


def test_frame_turns_east_north_into_forward_left():
    north = LocalFrame(41.0, 2.0, 0.0)
    east = LocalFrame(41.0, 2.0, 90.0)
    lon, lat = north.to_lonlat(np.array([100.0, 0.0]))  # 100 m north
    assert lon == pytest.approx(2.0, abs=1e-12) and lat > 41.0
    assert east.to_ego(lon, lat) == pytest.approx([0.0, 100.0], abs=1e-6)  # north is left of an east-looking radar
    assert east.angle(0.0) == pytest.approx(math.pi / 2) and east.angle(180.0) == pytest.approx(-math.pi / 2)
    xy = np.array([[12.0, -34.0], [-250.0, 75.5]])
    ll = LocalFrame(41.393, 2.161, 44.0).to_lonlat(xy)
    assert LocalFrame(41.393, 2.161, 44.0).to_ego(ll[:, 0], ll[:, 1]) == pytest.approx(xy, abs=1e-6)


def test_road_users_by_coordinates_and_by_lane():
    frame = LocalFrame(**RADAR)
    lon, lat = frame.to_lonlat(np.array([14.5, -12.0]))
    users = [{"name": "by_coords", "lat": float(lat), "lon": float(lon), "bearing": 134.0, "speed": 2.0},
             {"name": "by_lane", "kind": "bicycle", "lane": {"way": 202, "offset": 52.0, "side": "right"}},
             {"name": "oncoming", "lane": {"way": "way/202", "offset": 52.0, "side": "left", "lateral": 2.0}}]
    a, b, c = _scene(road_users=users).generate(0).objects
    assert a.center == pytest.approx((14.5, -12.0), abs=1e-6) and a.heading == pytest.approx(-math.pi / 2)
    assert a.velocity == pytest.approx((0.0, -2.0), abs=1e-9) and a.size == (4.5, 1.8)
    # way 202 runs from 40 m left to 40 m right along x = 14.5: 52 m along it is y = −12
    assert b.center == pytest.approx((12.75, -12.0), abs=0.02) and b.heading == pytest.approx(-math.pi / 2, abs=1e-3)
    assert b.kind == "bicycle" and b.size == (1.8, 0.6)
    assert c.center == pytest.approx((16.5, -12.0), abs=0.02) and c.heading == pytest.approx(math.pi / 2, abs=1e-3)
    with pytest.raises(InputError, match=r"lane.way 999 is no street .* its streets: 201, 202"):
        _scene(road_users=[{"lane": {"way": 999}}]).generate(0)
    with pytest.raises(InputError, match=r"lane.offset 500.0 m is beyond the end of way 202 \(80.0 m long\)"):
        _scene(road_users=[{"lane": {"way": 202, "offset": 500.0}}]).generate(0)
    with pytest.raises(ConfigError, match=r"by lat/lon or by lane, exactly one"):
        _scene(road_users=[{"lat": 41.0, "lon": 2.0, "lane": {"way": 202}}])


def test_geojson_footprints_and_holes(tmp_path):
    frame = LocalFrame(**RADAR)
    square = frame.to_lonlat(np.array([[20, -10], [30, -10], [30, 10], [20, 10], [20, -10]], float)).tolist()
    court = frame.to_lonlat(np.array([[24, -2], [26, -2], [26, 2], [24, 2], [24, -2]], float)).tolist()
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "id": "hall", "properties": {"building": "yes", "building:levels": 2},
         "geometry": {"type": "Polygon", "coordinates": [square, court]}},
        {"type": "Feature", "properties": {"building": "no"}, "geometry": {"type": "Polygon", "coordinates": [square]}}]}
    (tmp_path / "m.geojson").write_text(json.dumps(doc))
    (hall,) = read_map(tmp_path / "m.geojson").footprints
    (b,) = buildings_from_footprints([hall], frame)
    assert b.height == 6.0 and len(b.holes) == 1
    assert b.outer[:-1] == pytest.approx(np.array([[20, -10], [30, -10], [30, 10], [20, 10]]), abs=1e-6)
    doc["features"][0]["geometry"]["coordinates"][0] = square[:-1]  # not closed
    (tmp_path / "open.geojson").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"open.geojson: feature hall ring 0 needs ≥ 4|open.geojson: feature hall ring 0 is not closed"):
        read_map(tmp_path / "open.geojson")


BOMB = b"""<?xml version="1.0"?>
<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]>
<osm><node id="1" lat="0" lon="&lol2;"/></osm>"""


@pytest.mark.parametrize("content, message", [
    (BOMB, r"bomb.osm: holds a <!DOCTYPE …> declaration at byte 22; DTDs and entities are refused"),
    (b'<osm><!ENTITY x SYSTEM "file:///etc/passwd"></osm>', r"bomb.osm: holds a <!ENTITY"),
    (b"<osm><node id='1' lat='1' lon='2'></osm>", r"bomb.osm: not well-formed XML at line 1, column 36: mismatched tag"),
    (b"<html><body/></html>", r"bomb.osm: the document element is <html>, not <osm>"),
    (b"<osm><node id='7' lat='95' lon='2'/></osm>", r"bomb.osm: node '7' at lat=95.0, lon=2.0 is outside"),
    (b"<osm><node id='7' lat='x' lon='2'/></osm>", r"bomb.osm: node '7' has lat='x'"),
])
def test_malformed_or_hostile_xml_is_refused_naming_the_file(tmp_path, content, message):
    (tmp_path / "bomb.osm").write_bytes(content)
    with pytest.raises(InputError, match=message):
        read_map(tmp_path / "bomb.osm")


def test_oversized_and_unknown_map_files_are_refused_unread(tmp_path, monkeypatch):
    import sims.maps.reader as reader

    monkeypatch.setattr(reader, "MAX_MAP_BYTES", 100)
    (tmp_path / "big.osm").write_bytes(b"<osm>" + b" " * 200 + b"</osm>")
    with pytest.raises(InputError, match=r"map file .*big.osm is 211 bytes; at most 100 are read"):
        read_map(tmp_path / "big.osm")
    with pytest.raises(InputError, match=r"map file .*m.shp: unknown type '.shp'"):
        read_map(tmp_path / "m.shp")


def test_open_and_cut_building_ways_are_left_out_with_a_warning(tmp_path):
    (tmp_path / "cut.osm").write_text(
        "<osm><node id='1' lat='41.3930' lon='2.1610'/><node id='2' lat='41.3931' lon='2.1610'/>"
        "<node id='3' lat='41.3931' lon='2.1611'/>"
        "<way id='5'><nd ref='1'/><nd ref='2'/><nd ref='3'/><tag k='building' v='yes'/></way>"
        "<way id='6'><nd ref='1'/><nd ref='2'/><nd ref='9'/><nd ref='1'/><tag k='building' v='yes'/></way>"
        "<way id='7'><nd ref='1'/><nd ref='2'/><nd ref='3'/><nd ref='1'/><tag k='building' v='yes'/></way></osm>")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        data = read_map(tmp_path / "cut.osm")
    assert [f.id for f in data.footprints] == ["way/7"]
    text = " ".join(str(w.message) for w in seen if issubclass(w.category, MapTagWarning))
    assert "building way 5 is not a closed ring" in text and "building way 6 names 1 node(s) the file lacks" in text


def _box_stl(path: Path, extents) -> None:
    trimesh.creation.box(extents=extents).export(path)


def test_a_millimetre_mesh_is_refused_unless_its_unit_is_declared(tmp_path):
    _box_stl(tmp_path / "car.stl", (4500.0, 1800.0, 1500.0))  # a car written in millimetres
    with pytest.raises(InputError, match=r"mesh 'car' .*car.stl\) is 4500 units across .* as millimetres 4.5 m\. "
                                         r"The file looks like millimetres"):
        load_user_mesh(MeshSpec(name="car", file="car.stl", material="metal"), tmp_path)
    ((mesh, _, _),) = load_user_mesh(MeshSpec(name="car", file="car.stl", material="metal", unit="mm"), tmp_path)
    assert mesh.extents == pytest.approx([4.5, 1.8, 1.5])
    ((cm, _, _),) = load_user_mesh(MeshSpec(file="car.stl", material="metal", unit="cm", scale=0.1), tmp_path)
    assert cm.extents == pytest.approx([4.5, 1.8, 1.5])
    _box_stl(tmp_path / "block.stl", (800.0, 60.0, 20.0))  # metres, below the bound: accepted as it is
    ((block, _, _),) = load_user_mesh(MeshSpec(file="block.stl", material="concrete"), tmp_path)
    assert block.extents == pytest.approx([800.0, 60.0, 20.0])
    assert "unit" not in MeshSpec(file="block.stl").model_dump()  # scene digests without a unit unchanged
