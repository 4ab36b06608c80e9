"""Ray-tracer speed: time per map, casting throughput against raw embreex, the numpy fallback, and
how cost grows with scene size and bounce depth.

    python benchmarks/raytrace_speed.py [--maps 24] [--repeats 3]

1. Time per map (trace + render + noise) over the generator families (seeds 0…), single process.
2. Rays/s of the tracer's own casting (rays cast during a trace / trace time) against raw embreex
   first-hit casting of a big random batch on the same mesh, and the speed-up of embree over
   the pure-numpy trimesh backend on the same trace.
3. Batching: on the dataset families' meshes, the image-path stage as it was
   (one ``image_paths`` per object and chain: one cast per leg, ~16 rays a call) against the
   batched ``image_paths_chains`` (one cast per leg and chain length), back to back in this
   process, median of ``--repeats``: rays per call, casting Mrays/s (rays / time inside
   ``Caster.first_hit``) and stage time; raw embreex on the same meshes for reference.
4. Cost versus faces (a scene with N extra box obstacles) and versus the bounce cap.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from sims.raytrace.caster import embree_available
from sims.raytrace.model import RaytraceForwardModel
from sims.raytrace.world import build_world
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import ObjectSpec, Scene, WallSpec, load_scene


def _scenes(n: int):
    try:
        from sims.generators import FAMILIES, generate_scene
    except ImportError:
        return [load_scene({"builtin": "corner"}, "corner")] * n, ["corner"]
    fams = sorted(FAMILIES)
    return [generate_scene(fams[i % len(fams)], i) for i in range(n)], fams


def _median_time(fn, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def obstacle_scene(n_boxes: int, seed: int = 0) -> Scene:
    """The corner plus ``n_boxes`` random 1 m wall stubs (12 faces each) off the paths."""
    base = load_scene({"builtin": "corner"}, "corner")
    rng = np.random.default_rng(seed)
    stubs = []
    for i in range(n_boxes):
        x, y = rng.uniform(40, 95), rng.uniform(-60, 60)
        a = rng.uniform(0, np.pi)
        stubs.append(WallSpec(name=f"stub{i}", start=(x, y), end=(x + np.cos(a), y + np.sin(a)), reflectivity=0.5,
                              backscatter_db=-15.0))
    return base.model_copy(update={"walls": base.walls + stubs})


def batching(scenes, radar: RadarConfig, repeats: int) -> None:
    """Section 3 of the module doc: per-chain-and-object casts against batched casts."""
    from sims.raytrace.caster import Caster
    from sims.raytrace.tracer import image_paths, image_paths_chains

    model = RaytraceForwardModel({"backend": "embree"})
    h = model.params.radar_height
    origin = np.array([0.0, 0.0, h])
    cast_time = [0.0]
    plain = Caster.first_hit

    def timed(self, o, d):
        t0 = time.perf_counter()
        try:
            return plain(self, o, d)
        finally:
            cast_time[0] += time.perf_counter() - t0

    cases = []
    for sc in scenes:
        world, _, tr, _ = model.trace(sc, radar)
        pts, nrm = [], []
        for o in sc.objects:
            p2, n2, _ = o.scatterers(0.0)
            pts.append(np.column_stack([p2, np.full(len(p2), min(h, o.height))]))
            nrm.append(np.column_stack([n2, np.zeros(len(n2))]))
        cases.append((world, {(): None, **tr.chains}, pts, nrm))

    def per_chain():
        for world, chains, pts, nrm in cases:
            for j in range(len(pts)):
                for c, sector in chains.items():
                    image_paths(world, origin, pts[j], nrm[j], c, sector, model.params.az_step)

    def batched():
        for world, chains, pts, nrm in cases:
            image_paths_chains(world, origin, pts, nrm, chains, model.params.az_step)

    Caster.first_hit = timed
    try:
        rows = {}
        for name, fn in (("per object and chain (before)", per_chain), ("batched (after)", batched)):
            rows[name] = []
        for _ in range(repeats):  # alternate, so both see the same load
            for name, fn in (("per object and chain (before)", per_chain), ("batched (after)", batched)):
                for w, *_ in cases:
                    w.caster.rays_cast = w.caster.casts = 0
                cast_time[0] = 0.0
                t0 = time.perf_counter()
                fn()
                rows[name].append((time.perf_counter() - t0, cast_time[0], sum(w.caster.rays_cast for w, *_ in cases),
                                   sum(w.caster.casts for w, *_ in cases)))
    finally:
        Caster.first_hit = plain
    # raw embreex on the same meshes: a big batch of random horizontal-ish rays from the radar
    rng = np.random.default_rng(2)
    n = 100_000
    d = rng.standard_normal((n, 3))
    d[:, 2] *= 0.05
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.tile(origin, (n, 1))
    raw = statistics.median(n / _median_time(lambda: w.caster._ray.intersects_first(o, d), repeats)
                            for w, *_ in cases)
    print(f"\nimage-path stage on {len(cases)} dataset maps (median of {repeats}, alternating):")
    print(f"{'':>30} {'rays':>7} {'calls':>6} {'rays/call':>9} {'cast Mrays/s':>12} {'stage ms/map':>12}")
    for name, rs in rows.items():
        t = statistics.median(r[0] for r in rs)
        tc = statistics.median(r[1] for r in rs)
        rays, calls = rs[0][2], rs[0][3]
        print(f"{name:>30} {rays:>7} {calls:>6} {rays / max(calls, 1):>9.1f} {rays / tc / 1e6:>12.3f} "
              f"{1e3 * t / len(cases):>12.2f}")
    before = statistics.median(r[0] for r in rows["per object and chain (before)"])
    after = statistics.median(r[0] for r in rows["batched (after)"])
    print(f"raw embreex first-hit on the same meshes (100k rays, median over maps): {raw / 1e6:.2f} Mrays/s; "
          f"stage speed-up {before / after:.2f}x")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", type=int, default=24)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    radar = RadarConfig()
    model = RaytraceForwardModel()
    scenes, fams = _scenes(args.maps)
    model.simulate(scenes[0], radar, np.random.default_rng(0))  # warm imports and caches
    t0 = time.perf_counter()
    paths, traces = [], []
    for i, sc in enumerate(scenes):
        f = model.simulate(sc, radar, np.random.default_rng(i))
        paths.append(f.meta["n_paths"])
        traces.append(f.meta["trace_s"])
    per_map = (time.perf_counter() - t0) / len(scenes)
    print(f"families: {', '.join(fams)}")
    print(f"time per map: {1e3 * per_map:.1f} ms ({1 / per_map:.1f} maps/s on one core; trace "
          f"{1e3 * np.mean(traces):.1f} ms, {np.mean(paths):.0f} paths/map)")
    print(f"2,160 maps: {2160 * per_map / 60:.1f} min on one core, ≈ {2160 * per_map / 120:.1f} min on 2 workers")

    # casting throughput
    sc = scenes[0]
    if embree_available():
        world = build_world(sc, 0.0, "embree")
        rng = np.random.default_rng(1)
        n = 200_000
        d = rng.standard_normal((n, 3))
        d[:, 2] *= 0.05
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        o = np.tile([0.0, 0.0, 0.75], (n, 1))
        raw = n / _median_time(lambda: world.caster._ray.intersects_first(o, d), args.repeats)
        ours = n / _median_time(lambda: world.caster.first_hit(o, d), args.repeats)
        emb = RaytraceForwardModel({"backend": "embree"})
        tri = RaytraceForwardModel({"backend": "triangle"})
        t_e = _median_time(lambda: emb.trace(sc, radar), args.repeats)
        rays = emb.trace(sc, radar)[2].rays
        t_t = _median_time(lambda: tri.trace(sc, radar), args.repeats)
        print(f"raw embreex first-hit: {raw / 1e6:.2f} Mrays/s; Caster.first_hit (float64 distances): "
              f"{ours / 1e6:.2f} Mrays/s ({100 * ours / raw:.0f} %)")
        print(f"whole trace: {rays} rays in {1e3 * t_e:.1f} ms = {rays / t_e / 1e6:.3f} Mrays/s "
              f"({100 * rays / t_e / raw:.1f} % of raw: the rest is path bookkeeping and electromagnetics)")
        print(f"pure-numpy backend: {1e3 * t_t:.1f} ms per trace → embree speed-up {t_t / t_e:.1f}×")
    else:
        print("embreex not installed: throughput comparison skipped")

    if embree_available():
        batching(scenes, radar, args.repeats)

    print(f"\n{'extra boxes':>11} {'faces':>6} {'trace ms':>9}")
    for nb in (0, 50, 200, 800):
        s = obstacle_scene(nb)
        m = RaytraceForwardModel()
        t = _median_time(lambda: m.trace(s, radar), args.repeats)
        print(f"{nb:>11} {build_world(s).caster.n_faces:>6} {1e3 * t:>9.1f}")

    corridor = Scene(walls=[WallSpec(start=(2.0, 6.0), end=(95.0, 6.0), reflectivity=0.9),
                            WallSpec(start=(2.0, -6.0), end=(95.0, -6.0), reflectivity=0.9)],
                     objects=[ObjectSpec(shape="point", center=(40.0, 0.0), rcs=1.0)])
    print(f"\n{'bounce cap':>10} {'reached':>8} {'paths':>6} {'trace ms':>9} {'map ms':>7}   (corridor of 0.9 mirrors)")
    for cap in (0, 1, 2, 4, 8):
        m = RaytraceForwardModel({"max_bounces": cap, "min_snr_db": -100.0, "noise": False})
        t = _median_time(lambda: m.trace(corridor, radar), args.repeats)
        t_map = _median_time(lambda: m.simulate(corridor, radar, np.random.default_rng(0)), args.repeats)
        f = m.simulate(corridor, radar, np.random.default_rng(0))
        print(f"{cap:>10} {f.meta['max_bounce']:>8} {f.meta['n_paths']:>6} {1e3 * t:>9.1f} {1e3 * t_map:>7.1f}")
    adaptive = RaytraceForwardModel({"max_bounces": 8, "noise": False})
    f = adaptive.simulate(corridor, radar, np.random.default_rng(0))
    print(f"adaptive (min_snr_db 0, cap 8): rays stop after {f.meta['max_bounce']} bounces, {f.meta['n_paths']} paths")
    return 0


if __name__ == "__main__":
    sys.exit(main())
