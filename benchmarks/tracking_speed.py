"""Tracker update time per frame with 10 tracks (nearest, kalman, sindy) and identify_motion time per
track; writes benchmarks/tracking_speed.md. Issue 28 targets: ≤ 5 ms per frame, ≤ 50 ms per
identification (2 CPU cores).

Ten cars (straight and turning, 10 m/s, 0.3 m noise, 10 Hz) are tracked for 60 frames; the time of
the last 40 frames (all tracks confirmed, identification running for sindy) is reported as median and
maximum per frame; for sindy also the frames without an identification (the association, filter and
forecast alone). identify_motion: 3 s windows (30 samples) of straight, turning and braking tracks.

    OMP_NUM_THREADS=1 python benchmarks/tracking_speed.py
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from estimators.trackers.kalman import KalmanTracker
from estimators.trackers.nearest import NearestTracker
from estimators.trackers.sindy import SindyTracker
from estimators.trackers.sindy_model import identify_motion
from xnlos_core.motion import ConstantAcceleration, ConstantTurn
from xnlos_core.types import HiddenPoints

FRAMES, WARM, DT, N = 60, 20, 0.1, 10


def frames(seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(FRAMES) * DT
    paths = [ConstantTurn(speed=10.0, yaw_rate=0.3 * (k % 3 - 1)).state(t, (20.0 + 15 * (k % 5), 40.0 * (k // 5) - 20),
                                                                          rng.uniform(0, 2 * np.pi)).position
             for k in range(N)]
    out = []
    for i in range(FRAMES):
        z = np.array([p[i] for p in paths]) + 0.3 * rng.standard_normal((N, 2))
        out.append(HiddenPoints(z, np.tile(0.09 * np.eye(2), (N, 1, 1)), np.arange(N), np.zeros(N)))
    return t, out


def time_tracker(tracker, t, fr):
    tracker.reset()
    times, fits = [], []
    for i in range(FRAMES):
        t0 = time.perf_counter()
        out = tracker.update(fr[i], t[i])
        dt = time.perf_counter() - t0
        fitted = any(getattr(tr, "fitted_frame", -1) == i for tr in tracker._tracks)
        if i >= WARM:
            times.append(dt), fits.append(fitted)
    assert len(out) == N, f"{type(tracker).__name__}: {len(out)} tracks, expected {N}"
    return np.array(times) * 1e3, np.array(fits)


def main():
    t, fr = frames()
    lines = ["# Tracking speed (10 tracks, 10 Hz)", "", "| tracker | median [ms/frame] | max [ms/frame] | "
             "median without identification [ms/frame] |", "|---|---|---|---|"]
    for name, tracker in (("nearest", NearestTracker()), ("kalman", KalmanTracker()), ("sindy", SindyTracker())):
        ms, fits = time_tracker(tracker, t, fr)
        plain = np.median(ms[~fits]) if (~fits).any() else np.nan
        lines.append(f"| {name} | {np.median(ms):.2f} | {ms.max():.2f} | {plain:.2f} |")
    lines += ["", "| identify_motion (30 samples, n_models = 10) | median [ms] | max [ms] |", "|---|---|---|"]
    rng = np.random.default_rng(1)
    ts = np.arange(30) * DT
    for name, traj in (("straight", ConstantTurn(speed=10.0, yaw_rate=0.0)), ("turn", ConstantTurn(speed=10.0, yaw_rate=0.3)),
                       ("brake", ConstantAcceleration(speed=12.0, acceleration=-2.5))):
        runs = []
        for r in range(10):
            z = traj.state(ts, (0.0, 0.0), 0.5 + r).position + 0.5 * rng.standard_normal((30, 2))
            t0 = time.perf_counter()
            identify_motion(ts, z, None, n_models=10, seed=r)
            runs.append((time.perf_counter() - t0) * 1e3)
        lines.append(f"| {name} | {np.median(runs):.1f} | {np.max(runs):.1f} |")
    lines += ["", "`OMP_NUM_THREADS=1 python benchmarks/tracking_speed.py` on this machine (2 shared CPU cores)."]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(__file__).with_name("tracking_speed.md").write_text(text)


if __name__ == "__main__":
    main()
