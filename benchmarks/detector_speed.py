"""Prices of the learned detector's inference options (not a test).

    PYTHONPATH=. .venv/bin/python benchmarks/detector_speed.py [--dataset out/data/default] [--split test]
        [--max-maps 48] [--threads 2] [--repeats 15] [--detector swin_unet]
        [--variants plain,fp32,bf16,compile,compile_bf16] [--radius 1.0] [--agree-radius 0.3]

Variants of one detector and checkpoint, all on the same maps:

- ``plain``: the inference before the fast path (contiguous NCHW float32, ``run_network``);
- ``fp32``: the shipped default (``inference_mode``, channels-last);
- ``bf16``: ``precision = "bf16"``; ``compile``: ``compile = true``; ``compile_bf16``: both.

Latency: median / p90 ms of ``detect`` per map with ``torch.set_num_threads(threads)``, the variants
interleaved map by map (each repeat runs every variant on the same map back to back), so load from
other processes hits them alike and the ratios hold; each variant is warmed up first
(``warm_up``, whose seconds — compilation included — are listed). Quality: F1 of each variant's
detections against the ``fp32`` detections (same class, one-to-one within ``agree-radius`` metres,
pooled over the maps), and the Macro-F1 against ground truth thinned to the radar's resolution
(mean over maps, match radius ``radius``, as ``benchmarks/detectors.py`` scores it).
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

VARIANTS = {"plain": {}, "fp32": {}, "bf16": {"precision": "bf16"}, "compile": {"compile": True},
            "compile_bf16": {"compile": True, "precision": "bf16"}}


def build(name: str, variant: str, radar):
    """(detector, warm-up seconds) of ``variant`` on ``radar``'s grid; ``plain`` runs the path before channels-last inference and warm-up."""
    import copy

    import torch

    from plugins.detectors.learned import run_network
    from xnlos_core.registry import get_registry

    det = get_registry().create("detector", name, {"device": "cpu", **VARIANTS[variant]})
    t0 = time.perf_counter()
    det.warm_up(radar)
    warm = time.perf_counter() - t0
    if variant == "plain":
        net = copy.deepcopy(det._net).to(memory_format=torch.contiguous_format)
        det._runner = lambda feats: run_network(net, feats, torch.device("cpu"))
    return det, warm


def agreement(a, b, radius: float) -> float:
    """Pooled F1 of detection lists ``a`` against ``b`` (per class, one-to-one within ``radius`` m)."""
    from xnlos_core.metrics import match_points

    tp = n = 0
    for da, db in zip(a, b):
        for k in np.union1d(np.unique(da.label), np.unique(db.label)):
            pa, pb = da.position[da.label == k], db.position[db.label == k]
            tp += len(match_points(pa, pb, radius)[0])
            n += len(pa) + len(pb)
    return 2 * tp / max(n, 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="out/data/default")
    ap.add_argument("--split", default="test")
    ap.add_argument("--max-maps", type=int, default=48)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--detector", default="swin_unet")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--radius", type=float, default=1.0)
    ap.add_argument("--agree-radius", type=float, default=0.3)
    args = ap.parse_args()
    variants = args.variants.split(",")
    if "fp32" not in variants or not set(variants) <= set(VARIANTS):
        ap.error(f"--variants {args.variants}: a subset of {list(VARIANTS)} that includes fp32")

    import torch

    from sims.dataset import open_dataset
    from xnlos_core.metrics import dense_metrics, thin_to_resolution

    torch.set_num_threads(args.threads)
    ds = open_dataset(args.dataset, args.split)
    frames = [f for _, f in zip(range(args.max_maps or len(ds)), ds)]
    radar = frames[0].ra_map.radar
    dets, warm = {}, {}
    for v in variants:
        dets[v], warm[v] = build(args.detector, v, radar)
    times = {v: [] for v in variants}
    for k in range(args.repeats):
        f = frames[k % len(frames)]
        for v in variants:
            t0 = time.perf_counter()
            dets[v].detect(f)
            times[v].append(time.perf_counter() - t0)
    found = {v: [dets[v].detect(f) for f in frames] for v in variants}
    truth = [thin_to_resolution(f.ground_truth, f.ra_map.radar) for f in frames]
    macro = {v: float(np.mean([dense_metrics(d, g, args.radius)["macro"]["f1"] for d, g in zip(found[v], truth)]))
             for v in variants}
    compiled = {v: getattr(dets[v]._runner, "compiled", False) for v in variants}
    print(f"# {args.detector} inference options on {args.dataset} ({args.split}: {len(frames)} maps of "
          f"{frames[0].ra_map.shape[0]} × {frames[0].ra_map.shape[1]}), {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs, torch {torch.__version__}, threads {args.threads}, load average "
          f"{' / '.join(f'{x:.1f}' for x in os.getloadavg())}\n")
    print(f"| variant | median ms | p90 ms | speed-up vs plain | warm-up s | F1 vs fp32 detections "
          f"({args.agree_radius} m) | Macro-F1 vs ground truth ({args.radius} m) |\n|---|---|---|---|---|---|---|")
    base = np.median(times["plain"]) if "plain" in times else np.median(times["fp32"])
    for v in variants:
        t = 1e3 * np.array(times[v])
        note = "" if not VARIANTS[v].get("compile") or compiled[v] else " (compile fell back to eager)"
        print(f"| {v}{note} | {np.median(t):.1f} | {np.percentile(t, 90):.1f} | {1e3 * base / np.median(t):.2f}× | "
              f"{warm[v]:.1f} | {agreement(found[v], found['fp32'], args.agree_radius):.3f} | {macro[v]:.3f} |")


if __name__ == "__main__":
    main()
