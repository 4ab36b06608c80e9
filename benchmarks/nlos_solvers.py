"""Time and peak memory of the NLOS solvers: LCT and f-k on confocal volumes of
64 × 64 × 2048 and 32 × 32 × 512 bins (a hidden point plus Poisson background).

Each (solver, size) runs in a fresh process: the first call ("cold": FFT plans, LCT's resampling
matrix and kernel) and the best of three further calls ("warm": LCT reuses its cached kernel),
and the process's peak resident memory (ru_maxrss, the input volume included).

    python benchmarks/nlos_solvers.py                      # numpy rows; writes nothing, prints a table
    python benchmarks/nlos_solvers.py --device numpy cpu   # and the torch-cpu rows (cuda where a GPU is)
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

# the test volume (a hidden point at (z, y, x) = (1.1, -0.2, 0.3) m plus Poisson background),
# shared with benchmarks/lct_cold.py; needs n, t, np, C and TransientVolume in scope
VOLUME = r"""
rng = np.random.default_rng(0)
bw = 2 * 2.0 / C / t                      # bins reach 2 m depth on a 2 m wall
x = (np.arange(n) - (n - 1) / 2) * (2.0 / n)
r = np.sqrt((x[None, :] - 0.3) ** 2 + (x[:, None] + 0.2) ** 2 + 1.1 ** 2)
data = rng.poisson(1e-3, (t, n, n)).astype(float)
k = np.rint(2 * r / C / bw).astype(int)
i, j = np.nonzero(k < t)
data[k[i, j], i, j] += 1e3 * r[i, j] ** -4
vol = TransientVolume(data, bw, 2.0, 2.0)
del data
"""

CHILD = r"""
import json, resource, sys, time
import numpy as np
from xnlos_core.registry import get_registry
from xnlos_core.transient import TransientVolume, SPEED_OF_LIGHT as C
name, n, t, device = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
""" + VOLUME + r"""solver = get_registry().create("nlos_solver", name, {"device": device})
t0 = time.perf_counter(); out = solver.reconstruct(vol); cold = time.perf_counter() - t0
warm = []
for _ in range(3):
    t0 = time.perf_counter(); out = solver.reconstruct(vol); warm.append(time.perf_counter() - t0)
z, yy, xx = out.peak()
print(json.dumps({"cold_s": cold, "warm_s": min(warm), "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
                  "peak_zyx": [round(z, 3), round(yy, 3), round(xx, 3)]}))
"""


def run(name: str, n: int, t: int, device: str = "numpy") -> dict:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", CHILD, name, str(n), str(t), device], capture_output=True, text=True,
                         check=True, cwd=root, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", nargs="+", default=["numpy"], choices=["numpy", "cpu", "cuda"],
                    help="solver backends to time (the solvers' device parameter)")
    devices = ap.parse_args().device
    print(f"cores: {os.cpu_count()}; load average {os.getloadavg()[0]:.1f}; truth (z, y, x) = (1.1, -0.2, 0.3) m\n")
    print("| solver | device | volume (H × W × T) | cold [s] | warm [s] | peak RSS [GB] | peak (z, y, x) [m] |")
    print("|---|---|---|---|---|---|---|")
    for n, t in ((32, 512), (64, 2048)):
        for name in ("lct", "fk"):
            for device in devices:
                r = run(name, n, t, device)
                print(f"| {name} | {device} | {n} × {n} × {t} | {r['cold_s']:.2f} | {r['warm_s']:.2f} | "
                      f"{r['peak_rss_gb']:.2f} | {tuple(r['peak_zyx'])} |", flush=True)


if __name__ == "__main__":
    main()
