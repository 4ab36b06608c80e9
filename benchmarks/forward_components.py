"""Cost of each optional forward-model component and the error from leaving it out.

    python benchmarks/forward_components.py [--repeats 7] [--carrier 10e9 77e9]

A scene that needs every component: the built-in corner with ITU-R P.2040 materials (rough
concrete facade of 0.3 m and block faces), a 12 mm glass shop window with a pedestrian
behind it (transmission), a declared standard atmosphere and a radar with −20 dB mutual
coupling. For each component the image model is run with everything on and with that component
switched off (noise off, fixed phases, same seed), and the table reports

* time [ms] per frame (median of ``--repeats``) and the extra cost of the component;
* the error from leaving it out: the largest change of any RA cell, in dB, of |κ|² + N where N is
  the noise floor (so cells buried in noise count as unchanged), and the change in ground-truth
  points a radar could see.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from sims.image import ImageForwardModel
from sims.params import COMPONENTS
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import AtmosphereSpec, ObjectSpec, Scene, WallSpec
from xnlos_core.signal.chain import noise_floor


def scene_needing_everything() -> Scene:
    """The corner geometry with materials, a glass window, a pedestrian and an atmosphere."""
    walls = [
        WallSpec(name="chamfer_facade", start=(15.0, 10.0), end=(35.0, -10.0), material="concrete",
                 thickness=0.3, roughness=2e-3),
        WallSpec(name="near_block_front", start=(5.0, -4.0), end=(18.0, -4.0), material="concrete",
                 roughness=3e-3),
        WallSpec(name="near_block_side", start=(18.0, -4.0), end=(18.0, -30.0), material="concrete",
                 roughness=3e-3),
        WallSpec(name="shop_window", start=(8.0, 6.0), end=(14.0, 6.0), material="glass", thickness=0.012,
                 relay=False),
    ]
    objects = [
        ObjectSpec(name="car", shape="box", center=(22.0, -14.0), size=(4.5, 1.8), heading=1.5708, rcs=10.0),
        ObjectSpec(name="pedestrian", shape="point", center=(11.0, 8.0), rcs=0.5),
    ]
    return Scene(name="components", walls=walls, objects=objects, atmosphere=AtmosphereSpec())


def run(radar: RadarConfig, scene: Scene, params: dict, repeats: int):
    model = ImageForwardModel({"noise": False, "random_phase": False, "tolerance_db": 0.0, **params})
    times, frame = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        frame = model.simulate(scene, radar, np.random.default_rng(0))
        times.append(time.perf_counter() - t0)
    return statistics.median(times), frame


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--carrier", type=float, nargs="+", default=[10e9, 77e9])
    args = ap.parse_args(argv)
    scene = scene_needing_everything()
    for f_c in args.carrier:
        scene_f = scene
        radar = RadarConfig(carrier_frequency=f_c, coupling_db=-20.0)
        n = noise_floor(radar)
        all_on = {c: "on" for c in COMPONENTS}
        run(radar, scene_f, all_on, 1)  # warm caches
        t_full, full = run(radar, scene_f, all_on, args.repeats)
        gt_full = len(full.ground_truth.los_points) + len(full.ground_truth.mnlos_points)
        print(f"\ncarrier {f_c / 1e9:g} GHz — everything on: {1e3 * t_full:.2f} ms/frame, "
              f"{full.meta['n_paths']} paths, {gt_full} visible GT points")
        print(f"{'left out':<14} {'ms/frame':>9} {'saves':>9} {'max RA change':>14} {'GT points':>10}")
        for c in COMPONENTS:
            t, frame = run(radar, scene_f, {**all_on, c: "off"}, args.repeats)
            change = np.abs(10 * np.log10((full.ra_map.power + n) / (frame.ra_map.power + n))).max()
            gt = len(frame.ground_truth.los_points) + len(frame.ground_truth.mnlos_points)
            print(f"{c:<14} {1e3 * t:>9.2f} {1e3 * (t_full - t):>7.2f} ms {change:>11.2f} dB {gt - gt_full:>+10d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
