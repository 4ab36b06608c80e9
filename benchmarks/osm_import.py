"""Import speed of OpenStreetMap XML: a generated city grid of N buildings → scene (walls) and meshes.

Writes a seeded grid of N rectangular-ish blocks (8 corners each, jittered; heights, levels and
materials from tags as in real extracts) around a radar, then times, best and median of REPEATS:
``read`` (parse the file: sims.maps.read_map), ``scene`` (the ``osm`` scene generator's scene:
read + project with pyproj + walls, as a pipeline does it) and ``meshes`` (the extruded prisms).

    python benchmarks/osm_import.py [--no-timing] [--out PATH]   # writes benchmarks/osm_import.md
"""
from __future__ import annotations

import argparse
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.pages import marked  # noqa: E402
from sims.maps import LocalFrame, read_map  # noqa: E402
from sims.maps.buildings import building_meshes  # noqa: E402
from sims.maps.generator import OsmSceneGenerator, _read  # noqa: E402

RADAR = {"lat": 41.393, "lon": 2.161, "heading": 44.0}
SIZES = (200, 2000)
REPEATS = 7
MATERIALS = ("brick", "concrete", "glass", "stone", None)


def city(n: int, seed: int = 0) -> str:
    """OSM XML of n buildings on a grid of 40 m blocks (chamfered corners, 8 nodes each)."""
    rng = np.random.default_rng(seed)
    frame = LocalFrame(**RADAR)
    cols = int(np.ceil(np.sqrt(n)))
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', '<osm version="0.6" generator="xnlos benchmark">']
    ways, nid = [], 1
    for k in range(n):
        cx, cy = 50.0 * (k % cols) - 25.0 * cols, 50.0 * (k // cols) - 25.0 * cols
        half, cut = rng.uniform(15, 20), rng.uniform(2, 6)
        c = np.array([(half - cut, -half), (half, -half + cut), (half, half - cut), (half - cut, half),
                      (-half + cut, half), (-half, half - cut), (-half, -half + cut), (-half + cut, -half)])
        ll = frame.to_lonlat(c + (cx, cy) + rng.normal(0, 0.2, c.shape))
        refs = []
        for lon, lat in ll:
            lines.append(f'  <node id="{nid}" lat="{lat:.7f}" lon="{lon:.7f}"/>')
            refs.append(nid)
            nid += 1
        tags = {"building": "yes"}
        r = rng.random()
        if r < 0.4:
            tags["height"] = f"{rng.uniform(6, 40):.1f}"
        elif r < 0.8:
            tags["building:levels"] = str(int(rng.integers(1, 12)))
        m = MATERIALS[int(rng.integers(len(MATERIALS)))]
        if m:
            tags["building:material"] = m
        ways.append((1000 + k, refs + refs[:1], tags))
    for wid, refs, tags in ways:
        lines.append(f'  <way id="{wid}">')
        lines += [f'    <nd ref="{r}"/>' for r in refs]
        lines += [f'    <tag k="{k}" v="{v}"/>' for k, v in tags.items()]
        lines.append("  </way>")
    lines.append("</osm>")
    return "\n".join(lines) + "\n"


def timed(fn, repeats: int = REPEATS) -> tuple[float, float]:
    times = []
    for _ in range(repeats):
        _read.cache_clear()  # every repeat reads the file again
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-timing", action="store_true", help="only the deterministic table (maps and walls)")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_suffix(".md"))
    args = ap.parse_args()
    sizes, times = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for n in SIZES:
            path = Path(tmp) / f"city{n}.osm"
            path.write_text(city(n))
            gen = OsmSceneGenerator({"map": str(path), "radar": RADAR, "max_distance": 10_000.0})
            scene = gen.generate(0)
            assert scene.meta["buildings"] == n and len(scene.walls) == 8 * n
            sizes.append(f"| {n} | {path.stat().st_size / 1e6:.2f} | {len(scene.walls)} |")
            if args.no_timing:
                continue
            (r0, r1), (s0, s1), (m0, m1) = (timed(lambda: read_map(path)), timed(lambda: gen.generate(0)),
                                            timed(lambda: building_meshes(gen.buildings())))
            times.append(f"| {n} | {r0:.3f} / {r1:.3f} | {s0:.3f} / {s1:.3f} | {m0:.3f} / {m1:.3f} |")
    text = [f"# OpenStreetMap import speed ({Path(__file__).relative_to(Path(__file__).parents[1])})", "",
            "Made by `python benchmarks/osm_import.py` (its maps table: `python -m benchmarks.regenerate "
            "osm_import`).", "",
            "A seeded grid of chamfered blocks (8 corners each, tags for height, levels and material as in real "
            "extracts) written as OSM XML, imported around a radar. `read`: parse the file; `scene`: the `osm` scene "
            "generator's scene (read, project every node with pyproj, one wall per edge) — what a pipeline with "
            "`[scene] family = \"osm\"` does once; `meshes`: the buildings (projected) extruded to closed "
            f"prisms. Best / median of {REPEATS} runs, the file read afresh each time. Target: a 200-building "
            "map's scene ≤ 2 s.", "",
            *marked("maps", ["| buildings | file MB | walls |", "|---:|---:|---:|", *sizes]), ""]
    if times:
        text += [f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}.", "",
                 "| buildings | read s (best / median) | scene s (best / median) | meshes s (best / median) |",
                 "|---:|---:|---:|---:|", *times]
    args.out.write_text("\n".join(text) + "\n")
    print("\n".join(text))


if __name__ == "__main__":
    main()
