"""2 s-ahead forecasts of the sindy tracker on kinematic-bicycle manoeuvres, against a least-squares
constant-velocity line over the last 1 s and the Kalman tracker, with 1, 10 and 50 tracks at once.

Independent truth: the trajectories come from a kinematic bicycle written here (no code shared with
sims/, xnlos_core.motion or the scene generators): state (x, y, ψ, v) [m, m, rad, m/s], wheelbase
``WHEELBASE`` = 2.7 m, dx/dt = v cos ψ, dy/dt = v sin ψ, dψ/dt = v tan(δ)/L, dv/dt = a, integrated by
RK4 at 100 Hz from the steering δ(t) and acceleration a(t) of each class:

* straight: 5–15 m/s, δ = a = 0.
* turn: 6–11 m/s, a yaw rate of 0.2–0.45 rad/s (lateral acceleration ≤ 4 m/s²) reached by a 1 s
  steering ramp, held for a 90° turn, then ramped back.
* brake: 8–14 m/s, −2 to −4 m/s² to a standstill (the car then stays).
* accelerate: 3–8 m/s, +1 to +2.5 m/s² for 5 s.
* lane_change: 8–14 m/s, a lateral offset of ±(3.0–3.7) m in 3.5–5 s: the heading follows
  ψ₀ + Ψ sin²(π s/T) (δ from its rate), Ψ = 2W/(vT).
* reversing: 2–5 m/s forward, −1.5 to −3 m/s² through zero to −(1.5–3) m/s, then that speed backwards.

Each car starts at a random heading; its manoeuvre starts at 4.5–5.5 s; it is observed for 12 s at
10 Hz as one hidden point with isotropic noise σ ∈ [0.3, 0.5] m (its own, drawn per car; the points'
covariance says σ). Forecast origins every 0.5 s from 3 s to 10 s (15 per car). "During the manoeuvre":
origins from 1 s after its start (the track has seen it) to its end (turn: the held yaw rate; brake:
the stop; accelerate: the 5 s; lane change: T; reversing: reaching the reverse speed).

Simultaneous tracks: with N > 1 the cars are fed N at a time to one tracker (500 m apart, so that
association is trivial), groups filled up with extra seeded cars not scored; the per-frame tracker
time is the median wall time of ``update`` over the frames after the first 3 s.

Rows per class: mean 2 s error of sindy, of the CV line and of kalman; the ratios; 90 % disc coverage
over all origins and during the manoeuvre (sindy; kalman for reference); the share of straight
forecasts given a non-CV model; the same at 50 tracks with ``max_fits_per_frame = 1``. The speed section
times the sindy tracker at 10 and 50 tracks with the
machine as it is ("quiet") and with two CPU-bound processes started by the benchmark ("busy").

    OMP_NUM_THREADS=1 python benchmarks/bicycle_forecasts.py            # small: 12 cars per class
    OMP_NUM_THREADS=1 python benchmarks/bicycle_forecasts.py --full     # 60 cars per class (900 forecasts)
    OMP_NUM_THREADS=1 python benchmarks/bicycle_forecasts.py --calibrate  # per-model disc factors, seed 1

``--calibrate`` runs one track at a time on the calibration split (seed 1; the results use seed 0) and
prints the split-conformal factor per model key (``LibraryFit.interval_key``): the ⌈0.9(n + 1)⌉-th
smallest of error / (unscaled 90 % radius) over that key's forecasts in the phases the intervals are
for — the manoeuvring classes during their manoeuvre; a key seen fewer than 9 times there adds the
straight cars' forecasts (Vovk et al. 2005; Lei et al. 2018) — stored as ``INTERVAL_FACTORS`` in
estimators/trackers/sindy.py. A straight car's CV forecast is far more accurate than a CV forecast
during a manoeuvre that the window does not show yet, and nothing in the window tells them apart
(neither the CV's BIC weight nor its residuals' autocorrelation): one factor covers both, so straight
cars' discs are wider than 90 % needs. Forecasts whose 2 s straddle a
manoeuvre's onset or end are not calibrated for: nothing in the track's past announces them.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CLASSES = ("straight", "turn", "brake", "accelerate", "lane_change", "reversing")
DT, DURATION, WHEELBASE, SUBSTEPS = 0.1, 12.0, 2.7, 10
ORIGINS = np.arange(30, 101, 5)              # frame indices of the forecast origins (3 s … 10 s)
HORIZON = 2.0                                # [s]
SPACING = 500.0                              # [m] between simultaneous cars
TARGET_MS = {10: 10.0, 50: 50.0}             # per-frame tracker time targets [ms]


def _rk4(s: np.ndarray, delta: float, accel: float, h: float) -> np.ndarray:
    """One RK4 step h [s] of the bicycle (module docstring) with the controls held."""
    def f(x):
        return np.array([x[3] * np.cos(x[2]), x[3] * np.sin(x[2]), x[3] * np.tan(delta) / WHEELBASE, accel])
    k1 = f(s)
    k2 = f(s + h / 2 * k1)
    k3 = f(s + h / 2 * k2)
    k4 = f(s + h * k3)
    return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def bicycle(controls, state0) -> np.ndarray:
    """Positions (n, 2) [m] at t = k·DT, k ≤ DURATION/DT, of the bicycle driven by ``controls(t, state)``
    → (δ [rad], a [m/s²]) held over each 10 ms substep (RK4 within it)."""
    n = int(round(DURATION / DT)) + 1
    h = DT / SUBSTEPS
    s = np.array(state0, dtype=np.float64)
    out = np.empty((n, 2))
    t = 0.0
    for k in range(n):
        out[k] = s[:2]
        for _ in range(SUBSTEPS):
            s = _rk4(s, *controls(t, s), h)
            t += h
    return out


def car(cls: str, rng: np.random.Generator):
    """(truth (n, 2) [m], manoeuvre phase (start, end) [s] of the scoring, noise σ [m]) of one car."""
    heading = rng.uniform(0, 2 * np.pi)
    t0 = rng.uniform(4.5, 5.5)
    sigma = rng.uniform(0.3, 0.5)
    if cls == "straight":
        v = rng.uniform(5, 15)
        return bicycle(lambda t, s: (0.0, 0.0), (0, 0, heading, v)), (np.inf, np.inf), sigma
    if cls == "turn":
        v = rng.uniform(6, 11)
        omega = min(rng.uniform(0.2, 0.45), 4.0 / v) * rng.choice([-1, 1])
        delta = np.arctan(WHEELBASE * omega / v)
        hold = (np.pi / 2) / abs(omega)

        def ctl(t, s):
            ramp = np.clip(t - t0, 0, 1) - np.clip(t - (t0 + 1 + hold), 0, 1)
            return delta * ramp, 0.0
        return bicycle(ctl, (0, 0, heading, v)), (t0 + 1.0, t0 + 1 + hold), sigma
    if cls == "brake":
        v, a = rng.uniform(8, 14), -rng.uniform(2, 4)
        return (bicycle(lambda t, s: (0.0, a if (t >= t0 and s[3] > 0) else 0.0), (0, 0, heading, v)),
                (t0 + 1.0, t0 + v / -a), sigma)
    if cls == "accelerate":
        v, a = rng.uniform(3, 8), rng.uniform(1, 2.5)
        return (bicycle(lambda t, s: (0.0, a if t0 <= t < t0 + 5 else 0.0), (0, 0, heading, v)),
                (t0 + 1.0, t0 + 5.0), sigma)
    if cls == "lane_change":
        v, width, T = rng.uniform(8, 14), rng.uniform(3.0, 3.7) * rng.choice([-1, 1]), rng.uniform(3.5, 5.0)
        big_psi = 2 * width / (v * T)

        def ctl(t, s):
            if not t0 <= t < t0 + T:
                return 0.0, 0.0
            rate = big_psi * np.pi / T * np.sin(2 * np.pi * (t - t0) / T)   # d/dt Ψ sin²(π s/T)
            return np.arctan(WHEELBASE * rate / s[3]), 0.0
        return bicycle(ctl, (0, 0, heading, v)), (t0 + 1.0, t0 + T), sigma
    v, a, vr = rng.uniform(2, 5), -rng.uniform(1.5, 3), -rng.uniform(1.5, 3)
    return (bicycle(lambda t, s: (0.0, a if (t >= t0 and s[3] > vr) else 0.0), (0, 0, heading, v)),
            (t0 + 1.0, t0 + (v - vr) / -a), sigma)


def cars(per_class: int, seed: int):
    """[(class, truth, phase, σ, noisy (n, 2))] of ``per_class`` seeded cars per class."""
    out = []
    for c, cls in enumerate(CLASSES):
        rng = np.random.default_rng([seed, c])
        for _ in range(per_class):
            truth, phase, sigma = car(cls, rng)
            out.append((cls, truth, phase, sigma, truth + sigma * rng.standard_normal(truth.shape)))
    return out


def cv_line(noisy: np.ndarray, k: int, horizon: float = HORIZON) -> np.ndarray:
    """Position [m] ``horizon`` ahead of frame k from the least-squares line over the last 1 s (11 samples)."""
    t = np.arange(k - 10, k + 1) * DT
    coef = np.polyfit(t - t[-1], noisy[k - 10:k + 1], 1)
    return coef[1] + coef[0] * horizon


def run_group(tracker, group, timing: list | None = None) -> dict:
    """Feed the cars ``group`` [(…, truth, …, σ, noisy)] together; return {car index: {origin k: (forecast
    (2,), radius90, label)}} of the track nearest each car at the origins (None: no track within 5 m)."""
    from xnlos_core.types import HiddenPoints

    tracker.reset()
    n = len(group[0][1])
    offsets = np.array([[SPACING * (i % 10), SPACING * (i // 10)] for i in range(len(group))])
    sig = np.array([g[3] for g in group])
    cov = sig[:, None, None] ** 2 * np.eye(2)
    res = {i: {} for i in range(len(group))}
    zeros = np.zeros(len(group), np.int64)
    for k in range(n):
        z = np.array([g[4][k] for g in group]) + offsets
        t0 = time.perf_counter()
        out = tracker.update(HiddenPoints(z, cov, zeros, zeros), k * DT)
        if timing is not None and k >= 30:
            timing.append(time.perf_counter() - t0)
        if k not in ORIGINS:
            continue
        j = int(np.argmin(np.abs(out.horizons - HORIZON)))
        for i, g in enumerate(group):
            if len(out) == 0:
                res[i][k] = None
                continue
            d = np.linalg.norm(out.position - (g[1][k] + offsets[i]), axis=1)
            m = int(np.argmin(d))
            key = out.model[m]
            fit = getattr(tracker, "_tracks", None)
            if fit is not None:
                tr = next((x for x in tracker._tracks if x.id == out.track_id[m]), None)
                if tr is not None and hasattr(tr, "library"):
                    key = "unfitted" if tr.library is None else tr.library.interval_key
            res[i][k] = None if d[m] > 5.0 else (out.forecast[m, j] - offsets[i], float(out.radius90[m, j]),
                                                 out.model[m], key)
    return res


def evaluate(per_class: int, seed: int, sizes=(1, 10, 50), params: dict | None = None) -> dict:
    """{N: {"rows": [per-forecast records], "ms": median sindy ms/frame}} over the cars of :func:`cars`."""
    from estimators.trackers.kalman import KalmanTracker
    from estimators.trackers.sindy import SindyTracker

    pool = cars(per_class, seed)
    filler_rng = np.random.default_rng([seed, 99])
    out = {}
    for N in sizes:
        rows, timing = [], []
        order = np.random.default_rng([seed, N]).permutation(len(pool))
        for g0 in range(0, len(pool), N):
            idx = list(order[g0:g0 + N])
            group = [pool[i] for i in idx]
            while len(group) < N:                      # fill up with unscored cars
                cls = CLASSES[filler_rng.integers(len(CLASSES))]
                truth, phase, sigma = car(cls, filler_rng)
                group.append((cls, truth, phase, sigma, truth + sigma * filler_rng.standard_normal(truth.shape)))
            s = run_group(SindyTracker(params or {}), group, timing)
            kf = run_group(KalmanTracker(), group)
            for i, ci in enumerate(idx):
                cls, truth, phase, sigma, noisy = pool[ci]
                for k in ORIGINS:
                    future = truth[k + int(round(HORIZON / DT))]
                    t = k * DT
                    rec = {"cls": cls, "during": phase[0] <= t <= phase[1],
                           "cv": float(np.linalg.norm(cv_line(noisy, k) - future))}
                    for name, r in (("sindy", s[i][k]), ("kalman", kf[i][k])):
                        if r is None:
                            rec.update({name: np.nan, name + "_r90": np.nan, name + "_label": "lost",
                                        name + "_key": "lost"})
                        else:
                            rec[name] = float(np.linalg.norm(r[0] - future))
                            rec[name + "_r90"], rec[name + "_label"], rec[name + "_key"] = r[1], r[2], r[3]
                    rows.append(rec)
        out[N] = {"rows": rows, "ms": 1e3 * float(np.median(timing))}
    return out


def summary(rows: list, cls: str) -> dict:
    """Means, ratios, coverages of one class's records."""
    r = [x for x in rows if x["cls"] == cls]
    d = [x for x in r if x["during"]]

    def mean(rs, key):
        return float(np.nanmean([x[key] for x in rs])) if rs else np.nan

    def cover(rs, name):
        ok = [x[name] <= x[name + "_r90"] for x in rs if np.isfinite(x[name])]
        return float(np.mean(ok)) if ok else np.nan

    return {"n": len(r), "n_during": len(d), "sindy": mean(r, "sindy"), "cv": mean(r, "cv"), "kalman": mean(r, "kalman"),
            "sindy_d": mean(d, "sindy"), "cv_d": mean(d, "cv"), "kalman_d": mean(d, "kalman"),
            "cover": cover(r, "sindy"), "cover_d": cover(d, "sindy"), "kcover_d": cover(d, "kalman"),
            "non_cv": float(np.mean([x["sindy_label"] not in ("cv", "lost") for x in r])) if r else np.nan,
            "lost": float(np.mean([x["sindy_label"] == "lost" for x in r])) if r else np.nan}


def _busy(n: int) -> list:
    """Start ``n`` CPU-bound processes (ended by :func:`_stop` by their ids)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _stop(procs: list) -> None:
    for p in procs:
        p.kill()
        p.wait()


def speed(per_size_frames: int = 80, seed: int = 5) -> dict:
    """Median sindy ms/frame at 10 and 50 tracks, {(N, "quiet"|"busy"): ms}."""
    from estimators.trackers.sindy import SindyTracker

    rng = np.random.default_rng(seed)
    out = {}
    for N in (10, 50):
        group = []
        for i in range(N):
            cls = CLASSES[i % len(CLASSES)]
            truth, phase, sigma = car(cls, rng)
            group.append((cls, truth, phase, sigma, truth + sigma * rng.standard_normal(truth.shape)))
        for mode in ("quiet", "busy"):
            procs = _busy(2) if mode == "busy" else []
            try:
                timing = []
                run_group(SindyTracker(), group, timing)
            finally:
                _stop(procs)
            out[(N, mode)] = 1e3 * float(np.median(timing))
    return out


def calibrate(per_class: int, seed: int = 1) -> dict:
    """Split-conformal factor per model label (module docstring) from one-at-a-time runs on ``seed``."""
    from estimators.trackers.sindy import SindyTracker

    factors = SindyTracker().params.interval_factors
    rows = [x for x in evaluate(per_class, seed, sizes=(1,))[1]["rows"] if x["during"] or x["cls"] == "straight"]
    out = {}
    for label in sorted({x["sindy_key"] for x in rows} - {"lost"}):
        def scores(rs):
            return np.sort([x["sindy"] / (x["sindy_r90"] / factors.get(label, 1.0)) for x in rs
                            if x["sindy_key"] == label and np.isfinite(x["sindy"])])
        s = scores([x for x in rows if x["cls"] != "straight"])
        if len(s) < 9:                                   # too few during manoeuvres: straight cars too
            s = scores(rows)
        q = min(int(np.ceil(0.9 * (len(s) + 1))), len(s)) - 1
        out[label] = (round(float(s[q]), 2), len(s))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="60 cars per class (900 forecasts), else 12")
    ap.add_argument("--calibrate", action="store_true", help="print the per-model disc factors (seed 1)")
    ap.add_argument("--per-class", type=int, default=None)
    a = ap.parse_args()
    per_class = a.per_class or (60 if a.full else 12)
    t0 = time.perf_counter()
    if a.calibrate:
        print(calibrate(per_class))
        return
    res = evaluate(per_class, seed=0)
    capped = evaluate(per_class, seed=0, sizes=(50,), params={"max_fits_per_frame": 1})[50]
    sp = speed()
    load = os.getloadavg()[0]
    lines = [f"# Kinematic-bicycle forecasts, 2 s ahead ({per_class} cars per class, {len(ORIGINS)} origins each, "
             "0.3–0.5 m noise, 10 Hz)", "",
             "Error ratios are of mean 2 s errors over all origins (during the manoeuvre in brackets); coverage of "
             "sindy's 90 % discs over all origins / during the manoeuvre (kalman's during the manoeuvre in brackets).",
             ""]
    for N, r in res.items():
        lines += [f"## {N} track{'s' if N > 1 else ''} at once (sindy {r['ms']:.1f} ms per frame, median)", "",
                  "| class | sindy error [m] | sindy / CV line | sindy / kalman | 90 % cover all / during (kalman) "
                  "| non-CV share | lost |", "|---|---|---|---|---|---|---|"]
        for cls in CLASSES:
            s = summary(r["rows"], cls)
            during = cls != "straight"
            rcv = f"{s['sindy'] / s['cv']:.2f}" + (f" ({s['sindy_d'] / s['cv_d']:.2f})" if during else "")
            rkf = f"{s['sindy'] / s['kalman']:.2f}" + (f" ({s['sindy_d'] / s['kalman_d']:.2f})" if during else "")
            cov = f"{s['cover']:.2f}" + (f" / {s['cover_d']:.2f} ({s['kcover_d']:.2f})" if during else "")
            lines.append(f"| {cls} | {s['sindy']:.2f} | {rcv} | {rkf} | {cov} | {s['non_cv']:.2f} | {s['lost']:.2f} |")
        lines.append("")
    lines += ["## 50 tracks at once with `max_fits_per_frame = 1` (the former default: each track refitted every "
              f"50 frames; sindy {capped['ms']:.1f} ms per frame, median)", "",
              "| class | sindy / CV line | sindy / kalman | 90 % cover all / during | non-CV share |",
              "|---|---|---|---|---|"]
    for cls in CLASSES:
        s = summary(capped["rows"], cls)
        d = cls != "straight"
        lines.append(f"| {cls} | {s['sindy'] / s['cv']:.2f}" + (f" ({s['sindy_d'] / s['cv_d']:.2f})" if d else "")
                     + f" | {s['sindy'] / s['kalman']:.2f}" + (f" ({s['sindy_d'] / s['kalman_d']:.2f})" if d else "")
                     + f" | {s['cover']:.2f}" + (f" / {s['cover_d']:.2f}" if d else "") + f" | {s['non_cv']:.2f} |")
    lines += ["", "## Tracker time per frame (sindy, median over frames 30–119)", "",
              "| tracks | quiet [ms] | quiet / target | busy (2 CPU-bound processes) [ms] | busy / target |",
              "|---|---|---|---|---|"]
    for N in (10, 50):
        q, b = sp[(N, "quiet")], sp[(N, "busy")]
        lines.append(f"| {N} | {q:.1f} | {q / TARGET_MS[N]:.2f} | {b:.1f} | {b / TARGET_MS[N]:.2f} |")
    lines += ["", f"`OMP_NUM_THREADS=1 python benchmarks/bicycle_forecasts.py{' --full' if a.full else ''}` "
                  f"({time.perf_counter() - t0:.0f} s; 2 CPU cores, 1-min load average {load:.1f} at the end: the "
                  "machine is shared, so \"quiet\" is as quiet as it was)"]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(__file__).with_name("bicycle_forecasts.md").write_text(text)


if __name__ == "__main__":
    main()
