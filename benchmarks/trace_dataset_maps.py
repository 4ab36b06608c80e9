"""Ray-trace stage alone (``RaytraceForwardModel.trace``: world, fan, image and mixed paths; no
rendering) on the default dataset's first scenes, single process (not a test).

    PYTHONPATH=. python benchmarks/trace_dataset_maps.py [--scenes 48] [--repeats 3]

Run it with PYTHONPATH pointing at two checkouts, alternately, to compare them on the same scenes.
Prints the median over repeats of the trace time per map [ms].
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from sims.dataset import load_dataset_config, resolve
    from sims.dataset.config import scene_generators
    from sims.dataset.plan import make_plan
    from sims.raytrace.model import RaytraceForwardModel
    from xnlos_core.radar import RadarConfig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=48)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cfg = resolve(load_dataset_config(ROOT / "configs/datasets/default.toml"), "default.toml")
    plan, gens = make_plan(cfg), scene_generators(cfg, "default.toml")
    radar = RadarConfig.model_validate(cfg.radar)
    scenes = [gens[fam].generate(seed) for seed, fam in (plan.scene(k)[:2] for k in range(args.scenes))]
    model = RaytraceForwardModel()
    model.trace(scenes[0], radar)  # warm imports and caches
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        for sc in scenes:
            model.trace(sc, radar)
        times.append((time.perf_counter() - t0) / len(scenes))
    print(f"trace: {1e3 * statistics.median(times):.2f} ms/map (median of {args.repeats} over {len(scenes)} "
          f"dataset scenes; {', '.join(f'{1e3 * t:.2f}' for t in times)})")


if __name__ == "__main__":
    main()
