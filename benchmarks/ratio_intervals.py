"""How sure the 2 s forecast ratios of an ``xnlos eval`` are: a bootstrap over sequences.

    .venv/bin/python benchmarks/ratio_intervals.py out/eval/tracking-large [more eval dirs …] \
        [--runs "sindy + Doppler" "oracle → sindy + Doppler"] [--resamples 4000] [--seed 0] \
        [--out benchmarks/ratio_intervals.md]

The issue's forecast target is a ratio: the tracker's mean 2 s-ahead error over constant velocity's
(CV, from the same track states) on cars of one motion kind (xnlos_core.app.sequence_eval,
``family_motions``). Its forecasts are not independent: one car gives up to 40 consecutive ones
from one track, and the split holds a handful of braking cars. So the forecasts are resampled by
whole sequences (the percentile bootstrap, Efron & Tibshirani 1993, ch. 13): each resample draws
the split's sequences with replacement and recomputes the ratio from each sequence's
``xnlos_core.app.sequence_eval.prediction_summary`` (the function eval.md's ratio comes from; pooled as
sums, :func:`interval`). The
table gives, per run and family/motion, the ratio on the split, its 90 % interval and the sequences
that hold a scored 2 s forecast of that kind (the cars' count that decides the spread). Seeded.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xnlos_core.app.sequence_eval import prediction_summary

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
    ap.add_argument("--figure", default=None, help="also draw the car motions' ratios and intervals (PNG)")
    args = ap.parse_args()
    runs = " ".join(f'"{r}"' for r in args.runs)
    lines = ["# 2 s forecast ratios to constant velocity with 90 % sequence-bootstrap intervals", "",
             f"`python benchmarks/ratio_intervals.py {' '.join(args.eval_dirs)} --runs {runs}` ({args.resamples} "
             f"resamples, seed {args.seed}). Each cell: the split's ratio [5 %, 95 %] (sequences).", ""]
    found = {}                                                        # (dir, run) → {kind: (r, lo, hi, n)}
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
                found.setdefault((root.name, name), {})[kind] = (r, lo, hi, n)
                cells.append(f"{r:.2f} [{lo:.2f}, {hi:.2f}] ({n})" if n else "-")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    text = "\n".join(lines)
    if args.out:
        Path(args.out).write_text(text)
    if args.figure:
        figure(found, args.figure)
    print(text)


CAR_KINDS = {"hidden_car_approach/braking": 0.70, "hidden_car_approach/turning": 0.70,
             "hidden_car_approach/straight": 1.05}  # the bars: ≤ 0.70 (braking or turning), ≤ 1.05


def figure(found: dict, path: str) -> None:
    """One panel per car motion: each (eval folder, run)'s ratio with its 90 % interval, the issue's bar dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(found)
    fig, axes = plt.subplots(1, len(CAR_KINDS), figsize=(4.2 * len(CAR_KINDS), 0.45 * len(keys) + 1.6), sharey=True)
    for ax, (kind, bar) in zip(axes, CAR_KINDS.items()):
        for i, key in enumerate(keys):
            r, lo, hi, n = found[key].get(kind, (np.nan,) * 3 + (0,))
            if n:
                ax.errorbar(r, i, xerr=[[r - lo], [hi - r]], fmt="o", color="C0" if r <= bar else "C3", capsize=3)
                ax.annotate(f"{r:.2f} ({n})", (r, i), textcoords="offset points", xytext=(0, 6), ha="center",
                            fontsize=7)
        ax.axvline(bar, ls="--", color="0.4", lw=1)
        ax.axvline(1.0, color="0.8", lw=1, zorder=0)
        ax.set_title(f"{kind.split('/')[1]} cars (bar {bar:.2f})", fontsize=9)
        ax.set_xlabel("2 s error / CV's")
    axes[0].set_yticks(range(len(keys)), [f"{d}: {r}" for d, r in keys], fontsize=7)
    axes[0].invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    main()
