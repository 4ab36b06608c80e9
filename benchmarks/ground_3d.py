"""3-D propagation cost and effect on the corner scene: 2-D frame against 3-D frame (not a test).

    python benchmarks/ground_3d.py [--repeats 15] [--no-timing] [--out benchmarks/ground_3d.md]

The built-in corner scene at the default radar, rendered by each forward model with ``dimensions``
"2d" (the shipped default's choice) and "3d" over a concrete ground (every path with its DG, GD, GG
twins, :mod:`sims.ground`), alternating 2-D and 3-D frames, median wall time of ``--repeats`` after a
warm-up. The ratio (3-D / 2-D, each a median) is the figure; absolute ms move with the machine's load.
The deterministic table (``--no-timing`` writes only it): the paths of the 3-D frame and what ``auto``
decides on the corner scene without and with the ground.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.pages import marked  # noqa: E402
from sims.image import ImageForwardModel  # noqa: E402
from sims.raytrace.model import RaytraceForwardModel  # noqa: E402
from xnlos_core.radar import RadarConfig  # noqa: E402
from xnlos_core.scene import GroundSpec, load_scene  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--no-timing", action="store_true", help="only the deterministic table")
    ap.add_argument("--out", default=str(ROOT / "benchmarks/ground_3d.md"))
    args = ap.parse_args()
    radar = RadarConfig()
    flat = load_scene({"builtin": "corner"}, "benchmark", ".")
    grounded = flat.model_copy(update={"ground": GroundSpec(material="concrete")})
    rows, facts = [], []
    for name, cls in (("image", ImageForwardModel), ("raytrace", RaytraceForwardModel)):
        m2, m3 = cls({"dimensions": "2d"}), cls({"dimensions": "3d"})
        paths3 = m3.simulate(grounded, radar, np.random.default_rng(0)).meta["n_paths"]
        auto = cls({})
        a0 = auto.simulate(flat, radar, np.random.default_rng(0)).meta["components"]["dimensions"]
        a1 = auto.simulate(grounded, radar, np.random.default_rng(0)).meta["components"]["dimensions"]
        facts.append(f"| {name} | {paths3} | {4 * paths3} | {a0} | {a1} |")
        if args.no_timing:
            continue
        times = {2: [], 3: []}
        for k in range(args.repeats + 1):
            for dim, m, sc in ((2, m2, flat), (3, m3, grounded)):
                t = time.perf_counter()
                m.simulate(sc, radar, np.random.default_rng(k))
                if k:
                    times[dim].append(time.perf_counter() - t)
        t2, t3 = (float(np.median(times[d])) * 1e3 for d in (2, 3))
        rows.append(f"| {name} | {t2:.1f} | {t3:.1f} | {t3 / t2:.2f}× |")
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    text = [
        "# 3-D propagation: corner scene, 2-D against 3-D frame", "",
        "`python benchmarks/ground_3d.py` (its table: `python -m benchmarks.regenerate ground_3d`)", "",
        "Paths of the 3-D frame over the concrete ground and what `dimensions = \"auto\"` decides "
        "(`frame.meta[\"components\"][\"dimensions\"]`) without and with that ground:", "",
        *marked("paths_and_auto", [
            "| forward model | paths | synthesised (3-D) | auto without ground | auto with the concrete ground |",
            "|---|---:|---:|---|---|", *facts]), ""]
    if rows:
        text += [
            f"{platform.machine()}, {os.cpu_count()} cores, load average {load} (1 / 5 / 15 min) at the end of the "
            f"run; 2-D and 3-D alternated, median of {args.repeats}", "",
            "| forward model | 2-D ms | 3-D ms (concrete ground) | 3-D / 2-D |",
            "|---|---:|---:|---:|", *rows, "",
            "The target, a 3-D frame of the corner scene ≤ 3× the 2-D frame's time, holds where the ratio "
            "column is ≤ 3×. The 3-D frame synthesises four twins (DD, DG, GD, GG) of every path; the "
            "geometry is found once, in plan.", ""]
    Path(args.out).write_text("\n".join(text), encoding="utf-8")
    print("\n".join(text))


if __name__ == "__main__":
    main()
