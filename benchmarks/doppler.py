"""Doppler figures of motion support (not a test): processing time per frame, and un-mirrored velocity error.

    .venv/bin/python benchmarks/doppler.py [--repeats 20] [--cars 12] [--out benchmarks/doppler.md]

1. Time: :func:`xnlos_core.signal.doppler.doppler_ra_maps` on one frame's chirp-sequence cube at the default
   radar size (512 samples × 64 chirp loops × 32 virtual channels → 401 range × 121 azimuth bins) with
   one and two workers, and
   the coherent-mean RA path of the same cube for reference; median of ``--repeats`` after a warm-up.
2. Velocity: hidden cars 20 m from the radar in the corner scene's hidden street, speeds 2–12 m/s in
   random directions along the street (seeded), rendered with the Doppler image model on the lighter
   radar of configs/pipelines/corner_doppler.toml, detected (nlos_cfar), wall by lsq, un-mirrored by
   the mirror reconstructor. Error per hidden point on the car: ĝᵀw − ĝᵀv_true, the observed component
   (:mod:`plugins.mirror.mirror_doppler`) against the truth; RMSE over points, and the mean predicted σ.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from hardware.adc import AdcLayout, canonical_cube
from xnlos_core.config import parse_pipeline
from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube, doppler_ra_maps
from xnlos_core.files import load_toml
from xnlos_core.pipeline import Pipeline
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import ra_map_from_cube

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "pipelines" / "corner_doppler.toml"


def _median_ms(f, repeats: int) -> float:
    f()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts))


def timing(repeats: int) -> list[str]:
    radar = RadarConfig()
    rng = np.random.default_rng(0)
    cube = add_chirp_noise(chirp_sequence_cube(radar, [20.0, 35.0], [0.3, -0.2], [1e-4, 3e-5], [5.0, -1.3]),
                           radar, rng)
    dop = {w: _median_ms(lambda: doppler_ra_maps(cube, radar, workers=w), repeats) for w in (1, 2)}
    ra = _median_ms(lambda: ra_map_from_cube(canonical_cube(cube, AdcLayout(), radar), radar), repeats)
    return ["## Doppler processing time per frame (default radar size)", "",
            f"cube {cube.shape} → maps ({len(radar.range_axis)}, {radar.n_azimuth_bins}); "
            f"{platform.processor() or platform.machine()}, median of {repeats}, load average "
            f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (a shared machine inflates both rows alike; "
            f"old vs new back to back: benchmarks/dechirp_speed.md)", "",
            "| path | median ms |", "|---|---|",
            *(f"| doppler_ra_maps (range–Doppler, beams per Doppler bin, velocity per cell), workers={w} | {t:.1f} |"
              for w, t in dop.items()),
            f"| coherent chirp mean → ra_map_from_cube (no Doppler) | {ra:.1f} |", ""]


def _car_table(base: dict, centre, velocity) -> dict:
    table = {k: v for k, v in base.items()}
    car = dict(base["scene"]["objects"][0])
    car.update(center=[float(c) for c in centre], heading=float(math.atan2(velocity[1], velocity[0])),
               trajectory={"model": "constant_velocity", "velocity": [float(v) for v in velocity]})
    table["scene"] = {**base["scene"], "objects": [car]}
    table["run"] = {**base["run"], "frames": 1, "figure": False}
    return table


def velocity_errors(n_cars: int, seed: int = 0) -> tuple[list[str], np.ndarray]:
    base = load_toml(CONFIG)
    facade_n = np.array([1.0, 1.0]) / math.sqrt(2)  # the corner scene's relay facade x + y = 25
    mirror = np.eye(2) - 2.0 * np.outer(facade_n, facade_n)
    rng = np.random.default_rng(seed)
    errs, sig, rows = [], [], []
    for k in range(n_cars):
        x = rng.uniform(19.1, 19.4)  # hidden street beyond the block side x = 18 m; |o| = 20 m, y ≈ −5 m
        centre = np.array([x, -math.sqrt(20.0**2 - x**2)])
        speed = rng.uniform(2.0, 12.0)
        v = speed * np.array([0.0, rng.choice([-1.0, 1.0])])
        table = _car_table(base, centre, v)
        table["seed"] = int(seed * 1000 + k)
        (res,) = Pipeline(parse_pipeline(table, str(CONFIG), base_dir=CONFIG.parent)).run()
        hid, det = res.hidden, res.detections
        if hid.velocity is None:
            continue
        n_on = 0
        for o, w, cov, src in zip(hid.mean, hid.velocity, hid.velocity_cov, hid.source_index):
            if np.linalg.norm(o - centre) > 3.0:
                continue
            a = det.azimuth[src]
            g = mirror @ np.array([math.cos(a), math.sin(a)])
            errs.append(g @ w - g @ v)
            sig.append(math.sqrt(g @ cov @ g))
            n_on += 1
        rows.append(f"| {k} | ({centre[0]:.1f}, {centre[1]:.1f}) | {v[1]:+.1f} | {n_on} |")
    e = np.array(errs)
    lines = ["## Un-mirrored radial velocity of hidden cars 20 m from the radar", "",
             f"{n_cars} cars (seed {seed}), corner scene, Doppler image model on corner_doppler's radar; "
             f"{len(e)} hidden points on the cars", "",
             f"- RMSE of ĝᵀw − ĝᵀv_true: **{math.sqrt(np.mean(e ** 2)):.3f} m/s** (target ≤ 0.3)"
             if len(e) else "- no hidden point on any car",
             f"- mean error {np.mean(e):+.3f} m/s, max |error| {np.max(np.abs(e)):.3f} m/s, "
             f"mean predicted σ {np.mean(sig):.3f} m/s, share within 2σ "
             f"{np.mean(np.abs(e) <= 2 * np.array(sig)):.2f}" if len(e) else "", "",
             "| car | centre [m] | v_y [m/s] | points on car |", "|---|---|---|---|", *rows, ""]
    return lines, e


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--cars", type=int, default=12)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "doppler.md"))
    args = ap.parse_args()
    lines = ["# Doppler benchmarks", "", "`.venv/bin/python benchmarks/doppler.py`", ""]
    lines += timing(args.repeats)
    lines += velocity_errors(args.cars)[0]
    text = "\n".join(lines) + "\n"
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
