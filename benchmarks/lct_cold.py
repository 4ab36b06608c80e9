"""LCT cold time, old vs new (≤ 2 s cold on 64 × 64 × 2048, 2 cores).

Alternates fresh processes running the LCT solver of ``--old`` (a git revision; its
estimators/nlos/lct.py is loaded from ``git show``) and of the working tree on the volume of
benchmarks/nlos_solvers.py, ``--repeats`` times each; prints the totals (cold: first
call, FFT plans and kernel included; warm: median of 3 later calls), peak RSS, the medians and the
old/new ratio, and the largest difference of the two outputs relative to their peak.

    python benchmarks/lct_cold.py [--old 50677e8] [--repeats 5] [--n 64] [--t 2048]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from nlos_solvers import VOLUME  # the same test volume (run as a script: benchmarks/ is on sys.path)

CHILD = r"""
import importlib.util, json, resource, sys, time
import numpy as np
from xnlos_core.transient import TransientVolume, SPEED_OF_LIGHT as C
path, n, t, save = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
spec = importlib.util.spec_from_file_location("estimators.nlos._lct_under_test", path)
mod = importlib.util.module_from_spec(spec); spec.loader.exec_module(mod)
""" + VOLUME + r"""s = mod.LCTSolver({})
t0 = time.perf_counter(); out = s.reconstruct(vol); cold = time.perf_counter() - t0
warm = []
for _ in range(3):
    t0 = time.perf_counter(); out = s.reconstruct(vol); warm.append(time.perf_counter() - t0)
if save != "-":
    np.save(save, out.albedo)
print(json.dumps({"cold_s": cold, "warm_s": float(np.median(warm)),
                  "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", default="50677e8")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--t", type=int, default=2048)
    args = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    with tempfile.TemporaryDirectory() as tmp:
        old_src = subprocess.run(["git", "show", f"{args.old}:estimators/nlos/lct.py"], capture_output=True,
                                 text=True, check=True, cwd=root).stdout
        old_path = os.path.join(tmp, "lct_old.py")
        with open(old_path, "w") as fh:
            fh.write(old_src.replace("from .prep import", "from estimators.nlos.prep import"))
        paths = {"old": old_path, "new": os.path.join(root, "estimators", "nlos", "lct.py")}
        res = {"old": [], "new": []}
        for rep in range(args.repeats):
            for name in ("old", "new"):
                save = os.path.join(tmp, f"{name}.npy") if rep == 0 else "-"
                out = subprocess.run([sys.executable, "-c", CHILD, paths[name], str(args.n), str(args.t), save],
                                     capture_output=True, text=True, check=True, cwd=root, env=env)
                res[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
                print(name, res[name][-1], flush=True)
        a, b = np.load(os.path.join(tmp, "old.npy")), np.load(os.path.join(tmp, "new.npy"))
    print(f"\n{args.n} × {args.n} × {args.t}, {os.cpu_count()} cores, load average {os.getloadavg()}")
    print("| code | cold median [s] | warm median [s] | peak RSS [GB] |\n|---|---|---|---|")
    med = {}
    for name in ("old", "new"):
        med[name] = {k: float(np.median([r[k] for r in res[name]])) for k in res[name][0]}
        print(f"| {name} | {med[name]['cold_s']:.2f} | {med[name]['warm_s']:.2f} | {med[name]['peak_rss_gb']:.2f} |")
    print(f"\ncold ratio old/new {med['old']['cold_s'] / med['new']['cold_s']:.2f}×, warm "
          f"{med['old']['warm_s'] / med['new']['warm_s']:.2f}×; max |new − old| / max |old| = "
          f"{np.abs(b - a).max() / np.abs(a).max():.2e}")


if __name__ == "__main__":
    main()
