"""CPU time per map of ``build_shard`` on the default dataset's first shards, in this process (not a test).

    PYTHONPATH=. python benchmarks/shard_cpu.py [--shards 4] [--repeats 3]

Run it with PYTHONPATH pointing at two checkouts, alternately, to compare them on the same maps
(the work a ``make dataset`` worker does: scene generation, forward model, shard encoding). Prints
the median over repeats of the process CPU time per map [ms] (less sensitive to other processes
on a loaded machine than wall time) and the wall time per map.
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from sims.dataset import load_dataset_config, resolve
    from sims.dataset.config import generator_classes
    from sims.dataset.plan import make_plan
    from sims.dataset.shard import _one_blas_thread, build_shard

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shards", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    src = str(ROOT / "configs/datasets/default.toml")
    cfg = resolve(load_dataset_config(src), src)
    classes, plan, digest = generator_classes(cfg, src), make_plan(cfg), cfg.digest()
    jobs = [(s.name, s.split, [(k, *plan.scene(k)[:2]) for k in s.scenes]) for s in plan.shards[:args.shards]]
    cpu, wall = [], []
    with _one_blas_thread():  # as the dataset workers run
        build_shard(cfg, *jobs[0], digest, classes)  # warm imports and caches
        for _ in range(args.repeats):
            t0, c0, n = time.perf_counter(), time.process_time(), 0
            for job in jobs:
                n += build_shard(cfg, *job, digest, classes)["n_maps"]
            cpu.append((time.process_time() - c0) / n)
            wall.append((time.perf_counter() - t0) / n)
    print(f"build_shard: CPU {1e3 * statistics.median(cpu):.2f} ms/map, wall {1e3 * statistics.median(wall):.2f} "
          f"ms/map (median of {args.repeats} over {n} maps; CPU {', '.join(f'{1e3 * c:.2f}' for c in cpu)})")


if __name__ == "__main__":
    main()
