"""Speed–accuracy frontier of the wall estimators (not a test).

    PYTHONPATH=. .venv/bin/python benchmarks/wall_frontier.py [--frames 200] [--out benchmarks/out] [--quick]

(PYTHONPATH=.: a script run puts benchmarks/ first on sys.path, so without it a worktree would
benchmark the editable install's estimators instead of its own.)

Every setting (lsq; casadi_map; casadi_map line-only; laplace_is — Laplace + Student-t importance
sampling with its emcee fallback —; emcee at several (walkers, steps)) runs on
the same simulated frames (:func:`estimators.calibration.simulate_wall_scene`: one relay wall per
frame, a line or — with probability ``--arc-fraction`` — an arc, 8–24 LOS detections of which
``--outlier-fraction`` are clutter, 6 hidden points). Per setting: estimator time per wall [ms] (one wall per frame)
(after ``warm_up``, which builds casadi's Functions for every cluster size once, and one untimed
frame), wall-angle error
[deg] and offset error [m] (median and mean), hidden-point Chamfer distance [m²] (median), the
fraction of true hidden points inside their 50 % / 90 % credible ellipses (total: detection +
wall uncertainty; wall-only: the true virtual points mirrored through the wall posterior), the
number of frames whose wall was chosen as an arc, the effective sample size per wall (median, min;
lsq and casadi_map have none), how many walls warned ESS < min_ess, and laplace_is's emcee fallbacks;
a second table splits the calibration by the true wall type (flat / curved).
Writes wall_frontier.md, wall_frontier.csv and wall_frontier.png under --out and prints the table.
"""
from __future__ import annotations

import argparse
import csv
import io
import logging
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

from estimators.calibration import coverage, evaluate, simulate_wall_scene
from plugins.mirror.mirror import MirrorReconstructor
from xnlos_core.io import atomic_write_bytes, atomic_write_text
from xnlos_core.registry import get_registry

SETTINGS = [
    ("lsq", "lsq", {}),
    ("casadi_map", "casadi_map", {}),
    ("casadi_map line-only", "casadi_map", {"models": ["line"]}),
    ("laplace_is", "laplace_is", {}),
    ("emcee 128×200 (default)", "emcee", {}),
    ("emcee 64×300", "emcee", {"n_walkers": 64, "n_steps": 300, "burn": 100}),
    ("emcee 16×300", "emcee", {"n_walkers": 16, "n_steps": 300, "burn": 100}),
    ("emcee 16×2000 (old default)", "emcee", {"n_walkers": 16, "n_steps": 2000, "burn": 250}),
]
QUICK = {"lsq", "casadi_map", "laplace_is", "emcee 128×200 (default)"}


class Recorder:
    """Passes ``estimate`` through to a wall estimator and keeps every wall's info (ESS, fallback)."""

    def __init__(self, est):
        self.est, self.infos = est, []

    def estimate(self, detections):
        walls = self.est.estimate(detections)
        self.infos.extend(w.info for w in walls)
        return walls


def make_frames(n: int, seed: int, arc_fraction: float, outlier_fraction: float):
    rng = np.random.default_rng(seed)
    frames = []
    for _ in range(n):
        model = "arc" if rng.random() < arc_fraction else "line"
        frames.append(simulate_wall_scene(rng, model=model, n_los=int(rng.integers(8, 25)),
                                          outlier_fraction=outlier_fraction))
    return frames


def run_setting(name: str, kind: str, params: dict, frames) -> dict:
    est = get_registry().create("wall_estimator", kind, params, source=f"wall_frontier {name}")
    rec = MirrorReconstructor()
    n_warn = 0
    est.warm_up(max(len(f.detections) for f in frames))  # casadi builds its Functions once per problem size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        evaluate(est, rec, frames[0])  # warm-up of everything else
        n0 = len(caught)
        est = Recorder(est)
        evals = [evaluate(est, rec, f) for f in frames]
        n_warn = sum("effective sample size" in str(w.message) for w in caught[n0:])
    ess = np.array([i.get("ess", np.nan) for i in est.infos], dtype=float)
    n_fallback = sum(i.get("fallback") == "emcee" for i in est.infos)
    ang = np.array([e.angle_deg for e in evals])
    off = np.array([e.offset_m for e in evals])
    cd = np.array([e.cd for e in evals])
    tot = coverage(np.concatenate([e.m2_total for e in evals]))
    wal = coverage(np.concatenate([e.m2_wall for e in evals]))
    truth_arc = np.array([f.wall.model == "arc" for f in frames])
    chose_arc = np.array([e.model == "arc" for e in evals])
    by_type = {}
    for label, sel in (("flat", ~truth_arc), ("curved", truth_arc)):
        sub = [e for e, keep in zip(evals, sel) if keep]
        t_ = coverage(np.concatenate([e.m2_total for e in sub]) if sub else np.empty(0))
        w_ = coverage(np.concatenate([e.m2_wall for e in sub]) if sub else np.empty(0))
        by_type.update({f"{label}_cov50_total": t_[0.5], f"{label}_cov90_total": t_[0.9],
                        f"{label}_cov50_wall": w_[0.5], f"{label}_cov90_wall": w_[0.9]})
    return {**by_type,
        "setting": name,
        "ms_per_wall": 1e3 * float(np.sum([e.time_s for e in evals])) / max(len(est.infos), 1),
        "ms_per_wall_med": 1e3 * float(np.median([e.time_s for e in evals])),
        "ess_min": float(np.nanmin(ess)) if np.isfinite(ess).any() else float("nan"),
        "ess_med": float(np.nanmedian(ess)) if np.isfinite(ess).any() else float("nan"),
        "fallbacks": n_fallback,
        "angle_med_deg": float(np.median(ang)), "angle_mean_deg": float(np.mean(ang)),
        "offset_med_m": float(np.median(off)), "offset_mean_m": float(np.mean(off)),
        "cd_med_m2": float(np.median(cd)), "cov50_total": tot[0.5], "cov90_total": tot[0.9],
        "cov50_wall": wal[0.5], "cov90_wall": wal[0.9],
        "arc_chosen": f"{int(np.sum(chose_arc & truth_arc))}/{int(truth_arc.sum())} arcs, "
                      f"{int(np.sum(chose_arc & ~truth_arc))}/{int((~truth_arc).sum())} lines",
        "low_ess_warnings": n_warn,
    }


COLUMNS = [("setting", "setting", "{}"), ("ms_per_wall", "ms/wall (mean)", "{:.1f}"),
           ("ms_per_wall_med", "median", "{:.1f}"), ("ess_med", "ESS med", "{:.0f}"),
           ("ess_min", "ESS min", "{:.0f}"),
           ("angle_med_deg", "angle err med [deg]", "{:.3f}"), ("angle_mean_deg", "mean", "{:.3f}"),
           ("offset_med_m", "offset err med [m]", "{:.3f}"), ("offset_mean_m", "mean", "{:.3f}"),
           ("cd_med_m2", "hidden CD med [m²]", "{:.3f}"),
           ("cov50_total", "in 50 % (total)", "{:.3f}"), ("cov90_total", "in 90 % (total)", "{:.3f}"),
           ("cov50_wall", "in 50 % (wall)", "{:.3f}"), ("cov90_wall", "in 90 % (wall)", "{:.3f}"),
           ("arc_chosen", "arc chosen", "{}"), ("low_ess_warnings", "ESS < min_ess warnings", "{}"),
           ("fallbacks", "emcee fallbacks", "{}")]


CAL_COLUMNS = [("setting", "setting", "{}")] + [
    (f"{t}_cov{p}_{k}", f"{t}: in {p} % ({k})", "{:.3f}")
    for t in ("flat", "curved") for k in ("total", "wall") for p in (50, 90)]


def table(rows: list[dict], columns=COLUMNS) -> str:
    head = "| " + " | ".join(c[1] for c in columns) + " |"
    sep = "|" + "---|" * len(columns)
    body = ["| " + " | ".join(fmt.format(r[k]) for k, _, fmt in columns) + " |" for r in rows]
    return "\n".join([head, sep, *body])


def frontier_png(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([r["ms_per_wall"] for r in rows])
    panels = [("angle_med_deg", "median wall-angle error [deg]"), ("offset_med_m", "median offset error [m]"),
              ("cd_med_m2", "median hidden-point CD [m²]"), ("cov90_total", "coverage of 90 % ellipses")]
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.4))
    for ax, (key, label) in zip(axes, panels):
        y = np.array([r[key] for r in rows])
        ax.scatter(t, y, c="tab:blue")
        for r, xi, yi in zip(rows, t, y):
            ax.annotate(r["setting"], (xi, yi), fontsize=7, xytext=(3, 3), textcoords="offset points")
        if key.startswith("cov"):
            ax.axhline(0.9, color="k", lw=0.8, ls="--")
            ax.axhspan(0.85, 0.95, color="0.9", zorder=0)
            y_w = np.array([r["cov90_wall"] for r in rows])
            ax.scatter(t, y_w, c="tab:orange", marker="s", label="wall-only")
            ax.scatter([], [], c="tab:blue", label="total")
            ax.legend(fontsize=7)
        else:
            order = np.argsort(t)
            best, front = np.inf, []
            for i in order:  # Pareto frontier: faster settings that are also at least as accurate
                if y[i] < best:
                    best = y[i]
                    front.append(i)
            ax.plot(t[front], y[front], color="tab:red", lw=1, label="frontier")
            ax.legend(fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("time per wall [ms] (log)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fig.suptitle("wall estimators: speed vs accuracy on the same simulated frames")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--arc-fraction", type=float, default=0.25)
    ap.add_argument("--outlier-fraction", type=float, default=0.1)
    ap.add_argument("--out", default=str(Path(__file__).with_name("out")))
    ap.add_argument("--quick", action="store_true", help="only lsq, casadi_map, laplace_is and two emcee settings")
    args = ap.parse_args()
    logging.getLogger("emcee").setLevel(logging.ERROR)  # our own RuntimeWarning counts short chains
    frames = make_frames(args.frames, args.seed, args.arc_fraction, args.outlier_fraction)
    rows = []
    for name, kind, params in SETTINGS:
        if args.quick and name not in QUICK:
            continue
        t0 = time.perf_counter()
        rows.append(run_setting(name, kind, params, frames))
        logging.getLogger(__name__).info("%s done in %.1f s", name, time.perf_counter() - t0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    header = (f"# Wall estimators: speed vs accuracy — {len(frames)} frames (seed {args.seed}, "
              f"{args.arc_fraction:.0%} arcs, {args.outlier_fraction:.0%} outliers), "
              f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs\n")
    md = (header + "\n" + table(rows) + "\n\n## Calibration by wall type (fraction of true hidden points inside "
          "their credible ellipses; nominal 0.5 / 0.9)\n\n" + table(rows, CAL_COLUMNS) + "\n")
    atomic_write_text(out / "wall_frontier.md", md)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=[c[0] for c in COLUMNS] + [c[0] for c in CAL_COLUMNS[1:]])
    w.writeheader()
    w.writerows(rows)
    atomic_write_text(out / "wall_frontier.csv", buf.getvalue())
    frontier_png(rows, out / "wall_frontier.png")
    print(md)
    print(f"wrote {out / 'wall_frontier.md'}, {out / 'wall_frontier.csv'}, {out / 'wall_frontier.png'}")


if __name__ == "__main__":
    main()
