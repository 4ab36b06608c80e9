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
xnlos_core/app/sequence_eval.py), splits the (forecast, horizon) pairs by the track's model ("cv" or an
identified one) and gives, per run, class and level q ∈ {0.5, 0.9}, the split-conformal factor

    s_q = the ⌈(n + 1)·q⌉-th smallest of the ratios e / r_q  (n pairs),

so that discs of radius s_q·r_q hold the truth in a share ≥ q of new pairs drawn like these
(exchangeability; consecutive forecasts of one track are correlated, so the guarantee is
approximate and the effective n smaller). That guarantee is on average over calibration sets: a
test split of 70 sequences, whose cars differ from sequence to sequence, covers less than q about
as often as more. So the factors the table recommends hold with a stated confidence over whole
sequences (``--confidence``, 0.9; a training-conditional, "PAC" factor, Vovk 2012 and Park et al.
2020, with the sequence as the exchangeable unit):

    s_q^PAC = the confidence-quantile, over ``--resamples`` sequence-bootstrap draws (the
              calibration sequences drawn with replacement, whole), of s_q on the draw,

so that a split of new sequences like these is covered at ≥ q with about that confidence. The
factors go into the tracker's ``interval_scale`` (CV tracks) and, for ``sindy``,
``model_interval_scale`` (tracks with an identified model); the coverage is then reported on the
test split, never on the split the factors came from. Seeded (``--seed``).
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
    return {c: {q: np.concatenate(v) for q, v in d.items()} for c, d in sequence_pairs(run_dir).items()}


def sequence_pairs(run_dir: Path) -> dict[str, dict[float, list[np.ndarray]]]:
    """As :func:`pairs`, the ratios kept apart by sequence: {class: {q: [ratios of one sequence, …]}}
    (sequences without a pair of that class left out)."""
    info = json.loads((run_dir / "run.json").read_text())
    scale = scales((info["config"].get("tracker") or {}).get("params") or {})
    out: dict[str, dict[float, list]] = {}
    for line in (run_dir / "sequences.jsonl").read_text().splitlines():
        seq: dict[tuple[str, float], list] = {}
        for row in json.loads(line).get("forecasts", []):
            if row.get("err") is None or row.get("r50") is None:
                continue
            cls = "cv" if row.get("model", "cv") == "cv" else "model"
            for q, key, s in zip(LEVELS, ("r50", "r90"), scale[cls]):
                for e, r in zip(row["err"], row[key]):
                    if e is not None and r is not None and r > 0:
                        seq.setdefault((cls, q), []).append(s * e / r)
        for (cls, q), v in seq.items():
            out.setdefault(cls, {}).setdefault(q, []).append(np.asarray(v, dtype=np.float64))
    return out


def conformal_factor(ratios: np.ndarray, q: float) -> float:
    """The ⌈(n + 1)q⌉-th smallest ratio (+inf when n is too small for level q)."""
    n = len(ratios)
    k = math.ceil((n + 1) * q)
    return float(np.sort(ratios)[k - 1]) if 0 < k <= n else math.inf


def sequence_factor(sequences: list[np.ndarray], q: float, confidence: float = 0.9, resamples: int = 1000,
                    seed: int = 0) -> float:
    """The PAC factor (module doc): the ``confidence``-quantile (numpy's linear interpolation) of
    :func:`conformal_factor` (level q) over ``resamples`` bootstrap draws of the sequences, each array
    in ``sequences`` one sequence's ratios; +inf when a draw is too small for level q."""
    if not sequences:
        return math.inf
    rng = np.random.default_rng(seed)
    draws = [conformal_factor(np.concatenate([sequences[i] for i in rng.integers(0, len(sequences), len(sequences))]), q)
             for _ in range(resamples)]
    return float(np.quantile(draws, confidence))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("eval_dirs", nargs="+", help="xnlos eval output folders, pooled by run name")
    ap.add_argument("--confidence", type=float, default=0.9, help="of the PAC factors (module doc)")
    ap.add_argument("--resamples", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    roots = [Path(d) for d in args.eval_dirs]
    lines = [f"# Conformal disc factors from {', '.join(f'`{r}`' for r in roots)}", "",
             f"Pooled: s50, s90 (module doc). PAC: the same at confidence {args.confidence:g} over whole sequences "
             f"({args.resamples} sequence-bootstrap draws, seed {args.seed}).", "",
             "| run | tracker | class | sequences | pairs | cover50 now | cover90 now | s50 | s90 | PAC s50 | PAC s90 |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    pooled: dict[str, tuple[dict, dict]] = {}
    for root in roots:
        for run in sorted(root.glob("run-*")):
            info = json.loads((run / "run.json").read_text())
            by_cls = pooled.setdefault(info["name"], (info, {}))[1]
            for cls, by_q in sequence_pairs(run).items():
                for q, seqs in by_q.items():
                    by_cls.setdefault(cls, {}).setdefault(q, []).extend(seqs)
    for info, by_cls in pooled.values():
        tracker = info["config"].get("tracker") or {}
        for cls, by_q in sorted(by_cls.items()):
            r50, r90 = (np.concatenate(by_q[q]) for q in LEVELS)
            pac = [sequence_factor(by_q[q], q, args.confidence, args.resamples, args.seed) for q in LEVELS]
            lines.append(f"| {info['name']} | {tracker.get('name', '-')} | {cls} | {len(by_q[0.9])} | {len(r90)} | "
                         f"{np.mean(r50 <= 1):.2f} | {np.mean(r90 <= 1):.2f} | {conformal_factor(r50, 0.5):.3f} | "
                         f"{conformal_factor(r90, 0.9):.3f} | {pac[0]:.3f} | {pac[1]:.3f} |")
    lines += ["", "Set `interval_scale = [s50, s90]` of the cv class (and, for sindy, `model_interval_scale` of the "
              "model class) in the tracker's params, the PAC columns for coverage that holds over new sequences; "
              "report coverage on the test split."]
    text = "\n".join(lines) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
