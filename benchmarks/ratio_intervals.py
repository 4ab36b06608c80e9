"""How sure the 2 s forecast ratios of an ``xnlos eval`` are: a bootstrap over sequences.

    .venv/bin/python benchmarks/ratio_intervals.py out/eval/tracking-large [more eval dirs …] \
        [--runs "sindy + Doppler" "oracle → sindy + Doppler"] [--resamples 4000] [--seed 0] \
        [--out benchmarks/ratio_intervals.md]

The issue's forecast target is a ratio: the tracker's mean 2 s-ahead error over constant velocity's
(CV, from the same track states) on cars of one motion kind (xnlos_core.sequence_eval,
``family_motions``). Its forecasts are not independent: one car gives up to 40 consecutive ones
from one track, and the split holds a handful of braking cars. So the forecasts are resampled by
whole sequences (the percentile bootstrap, Efron & Tibshirani 1993, ch. 13): each resample draws
the split's sequences with replacement and recomputes the ratio from each sequence's
``xnlos_core.sequence_eval.prediction_summary`` (the function eval.md's ratio comes from; pooled as
sums, :func:`interval`). The
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
    """(ratio, 5 %, 95 % bootstrap quantiles, sequences scored at 2 s).

    Each sequence is summarised once: its summed 2 s errors and their counts (the mean 2 s error of
    ``prediction_summary`` times its ``n@2s``), tracker's and CV's; a resample's pooled means are then
    sums of those, the same as ``prediction_summary`` of the resample's rows."""
    sums = []
    for s in seqs:
        p = prediction_summary(s)
        if p["cv"]["n@2s"]:
            sums.append([(p[k]["fde@2s"] or 0.0) * p[k]["n@2s"] for k in ("model", "cv")]
                        + [p[k]["n@2s"] for k in ("model", "cv")])
    if not sums:
        return float("nan"), float("nan"), float("nan"), 0
    sums = np.array(sums)                                             # (S, 4): Σe, Σe_cv, n, n_cv

    def ratios(tot):                                                  # (…, 4) → (…,)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (tot[..., 0] / tot[..., 2]) / (tot[..., 1] / tot[..., 3])

    draws = ratios(sums[rng.integers(0, len(sums), (resamples, len(sums)))].sum(1))
    lo, hi = np.nanquantile(draws, [0.05, 0.95])
    return float(ratios(sums.sum(0))), float(lo), float(hi), len(sums)


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
