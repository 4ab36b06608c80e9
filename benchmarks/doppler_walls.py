"""How much of a hidden car's velocity one frame's Doppler holds: the velocity solved from the
radial velocities of its own points, per cluster, against the car's true velocity, by the spread of the
points' mirrored lines of sight.

Runs one case of ``configs/ablations/tracking.toml`` (default: "sindy + Doppler behind nlos_cfar") on the
first ``--sequences`` ``hidden_car_approach`` sequences of a dataset split. Each frame's hidden points are
grouped as the trackers group them (single linkage, 5 m); a group of ≥ 2 points with radial velocities
whose centroid lies within 3 m of a mirror-visible car moving ≥ 0.5 m/s is kept. Its points' rows
ĝ_iᵀv = y_i (weights 1/s_i, s_i from ``velocity_cov`` plus 0.1² m²/s²) are solved for v by weighted
least squares; the error of v is split along ĝ_c (the weighted mean line of sight: what the tracker's
one Doppler row per cluster measures) and across it (what one row cannot see), and compared with the
standard deviation across that the rows state. The spread is the range of the lines of sight's angles
[deg]: points mirrored through two relay walls see the car from two mirrored radars.

Writes benchmarks/doppler_walls.md.

    python benchmarks/doppler_walls.py [--case 4] [--split val] [--sequences 12]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tracking_case import case_parser, family_sequences

BINS = ((0, 2), (2, 5), (5, 10), (10, 90), (90, 360))


def rows(case: int, config: str, dataset: str, split: str, n_seq: int) -> tuple[str, np.ndarray]:
    """(case name, per kept cluster: spread [deg], points, error across, error along [m/s], stated σ across)."""
    from estimators.lsq import single_linkage
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline

    r = plan_runs(config, dataset=dataset, split=split)[case]
    pipe = Pipeline(r["config"], source=r["source"])
    out = []
    for si, frames in enumerate(family_sequences(pipe, "hidden_car_approach")):
        if si >= n_seq:
            break
        for f in frames:
            h = pipe.process(f).hidden
            if h.velocity is None or len(h.mean) < 2:
                continue
            truth = f.meta["object_truth"]
            labels = single_linkage(np.asarray(h.mean, np.float64), 5.0)
            for c in np.unique(labels):
                row = _cluster(h, np.flatnonzero(labels == c), truth)
                if row is not None:
                    out.append(row)
    return r["name"], np.array(out)


def _cluster(h, idx, truth):
    """One kept cluster's row (module docstring), or None."""
    if len(idx) < 2:
        return None
    z = h.mean[idx].mean(0)
    d = [np.linalg.norm(np.asarray(p) - z) for p in truth["position"]]
    j = int(np.argmin(d))
    vt = np.asarray(truth["velocity"][j], np.float64)
    if d[j] > 3.0 or not truth["mirror"][j] or np.linalg.norm(vt) < 0.5:
        return None
    w = np.asarray(h.velocity[idx], np.float64)
    norm = np.linalg.norm(w, axis=1)
    ok = norm > 0
    if ok.sum() < 2:
        return None
    g, y = w[ok] / norm[ok, None], norm[ok]                 # y_i = ĝ_iᵀ w_i with ĝ_i = w_i/|w_i|
    s = np.einsum("mi,mij,mj->m", g, np.asarray(h.velocity_cov)[idx][ok], g) + 0.01
    a, b = g / np.sqrt(s)[:, None], y / np.sqrt(s)
    v = np.linalg.lstsq(a, b, rcond=None)[0]
    gc = (g / s[:, None]).sum(0)
    gc /= np.linalg.norm(gc)
    across = np.array([-gc[1], gc[0]])
    angles = np.unwrap(np.arctan2(g[:, 1], g[:, 0]))
    sigma = float(np.sqrt(max(across @ np.linalg.pinv(a.T @ a) @ across, 0.0)))
    return np.degrees(np.ptp(angles)), len(g), (v - vt) @ across, (v - vt) @ gc, sigma


def report(name: str, r: np.ndarray, cmd: str, seconds: float) -> str:
    lines = [f"# One frame's Doppler of a hidden car, solved per cluster ({name})", "",
             f"{len(r)} clusters of ≥ 2 points on a moving, mirror-visible car; median {np.median(r[:, 1]):.0f} points, "
             f"median spread of their lines of sight {np.median(r[:, 0]):.0f}°.", "",
             "| spread [deg] | clusters | median abs error across ĝ_c [m/s] | median stated σ across [m/s] | "
             "median abs error along ĝ_c [m/s] |", "|---|---|---|---|---|"]
    for lo, hi in BINS:
        m = (r[:, 0] >= lo) & (r[:, 0] < hi)
        if m.any():
            lines.append(f"| {lo}–{hi} | {m.sum()} | {np.median(np.abs(r[m, 2])):.2f} | {np.median(r[m, 4]):.2f} | "
                         f"{np.median(np.abs(r[m, 3])):.2f} |")
    lines += ["", f"`{cmd}` ({seconds:.0f} s)"]
    return "\n".join(lines) + "\n"


def main():
    ap = case_parser(__doc__, case=4, split="val")
    ap.add_argument("--sequences", type=int, default=12)
    ap.add_argument("--out", default=str(Path(__file__).with_name("doppler_walls.md")))
    a = ap.parse_args()
    t0 = time.perf_counter()
    name, r = rows(a.case, a.config, a.dataset, a.split, a.sequences)
    cmd = f"python benchmarks/doppler_walls.py --case {a.case} --split {a.split} --sequences {a.sequences}"
    text = report(name, r, cmd, time.perf_counter() - t0)
    print(text)
    Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
