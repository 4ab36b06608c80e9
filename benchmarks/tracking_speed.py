"""Tracker update time per frame with 10 tracks (nearest, kalman, sindy) and identify_motion time per
track; writes benchmarks/tracking_speed.md. Targets: ≤ 5 ms per frame, ≤ 50 ms per
identification (2 CPU cores).

Ten cars (straight and turning, 10 m/s, 0.3 m noise, 10 Hz) are tracked for 60 frames; the time of
the last 40 frames (all tracks confirmed, identification running for sindy) is reported as median and
maximum per frame; and per frame without the time spent identifying (sindy identifies one track in
every frame: ten tracks due every ``refit_every`` = 2 frames, ``max_fits_per_frame`` = 1), i.e.
the association, filter, forecast and bookkeeping alone, with the identification time per call.
identify_motion alone: 3 s windows (30 samples) of straight, turning and braking tracks, from the
positions and with their radial velocities too (0.2 m/s noise, seen from the origin). The hidden
points carry those radial velocities, so kalman and sindy run with their Doppler update and sindy's
identification fits them (its defaults; the rows "…, screened" with screen_radial on). The rows "…, the ablation's Doppler" run the tracking
ablation's setting (configs/ablations/tracking.toml: one Doppler row per relay wall, gated at χ²₁
0.999, tracks kept lost for 10 frames, and sindy's evidence bars 30 / 10 with its radial residuals counted in full) on cars seen through two relay walls: each car gives two
points 0.5 m apart with wall_index 0 and 1, the second's radial velocity along the line of sight
turned by 90° (two rows per track). The rows "…, cars missed 6 frames each" take the same cars with car k
missed in frames 25 + 2k to 30 + 2k: its track is lost after 3 misses (the second association pass runs)
and revived by its next hit.

    OMP_NUM_THREADS=1 python benchmarks/tracking_speed.py
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from estimators.trackers.kalman import KalmanTracker
from estimators.trackers.nearest import NearestTracker
from estimators.trackers.sindy import SindyTracker as _Sindy
from estimators.trackers.sindy_model import identify_motion
from xnlos_core.motion import ConstantAcceleration, ConstantTurn
from xnlos_core.types import HiddenPoints

FRAMES, WARM, DT, N = 60, 20, 0.1, 10


def SindyTracker(params=None):
    """The sindy tracker as this page measures it: ensemble SINDy, one identification a frame (the
    library default is timed by benchmarks/bicycle_forecasts.py)."""
    return _Sindy({"identification": "ensemble", "max_fits_per_frame": 1, **(params or {})})


def frames(seed: int = 0, two_walls: bool = False, gaps: bool = False):
    """Ten cars' hidden points per frame; with ``gaps`` car k is missed in frames 25 + 2k … 30 + 2k (lost
    after ``max_misses`` = 3 of them, revived by the next hit)."""
    rng = np.random.default_rng(seed)
    t = np.arange(FRAMES) * DT
    states = [ConstantTurn(speed=10.0, yaw_rate=0.3 * (k % 3 - 1)).state(t, (20.0 + 15 * (k % 5), 40.0 * (k // 5) - 20),
                                                                          rng.uniform(0, 2 * np.pi))
              for k in range(N)]
    out = []
    for i in range(FRAMES):
        seen = ~((i >= 25 + 2 * np.arange(N)) & (i < 31 + 2 * np.arange(N))) if gaps else np.ones(N, bool)
        out.append(_frame(states, i, rng, two_walls, seen))
    return t, out


def _frame(states, i, rng, two_walls: bool, seen) -> HiddenPoints:
    """Frame ``i``'s hidden points of the cars ``seen`` (N,) bool (:func:`frames`); every car's noise is
    drawn, seen or not, so that the draws do not depend on the gaps."""
    z = np.array([s.position[i] for s in states]) + 0.3 * rng.standard_normal((N, 2))
    v = np.array([s.velocity[i] for s in states])
    g = z / np.linalg.norm(z, axis=1, keepdims=True)
    y = np.sum(g * v, axis=1) + 0.2 * rng.standard_normal(N)
    walls = np.zeros(N)
    if two_walls:
        g2 = g @ np.array([[0.0, 1.0], [-1.0, 0.0]])                 # the second wall's line of sight, +90°
        y2 = np.sum(g2 * v, axis=1) + 0.2 * rng.standard_normal(N)
        z, g, y, walls, seen = np.r_[z, z + 0.5 * g2], np.r_[g, g2], np.r_[y, y2], np.r_[walls, np.ones(N)], np.r_[seen, seen]
    z, g, y, walls = z[seen], g[seen], y[seen], walls[seen]
    m = len(z)
    return HiddenPoints(z, np.tile(0.09 * np.eye(2), (m, 1, 1)), np.arange(m), walls, velocity=y[:, None] * g,
                        velocity_cov=0.04 * g[:, :, None] * g[:, None, :])


def time_tracker(tracker, t, fr):
    """(ms per frame (F,), ms per frame spent in identifications (F,), ms per identification (I,))."""
    tracker.reset()
    ident = getattr(tracker, "_identify", None)
    spent = []
    if ident is not None:
        def timed(tr):
            t0 = time.perf_counter()
            ident(tr)
            spent.append(time.perf_counter() - t0)
        tracker._identify = timed
    times, in_fits, calls = [], [], []
    for i in range(FRAMES):
        n0 = len(spent)
        t0 = time.perf_counter()
        out = tracker.update(fr[i], t[i])
        dt = time.perf_counter() - t0
        if i >= WARM:
            times.append(dt), in_fits.append(sum(spent[n0:])), calls.extend(spent[n0:])
    assert len(out) == N, f"{type(tracker).__name__}: {len(out)} tracks, expected {N}"
    return np.array(times) * 1e3, np.array(in_fits) * 1e3, np.array(calls) * 1e3


def main():
    t, fr = frames()
    _, fr2 = frames(two_walls=True)
    _, fr3 = frames(two_walls=True, gaps=True)
    ablation = {"doppler_rows": "wall", "doppler_gate": 0.999, "lost_frames": 10}
    sindy_ablation = {**ablation, "min_evidence": 30.0, "braking_evidence": 10.0, "radial_share": "full"}
    lines = ["# Tracking speed (10 tracks, 10 Hz)", "", "| tracker | median [ms/frame] | max [ms/frame] | "
             "median without identification [ms/frame] | max without identification [ms/frame] | "
             "identification median [ms each] |", "|---|---|---|---|---|---|"]
    for name, tracker, data in (("nearest", NearestTracker(), fr), ("kalman", KalmanTracker(), fr),
                                ("sindy", SindyTracker(), fr),
                                ("kalman, the ablation's Doppler", KalmanTracker(ablation), fr2),
                                ("sindy, the ablation's Doppler", SindyTracker(sindy_ablation), fr2),
                                ("kalman, the ablation's, cars missed 6 frames each", KalmanTracker(ablation), fr3),
                                ("sindy, the ablation's, cars missed 6 frames each", SindyTracker(sindy_ablation), fr3)):
        ms, fit_ms, calls = time_tracker(tracker, t, data)
        plain = ms - fit_ms
        ident = f"{np.median(calls):.1f} ({len(calls)} in {len(ms)} frames)" if len(calls) else "–"
        lines.append(f"| {name} | {np.median(ms):.2f} | {ms.max():.2f} | {np.median(plain):.2f} | {plain.max():.2f} | "
                     f"{ident} |")
    lines += ["", "| identify_motion (30 samples, n_models = 5, the default) | median [ms] | max [ms] |", "|---|---|---|"]
    rng = np.random.default_rng(1)
    ts = np.arange(30) * DT
    for name, traj in (("straight", ConstantTurn(speed=10.0, yaw_rate=0.0)), ("turn", ConstantTurn(speed=10.0, yaw_rate=0.3)),
                       ("brake", ConstantAcceleration(speed=12.0, acceleration=-2.5))):
        for doppler, screen in ((False, False), (True, False), (True, True)):
            runs = []
            for r in range(10):
                st = traj.state(ts, (20.0, 5.0), 0.5 + r)
                z = st.position + 0.5 * rng.standard_normal((30, 2))
                g = z / np.linalg.norm(z, axis=1, keepdims=True)
                kw = {"direction": g, "radial": np.sum(g * st.velocity, axis=1) + 0.2 * rng.standard_normal(30),
                      "screen_radial": screen} if doppler else {}
                t0 = time.perf_counter()
                identify_motion(ts, z, None, n_models=SindyTracker.Params().n_models, seed=r, **kw)
                runs.append((time.perf_counter() - t0) * 1e3)
            label = (" + radial velocities" if doppler else "") + (", screened (screen_radial)" if screen else "")
            lines.append(f"| {name}{label} | {np.median(runs):.1f} | "
                         f"{np.max(runs):.1f} |")
    lines += ["", "`OMP_NUM_THREADS=1 python benchmarks/tracking_speed.py` on this machine (2 CPU cores, shared with "
                  "other jobs while measured: the maxima especially are load-dependent)."]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(__file__).with_name("tracking_speed.md").write_text(text)


if __name__ == "__main__":
    main()
