"""Dataset generation speed: N maps of the default dataset config on a local pool (not a test).

    .venv/bin/python benchmarks/dataset_speed.py [--maps 200] [--workers 2] [--config PATH] [--keep DIR]

Prints maps/s, s/map, the projected time for the full 2,160-map dataset at the same rate, the
bytes per map, the peak resident memory of this (writing) process and of the largest worker
(``resource.getrusage``: run two sizes to see whether memory grows with the dataset), and which
forward model and scene generators (registered components named in ``families``) were used. When the config's forward model is not registered, the ``image`` model
stands in — the output says so.
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from sims.dataset import load_dataset_config, resolve, simulate_dataset
    from xnlos_core.io import read_jsonl
    from xnlos_core.registry import get_registry

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--config", default=str(ROOT / "configs/datasets/default.toml"))
    ap.add_argument("--keep", type=Path, help="write the dataset here (default: a temporary directory)")
    args = ap.parse_args()

    cfg = load_dataset_config(args.config, n_maps=args.maps)
    notes = []
    if cfg.forward_model.name not in get_registry().names("forward_model"):
        notes.append(f"forward model {cfg.forward_model.name!r} is not registered; using 'image'")
        cfg = cfg.model_copy(update={"forward_model": cfg.forward_model.model_copy(
            update={"name": "image", "params": {}})})
    resolve(cfg, args.config)  # unknown families fail here, listing the registered scene generators
    providers = {f: get_registry().get("scene_generator", f).provider for f in cfg.weights()}

    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp) / "ds"
        t0 = time.perf_counter()
        summary = simulate_dataset(cfg, out, source=args.config, workers=args.workers, progress=True)
        wall = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in (Path(out) / "shards").glob("*.npz"))
        recs = read_jsonl(Path(out) / "completed.jsonl")[-summary["generated"]:] if summary["generated"] else []
        cpu = sum(r["cpu_seconds"] for r in recs)
    n = summary["maps_generated"]
    print(f"config: {args.config} (n_maps overridden to {cfg.n_maps})")
    print(f"forward model: {cfg.forward_model.name}; scene generators: {', '.join(f'{f} ({p})' for f, p in providers.items())}; workers: {args.workers} "
          f"local processes; CPU: {os.cpu_count()} cores, {platform.processor() or platform.machine()}")
    for note in notes:
        print(f"note: {note}")
    if not n:
        print("nothing generated (the dataset in --keep was already complete)")
        return
    print(f"{n} maps in {wall:.1f} s (start-up, resolve and writing included): {n / wall:.2f} maps/s, "
          f"{wall / n:.3f} s/map, {size / n / 1e6:.2f} MB/map on disk")
    print(f"projected for 2,160 maps at this rate: {2160 * wall / n / 60:.1f} min "
          f"(target < 10 min on 2 cores)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak RSS: writer process {peak:.0f} MiB, largest worker {child:.0f} MiB "
          f"({n} maps, {size / 2**20:.0f} MiB of shards)")
    print(f"worker CPU time: {cpu / n:.3f} s/map (scene generation, forward model, encoding), so "
          f"{2160 * cpu / n / args.workers / 60:.1f} min of pure work for 2,160 maps on {args.workers} "
          f"idle cores; load average during the run: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
