"""How sure the 2 s forecast ratios of an ``xnlos eval`` are: a bootstrap over sequences.

    .venv/bin/python benchmarks/ratio_intervals.py out/eval/tracking-large [more eval dirs …] \
        [--runs "sindy + Doppler" "oracle → sindy + Doppler"] [--resamples 4000] [--seed 0] \
        [--out benchmarks/ratio_intervals.md]

The issue's forecast target is a ratio: the tracker's mean 2 s-ahead error over constant velocity's
(CV, from the same track states) on cars of one motion kind (xnlos_core.sequence_eval,
``family_motions``). Its forecasts are not independent: one car gives up to 40 consecutive ones
from one track, and the split holds a handful of braking cars. So the forecasts are resampled by
whole sequences (the percentile bootstrap, Efron & Tibshirani 1993, ch. 13): each resample draws
the split's sequences with replacement and recomputes the ratio with
``xnlos_core.sequence_eval.prediction_summary`` — the same function eval.md's ratio comes from. The
table gives, per run and family/motion, the ratio on the split, its 90 % interval and the sequences
that hold a scored 2 s forecast of that kind (the cars' count that decides the spread). Seeded.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xnlos_core.sequence_eval import prediction_summary

KINDS = ("hidden_car_approach/braking", "hidden_car_approach/turning", "hidden_car_approach/straight",
         "hidden_cyclist/turning", "hidden_cyclist/straight")


def ratio(rows: list[dict]) -> float:
    """Mean 2 s error of the tracker's forecast over CV's (NaN where nothing is scored at 2 s)."""
    s = prediction_summary(rows)
    a, b = s["model"]["fde@2s"], s["cv"]["fde@2s"]
    return a / b if a is not None and b else float("nan")


def by_sequence(run_dir: Path, kind: str) -> list[list[dict]]:
    """The forecast rows of ``kind`` ("family/motion") of each sequence that has any."""
    fam, motion = kind.split("/")
    out = []
    for line in (run_dir / "sequences.jsonl").read_text().splitlines():
        s = json.loads(line)
        rows = [r for r in s["forecasts"] if s["family"] == fam and r["motion"] == motion]
        if rows:
            out.append(rows)
    return out


def interval(seqs: list[list[dict]], resamples: int, rng: np.random.Generator) -> tuple[float, float, float, int]:
    """(ratio, 5 %, 95 % bootstrap quantiles, sequences scored at 2 s)."""
    scored = [s for s in seqs if prediction_summary(s)["cv"]["n@2s"]]
    if not scored:
        return float("nan"), float("nan"), float("nan"), 0
    draws = np.array([ratio([r for i in rng.integers(0, len(scored), len(scored)) for r in scored[i]])
                      for _ in range(resamples)])
    lo, hi = np.nanquantile(draws, [0.05, 0.95])
    return ratio([r for s in scored for r in s]), float(lo), float(hi), len(scored)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("eval_dirs", nargs="+", help="xnlos eval output folders (one table each)")
    ap.add_argument("--runs", nargs="*", default=["sindy + Doppler", "oracle → sindy + Doppler"])
    ap.add_argument("--resamples", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    lines = ["# 2 s forecast ratios to constant velocity with 90 % sequence-bootstrap intervals", "",
             f"`python benchmarks/ratio_intervals.py {' '.join(args.eval_dirs)}` ({args.resamples} resamples, "
             f"seed {args.seed}). Each cell: the split's ratio [5 %, 95 %] (sequences).", ""]
    for root in map(Path, args.eval_dirs):
        rng = np.random.default_rng(args.seed)
        lines += [f"## `{root}`", "", "| run | " + " | ".join(KINDS) + " |", "|---|" + "---|" * len(KINDS)]
        for run in sorted(root.glob("run-*")):
            name = json.loads((run / "run.json").read_text())["name"]
            if name not in args.runs:
                continue
            cells = []
            for kind in KINDS:
                r, lo, hi, n = interval(by_sequence(run, kind), args.resamples, rng)
                cells.append(f"{r:.2f} [{lo:.2f}, {hi:.2f}] ({n})" if n else "-")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    text = "\n".join(lines)
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
