"""FDTD versus analytic slab |R| (normal incidence) for materials × thickness × {10, 77} GHz.

Usage: .venv/bin/python benchmarks/fdtd_check.py [--ppw 40]
Prints one row per case: |R| from the 1-D FDTD and from the Airy formula (P.2040-3 Eq. 43a),
the complex error |R_fdtd − R_analytic|, grid size, time steps and wall time. No caching.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.constants import speed_of_light

from sims.fdtd import simulate_slab
from sims.fresnel import slab
from sims.materials import get_material

MATERIALS = ("concrete", "glass", "wood", "plasterboard", "metal")
THICKNESS_MM = (1.0, "half-wave", 10.0, 30.0, 100.0, 300.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ppw", type=float, default=40.0, help="cells per wavelength in the densest medium")
    args = ap.parse_args()
    print(f"{'material':13s} {'f GHz':>5s} {'d mm':>8s} {'|R| fdtd':>9s} {'|R| an.':>8s} {'|ΔR|':>8s} "
          f"{'cells':>6s} {'steps':>7s} {'time s':>7s}")
    worst, total = 0.0, 0.0
    for f in (10e9, 77e9):
        for name in MATERIALS:
            m = get_material(name)
            e1, sig, eps = float(m.real_permittivity(f)), float(m.conductivity(f)), m.permittivity(f)
            for d_mm in THICKNESS_MM:
                d = speed_of_light / f / (2 * np.sqrt(e1)) if d_mm == "half-wave" else d_mm * 1e-3
                t0 = time.perf_counter()
                res = simulate_slab(e1, sig, d, f, ppw=args.ppw)
                dt = time.perf_counter() - t0
                total += dt
                Ra, _ = slab(eps, d, 0.0, f)
                err = abs(res.R[0] - Ra)
                worst = max(worst, abs(abs(res.R[0]) - abs(Ra)))
                print(f"{name:13s} {f / 1e9:5.0f} {d * 1e3:8.3f} {abs(res.R[0]):9.4f} {abs(Ra):8.4f} {err:8.1e} "
                      f"{res.n_cells:6d} {res.n_steps:7d} {dt:7.3f}")
    print(f"worst ||R_fdtd| − |R_an|| = {worst:.4f}; total FDTD time {total:.2f} s")


if __name__ == "__main__":
    main()
