"""How steady the relay walls are frame by frame, fitted to one frame's LOS detections or to those of
the last K (``lsq``'s ``history_frames``; not a test).

Runs the detector and ``lsq`` of one case of ``configs/ablations/tracking.toml`` over the
``hidden_car_approach`` sequences of a dataset split (the estimator reset at each sequence), for each
K given. Per frame and true relay wall (``GroundTruth.walls``, canonical (n, b)), the estimated wall
nearest to it is the one with the smallest |Δφ| among those within ``--tolerance`` (10°, 1.5 m by
default: |Δφ| and |Δb| at the wall's centre); none such: the wall is missing in that frame. Prints the
share of (frame, wall) pairs found, the median and 90th percentile of |Δφ| [deg] and of the offset error
at the wall's centre [m], and draws ``benchmarks/wall_history.png``: the normal-angle error of the walls
of one sequence frame by frame, for each K.

    python benchmarks/wall_history.py [--dataset out/data/sequences_large64] [--split val] [--case 4] [--k 1 5]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tracking_case import case_parser, family_sequences

FAMILY = "hidden_car_approach"


def errors(config: str, case: int, dataset: str, split: str, k: int, tol_deg: float, tol_m: float):
    """Per sequence, per frame: [(wall index, |Δφ| [deg] or NaN when missing, |Δd| [m] or NaN)]."""
    from xnlos_core.errors import InsufficientDataError
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline

    r = plan_runs(config, dataset=dataset, split=split)[case]
    cfg = r["config"]
    cfg.wall_estimator.params["history_frames"] = k
    pipe = Pipeline(cfg, source=r["source"])
    detector, estimator = pipe.stages["detector"], pipe.stages["wall_estimator"]
    out = []
    for frames in family_sequences(pipe, FAMILY):
        seq = []
        for frame in frames:
            try:
                walls = estimator.estimate(detector.detect(frame))
            except InsufficientDataError:
                walls = []
            rows = []
            for j, w in enumerate(frame.ground_truth.walls):
                n, b = w._line
                centre = 0.5 * (np.asarray(w.start) + np.asarray(w.end))
                best = (np.nan, np.nan)
                for e in walls:
                    dphi = np.degrees(np.arccos(min(1.0, abs(float(e.normal @ n)))))
                    dd = abs(float(e.normal @ centre + e.offset))  # the estimate's distance from the true wall's centre
                    if dphi <= tol_deg and dd <= tol_m and not dphi >= best[0]:
                        best = (dphi, dd)
                rows.append((j, *best))
            seq.append(rows)
        out.append(seq)
    return out


def summary(seqs) -> tuple[float, float, float, float, float, int]:
    a = np.array([(p, d) for seq in seqs for rows in seq for _, p, d in rows], dtype=np.float64).reshape(-1, 2)
    found = ~np.isnan(a[:, 0])
    q = lambda v, p: float(np.percentile(v, p)) if len(v) else float("nan")  # noqa: E731
    return (float(found.mean()), q(a[found, 0], 50), q(a[found, 0], 90), q(a[found, 1], 50), q(a[found, 1], 90),
            len(a))


def plot(runs: dict[int, list], path: Path, sequence: int, most: int = 4) -> None:
    """The |Δφ| of each K's walls frame by frame in one sequence, for the (up to ``most``) true walls
    that the largest K finds in ≥ 20 % of the frames (walls no K sees are left out)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def series(k, j):
        return np.array([next((p for i, p, _ in rows if i == j), np.nan) for rows in runs[k][sequence]])

    ks = sorted(runs)
    n_walls = max(len(rows) for rows in runs[ks[0]][sequence])
    seen = [j for j in range(n_walls) if np.mean(~np.isnan(series(ks[-1], j))) >= 0.2][:most]
    cols = min(2, max(1, len(seen)))
    rows = max(1, -(-len(seen) // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(6.0 * cols, 3.2 * rows), squeeze=False, sharey=True)
    for ax, j in zip(axes.flat, seen):
        for k in ks:
            y = series(k, j)
            t = 0.1 * np.arange(len(y))
            ax.plot(t, y, marker="o", ms=3, lw=1, label=f"K = {k}: missing in {np.mean(np.isnan(y)):.0%} of frames")
        ax.set_title(f"true relay wall {j}")
        ax.set_xlabel("time in the sequence [s] (0.1 s frames)")
        ax.set_ylabel("|Δφ| [deg] (gap: missing)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(seen):]:
        ax.set_visible(False)
    fig.suptitle("lsq walls behind nlos_cfar, one hidden-car sequence: each frame alone vs K frames pooled")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = case_parser(__doc__, case=4, split="val")
    ap.add_argument("--k", type=int, nargs="+", default=[1, 5], help="history_frames to compare")
    ap.add_argument("--tolerance", type=float, nargs=2, default=[10.0, 1.5], metavar=("DEG", "M"))
    ap.add_argument("--sequence", type=int, default=0, help="the sequence drawn")
    ap.add_argument("--figure", default=str(Path(__file__).with_name("wall_history.png")))
    a = ap.parse_args()
    runs = {}
    print("| K | (frame, wall) pairs | found | median abs dphi [deg] | 90 % [deg] | median offset error [m] | 90 % [m] | time [s] |")
    print("|---|---|---|---|---|---|---|---|")
    for k in a.k:
        t0 = time.perf_counter()
        runs[k] = errors(a.config, a.case, a.dataset, a.split, k, *a.tolerance)
        found, p50, p90, d50, d90, n = summary(runs[k])
        print(f"| {k} | {n} | {found:.2f} | {p50:.2f} | {p90:.2f} | {d50:.2f} | {d90:.2f} | {time.perf_counter() - t0:.0f} |")
    plot(runs, Path(a.figure), a.sequence)
    print(f"\nwrote {a.figure}")


if __name__ == "__main__":
    main()
