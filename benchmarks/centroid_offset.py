"""Where on a hidden car its reconstructed points sit, frame by frame: the extended-target offset a
tracker follows instead of the car's centre (not a test).

Runs one case of ``configs/ablations/tracking.toml`` (default: "oracle → sindy + Doppler") on the
``hidden_car_approach`` sequences of a split (through ``benchmarks/forecast_bound.py``'s runner) and,
per frame and moving visible car (truth speed ≥ 0.5 m/s), takes the centroid c of the hidden points
within ``--radius`` (3.5 m) of the car's centre p. Its offset along the car's heading
ĥ = v/|v|, o = (c − p)ᵀĥ [m] (+: towards the front), and across it. Printed: the offset's mean and
spread, its drift rate do/dt [m/s] between consecutive frames (a centroid that slides back along the
body reads as a car slower than it is by −do/dt), the lag-1 autocorrelation of the drift increments
(≈ 0: a random walk; < 0: jitter about a mean) and the same by distance to the radar. Drawn:
``benchmarks/centroid_offset.png``, o against time for the first sequences.

    python benchmarks/centroid_offset.py [--dataset out/data/sequences_large64] [--split test] [--case 6]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tracking_case import case_parser

from forecast_bound import _centroid, run


def offsets(seqs, radius: float) -> list[np.ndarray]:
    """Per (sequence, car): rows (t [s], along [m], across [m], range [m]) of the frames with a centroid."""
    out = []
    for s in seqs:
        cars = sorted({i for f in s for i in f["truth"]})
        for i in cars:
            rows = []
            for f in s:
                if i not in f["truth"]:
                    continue
                p, v, seen, _ = f["truth"][i]
                speed = float(np.linalg.norm(v))
                c = _centroid(f, i, radius) if seen and speed >= 0.5 else None
                if c is None:
                    continue
                h = v / speed
                d = c - p
                rows.append((f["t"], float(d @ h), float(d @ np.array([-h[1], h[0]])), float(np.linalg.norm(p))))
            if len(rows) >= 3:
                out.append(np.array(rows))
    return out


def summary(tracks: list[np.ndarray]) -> list[str]:
    along = np.concatenate([a[:, 1] for a in tracks])
    across = np.concatenate([a[:, 2] for a in tracks])
    rates, inc_pairs = [], []
    for a in tracks:
        dt = np.diff(a[:, 0])
        ok = dt <= 0.15  # consecutive frames (0.1 s), not across a gap
        r = np.diff(a[:, 1])[ok] / dt[ok]
        rates.append(r)
        if len(r) >= 2:
            inc_pairs.append(np.c_[r[:-1], r[1:]])
    rate = np.concatenate(rates)
    pairs = np.concatenate(inc_pairs)
    rho = float(np.corrcoef(pairs[:, 0], pairs[:, 1])[0, 1])
    lines = [f"{len(tracks)} car tracks, {len(along)} frames with a centroid", "",
             "| quantity | mean | SD | median |", "|---|---|---|---|",
             f"| offset along the heading o [m] (+: front) | {along.mean():+.2f} | {along.std():.2f} | {np.median(along):+.2f} |",
             f"| offset across [m] | {across.mean():+.2f} | {across.std():.2f} | {np.median(across):+.2f} |",
             f"| drift do/dt [m/s] between consecutive frames | {rate.mean():+.2f} | {rate.std():.2f} | {np.median(rate):+.2f} |",
             "", f"Lag-1 autocorrelation of the drift increments: {rho:+.2f} (0: a random walk of o; −0.5: white jitter of o).",
             "", "| car's range [m] | frames | mean o [m] | mean do/dt [m/s] |", "|---|---|---|---|"]
    rng = np.concatenate([a[1:, 3][np.diff(a[:, 0]) <= 0.15] for a in tracks])
    al = np.concatenate([a[1:, 1][np.diff(a[:, 0]) <= 0.15] for a in tracks])
    for lo, hi in ((0, 20), (20, 30), (30, 40), (40, 200)):
        m = (rng >= lo) & (rng < hi)
        if m.any():
            lines.append(f"| {lo}–{hi if hi < 200 else '…'} | {m.sum()} | {al[m].mean():+.2f} | {rate[m].mean():+.2f} |")
    return lines


def plot(tracks: list[np.ndarray], path: Path, n: int = 8) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for a in tracks[:n]:
        ax.plot(a[:, 0], a[:, 1], marker=".", lw=1)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("time in the sequence [s]")
    ax.set_ylabel("centroid offset along the heading [m]\n(+: towards the front; 0: the car's centre)")
    ax.set_title(f"hidden cars: where their reconstructed points sit ({min(n, len(tracks))} cars)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = case_parser(__doc__, case=6, split="test")
    ap.add_argument("--radius", type=float, default=3.5)
    ap.add_argument("--figure", default=str(Path(__file__).with_name("centroid_offset.png")))
    a = ap.parse_args()
    t0 = time.perf_counter()
    name, seqs, _, _ = run(a.config, a.case, a.dataset, a.split)
    tracks = offsets(seqs, a.radius)
    print(f"# Centroid offset of hidden cars ({name}, {a.split} split)\n")
    print("\n".join(summary(tracks)))
    plot(tracks, Path(a.figure))
    print(f"\n`python benchmarks/centroid_offset.py --split {a.split} --case {a.case}` "
          f"({time.perf_counter() - t0:.0f} s); figure {Path(a.figure).name}")


if __name__ == "__main__":
    main()
