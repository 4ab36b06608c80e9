"""2 s-ahead forecast error and 90 % interval coverage of the trackers on synthetic hidden tracks.

Straight (CV), turning (CT) and braking (CA) cars from :mod:`xnlos_core.motion` (the project's closed
forms), observed at 10 Hz for ``duration`` (4) s as one hidden point with isotropic noise ``noise`` [m]
(the mirror reconstructor's typical 0.3–0.5 m; no extent wander — the trackers' R still adds their
``extent_sigma``). At the last frame each tracker forecasts 2 s ahead; the error is against the true
position, and a disc covers when the error is within its radius. The coverage calibration on tracks
with the extent wander is benchmarks/forecast_calibration.py. Writes benchmarks/forecast_quality.md.

    python benchmarks/forecast_quality.py [--tracks 12] [--noise 0.5]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from xnlos_core.motion import ConstantAcceleration, ConstantTurn, ConstantVelocity
from xnlos_core.types import HiddenPoints

DT = 0.1


def scenario(kind: str, rng: np.random.Generator):
    """(trajectory, start (2,), heading [rad]) of one random car of ``kind`` (cv, turn, brake)."""
    speed, heading = rng.uniform(8, 14), rng.uniform(0, 2 * np.pi)
    start = rng.uniform(-20, 20, 2) + [30.0, 0.0]
    if kind == "cv":
        return ConstantVelocity(velocity=(speed * np.cos(heading), speed * np.sin(heading))), start, heading
    if kind == "turn":
        return ConstantTurn(speed=speed, yaw_rate=rng.choice([-1, 1]) * rng.uniform(0.2, 0.4)), start, heading
    return ConstantAcceleration(speed=speed + 4, acceleration=-rng.uniform(2.0, 3.0)), start, heading


def run_track(tracker, traj, start, heading, noise: float, duration: float, rng, horizon: float = 2.0):
    """Feed one noisy track to ``tracker``; return (2 s-ahead error [m], radius90 [m], model label, radius50 [m])."""
    tracker.reset()
    n = int(round(duration / DT))
    t = np.arange(n) * DT
    truth = traj.state(t, start, heading).position
    for k in range(n):
        z = truth[k] + noise * rng.standard_normal(2)
        out = tracker.update(HiddenPoints(z[None], noise ** 2 * np.eye(2)[None], [0], [0]), t[k])
    if len(out) != 1:
        return np.nan, np.nan, "lost", np.nan
    j = int(np.argmin(np.abs(out.horizons - horizon)))
    future = traj.state([t[-1] + out.horizons[j]], start, heading).position[0]
    return (float(np.linalg.norm(out.forecast[0, j] - future)), float(out.radius90[0, j]), out.model[0],
            float(out.radius50[0, j]))


def compare(trackers: dict, tracks: int, noise: float, duration: float = 4.0, seed: int = 0) -> dict:
    """{kind: {tracker: (errors (N,), radius90 (N,), labels, radius50 (N,))}} over ``tracks`` cars per kind."""
    out = {}
    for kind in ("cv", "turn", "brake"):
        out[kind] = {}
        for name, tracker in trackers.items():
            rng = np.random.default_rng([seed, ("cv", "turn", "brake").index(kind)])
            errs, r90, labels, r50 = [], [], [], []
            for _ in range(tracks):
                traj, start, heading = scenario(kind, rng)
                e, r, m, r5 = run_track(tracker, traj, start, heading, noise, duration, rng)
                errs.append(e), r90.append(r), labels.append(m), r50.append(r5)
            out[kind][name] = (np.array(errs), np.array(r90), labels, np.array(r50))
    return out


def main():
    from estimators.trackers.kalman import KalmanTracker
    from estimators.trackers.sindy import SindyTracker

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tracks", type=int, default=12)
    ap.add_argument("--noise", type=float, default=0.5)
    a = ap.parse_args()
    t0 = time.perf_counter()
    res = compare({"kalman": KalmanTracker(), "sindy": SindyTracker()}, a.tracks, a.noise)
    lines = [f"# Forecast quality, 2 s ahead ({a.tracks} cars per kind, {a.noise} m noise, 10 Hz, 4 s observed)", "",
             "| kind | kalman mean error [m] | sindy mean error [m] | sindy / kalman | kalman 50 % / 90 % cover | "
             "sindy 50 % / 90 % cover | sindy models |", "|---|---|---|---|---|---|---|"]
    for kind, r in res.items():
        (ek, rk, _, rk5), (es, rs, ls, rs5) = r["kalman"], r["sindy"]
        models = ", ".join(f"{m}: {ls.count(m)}" for m in sorted(set(ls)))
        lines.append(f"| {kind} | {np.nanmean(ek):.2f} | {np.nanmean(es):.2f} | {np.nanmean(es) / np.nanmean(ek):.2f} | "
                     f"{np.mean(ek <= rk5):.2f} / {np.mean(ek <= rk):.2f} | {np.mean(es <= rs5):.2f} / {np.mean(es <= rs):.2f} | "
                     f"{models} |")
    lines += ["", f"`python benchmarks/forecast_quality.py --tracks {a.tracks} --noise {a.noise}` "
                  f"({time.perf_counter() - t0:.0f} s)"]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(__file__).with_name("forecast_quality.md").write_text(text)


if __name__ == "__main__":
    main()
