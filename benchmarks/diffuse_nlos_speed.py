"""Cost of the image model's diffuse three-bounce NLOS path: before (every cell pair of every centre
rendered, a per-centre loop) vs after (vectorised over centres, importance cut at the defaults).

    PYTHONPATH=. python benchmarks/diffuse_nlos_speed.py [--repeats 5] [--before a5731649]

Scene: radar77.py's corner (45° concrete facade σ_h = 1 mm, 28 m long, 10 m high) at 77 GHz
(``automotive_77ghz``), hidden object 10 m behind the corner: a point (RCS 10 m²) or a box car
(the ObjectSpec default, its scattering centres on the outline). "before" is ``sims/image.py`` of
commit ``--before`` loaded beside the current package; "after" the working tree at the defaults
(floor −20 dB, at most 20 000 paths) and with every pair kept (floor −300 dB). Per case: median
wall time [ms] of one full frame (simulate: paths, rendering, noise), old and new alternated in one
process, and the number of rendered paths. Speed-ups are ratios of medians taken back to back.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from radar77 import scene as corner  # noqa: E402

from sims.image import ImageForwardModel  # noqa: E402
from xnlos_core.radar import load_radar  # noqa: E402
from xnlos_core.scene import ObjectSpec, Scene  # noqa: E402


def load_before(commit: str):
    """``sims/image.py`` at ``commit`` as module ``sims._image_before`` (relative imports resolve in sims)."""
    src = subprocess.run(["git", "show", f"{commit}:sims/image.py"], capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / "_image_before.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("sims._image_before", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.ImageForwardModel


def paths_ms(model, sc, radar) -> float:
    """Wall time [ms] of the path search alone (model._paths, before rendering)."""
    use = {k: v == "on" for k, v in model.components(sc, radar).items()}
    t0 = time.perf_counter()
    model._paths(sc, sc.planar_walls(), radar, np.random.default_rng(0), 0.0, use)
    return (time.perf_counter() - t0) * 1e3


def frame_ms(model, sc, radar, repeats: int) -> tuple[list[float], int]:
    times, n = [], 0
    for r in range(repeats):
        t0 = time.perf_counter()
        f = model.simulate(sc, radar, np.random.default_rng(r))
        times.append((time.perf_counter() - t0) * 1e3)
        n = f.meta["n_paths"]
    return times, n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--before", default="a5731649")
    args = ap.parse_args(argv)
    Before = load_before(args.before)
    radar = load_radar({"preset": "automotive_77ghz"}, "bench", ".")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; median of {args.repeats} frames\n")
    print("| object | cell [m] | before ms (paths) | after, defaults ms (paths) | after, every pair ms (paths) "
          "| speed-up defaults | speed-up every pair | path search ms before / after every pair | cut (defaults) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for obj in ("point", "box"):
        base = corner(10.0, "concrete", 1e-3)
        car = ObjectSpec(name="car", center=(22.0, -14.0)) if obj == "box" else base.objects[0]
        sc = Scene(name=base.name, walls=base.walls, objects=[car])
        for cell in (1.0, 0.5, 0.25):
            kw = {"diffuse_nlos": "on", "diffuse_nlos_cell": cell}
            models = {"before": Before(kw), "after": ImageForwardModel(kw),
                      "all": ImageForwardModel({**kw, "diffuse_nlos_floor_db": -300.0,
                                                "diffuse_nlos_max_paths": 10_000_000})}
            res = {k: ([], 0) for k in models}
            search = {"before": [], "all": []}
            for _ in range(args.repeats):  # alternate, one frame each, so load drifts hit all alike
                for k, m in models.items():
                    t, n = frame_ms(m, sc, radar, 1)
                    res[k] = (res[k][0] + t, n)
                    if k in search:
                        search[k].append(paths_ms(m, sc, radar))
            med = {k: statistics.median(v[0]) for k, v in res.items()}
            sm = {k: statistics.median(v) for k, v in search.items()}
            cut = models["after"].simulate(sc, radar, np.random.default_rng(0)).meta["components"]["diffuse_nlos_cut"]
            print(f"| {obj} | {cell} | {med['before']:.0f} ({res['before'][1]}) "
                  f"| {med['after']:.0f} ({res['after'][1]}) "
                  f"| {med['all']:.0f} ({res['all'][1]}) | {med['before'] / med['after']:.1f}× "
                  f"| {med['before'] / med['all']:.1f}× | {sm['before']:.0f} / {sm['all']:.0f} "
                  f"| {'; '.join(cut.split('; ')[1:])} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
