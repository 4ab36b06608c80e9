"""Conformal calibration of the trackers' forecast discs on held-out sequences (not a test).

    xnlos eval configs/ablations/tracking.toml --split val --out out/eval/tracking-val --no-figures
    xnlos eval configs/ablations/tracking.toml --split train --out out/eval/tracking-train --no-figures
    .venv/bin/python benchmarks/interval_calibration.py out/eval/tracking-val out/eval/tracking-train \
        [--out benchmarks/interval_calibration.md]

(an eval with the config's ``interval_scale`` / ``model_interval_scale`` lines does as well: the radii are
scaled by those factors, and each run's factors, read from its ``run.json``, are divided out again, so the
ratios below are against the Gaussian's own radii either way). Several eval folders are pooled run by run (matched by run name): the
trackers learn nothing from the train split, so every split but test can calibrate, and 9 val
sequences alone gave factors that the test split did not share.

Reads every run of an ``xnlos eval`` of sequences (``run-NNN/sequences.jsonl``: per forecast the error
e [m] of the forecast mean against the truth at t + h and the tracker's disc radii r50, r90 [m],
xnlos_core/sequence_eval.py), splits the (forecast, horizon) pairs by the track's model ("cv" or an
identified one) and gives, per run, class and level q ∈ {0.5, 0.9}, the split-conformal factor

    s_q = the ⌈(n + 1)·q⌉-th smallest of the ratios e / r_q  (n pairs),

so that discs of radius s_q·r_q hold the truth in a share ≥ q of new pairs drawn like these
(exchangeability; consecutive forecasts of one track are correlated, so the guarantee is
approximate and the effective n smaller). The factors go into the tracker's ``interval_scale``
(CV tracks) and, for ``sindy``, ``model_interval_scale`` (tracks with an identified model); the
coverage is then reported on the test split, never on the split the factors came from.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

LEVELS = (0.5, 0.9)


def scales(tracker_params: dict) -> dict[str, tuple[float, float]]:
    """{class: (s50, s90)}: the disc factors a run's tracker applied (1 where its config sets none)."""
    return {cls: tuple(tracker_params.get(key, (1.0, 1.0)))
            for cls, key in (("cv", "interval_scale"), ("model", "model_interval_scale"))}


def pairs(run_dir: Path) -> dict[str, dict[float, np.ndarray]]:
    """{class: {q: ratios e / r_q (n,)}} of one run's scored forecast pairs (finite radii only), r_q the
    Gaussian's own radius: the factors in the run's config (``run.json``) are divided out."""
    info = json.loads((run_dir / "run.json").read_text())
    scale = scales((info["config"].get("tracker") or {}).get("params") or {})
    out: dict[str, dict[float, list]] = {}
    for line in (run_dir / "sequences.jsonl").read_text().splitlines():
        for row in json.loads(line).get("forecasts", []):
            if row.get("err") is None or row.get("r50") is None:
                continue
            cls = "cv" if row.get("model", "cv") == "cv" else "model"
            for q, key, s in zip(LEVELS, ("r50", "r90"), scale[cls]):
                for e, r in zip(row["err"], row[key]):
                    if e is not None and r is not None and r > 0:
                        out.setdefault(cls, {}).setdefault(q, []).append(s * e / r)
    return {c: {q: np.asarray(v) for q, v in d.items()} for c, d in out.items()}


def conformal_factor(ratios: np.ndarray, q: float) -> float:
    """The ⌈(n + 1)q⌉-th smallest ratio (+inf when n is too small for level q)."""
    n = len(ratios)
    k = math.ceil((n + 1) * q)
    return float(np.sort(ratios)[k - 1]) if 0 < k <= n else math.inf


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("eval_dirs", nargs="+", help="xnlos eval output folders, pooled by run name")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    roots = [Path(d) for d in args.eval_dirs]
    lines = [f"# Conformal disc factors from {', '.join(f'`{r}`' for r in roots)}", "",
             "| run | tracker | class | pairs | cover50 now | cover90 now | s50 | s90 |", "|---|---|---|---|---|---|---|---|"]
    pooled: dict[str, tuple[dict, dict]] = {}
    for root in roots:
        for run in sorted(root.glob("run-*")):
            info = json.loads((run / "run.json").read_text())
            by_cls = pooled.setdefault(info["name"], (info, {}))[1]
            for cls, by_q in pairs(run).items():
                for q, r in by_q.items():
                    by_cls.setdefault(cls, {}).setdefault(q, []).append(r)
    for info, by_cls in pooled.values():
        tracker = info["config"].get("tracker") or {}
        for cls, by_q in sorted(by_cls.items()):
            r50, r90 = (np.concatenate(by_q[q]) for q in LEVELS)
            lines.append(f"| {info['name']} | {tracker.get('name', '-')} | {cls} | {len(r90)} | "
                         f"{np.mean(r50 <= 1):.2f} | {np.mean(r90 <= 1):.2f} | {conformal_factor(r50, 0.5):.3f} | "
                         f"{conformal_factor(r90, 0.9):.3f} |")
    lines += ["", "Set `interval_scale = [s50, s90]` of the cv class (and, for sindy, `model_interval_scale` of the "
              "model class) in the tracker's params; report coverage on the test split."]
    text = "\n".join(lines) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
