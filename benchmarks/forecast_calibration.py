"""Calibrate the trackers' forecast intervals: the process noise of the constant-velocity
filter (``accel_psd``, kalman and sindy), and for sindy's identified models the forecast process noise
(``model_accel_psd``), the members' spread scale (``member_spread``) and the ensemble size (``n_models``).

Synthetic tracks (closed forms of :mod:`xnlos_core.motion`, the ranges of the sequence families in
sims/generators): cars at 5–15 m/s with a random heading, of three kinds —
* straight: constant velocity;
* turn: constant turn at a yaw rate of ±(0.1–0.4) rad/s (a cyclist's steering to a car's junction turn);
* brake: constant speed, then from t_b ~ U(0, 2.5) s braking at 2–6 m/s² (to a stop, hidden_car_approach).
Observed at 10 Hz for 4 s as one hidden point a frame: the true centre plus the object's extent wander
(white, 1 m per axis: which scatterers of the body are seen changes from frame to frame, KalmanParams.
extent_sigma) plus the reconstruction noise σ_p ~ U(0.3, 0.5) m per axis, which the point's covariance
states. Each tracker (default parameters, horizons 1, 2, 3 s) forecasts at t = 2.9 s and 3.9 s; a
forecast counts as covered at level p when |forecast − true centre| ≤ radius_p. A run that does not end
with exactly one confirmed track is counted as lost (and left out of the coverage).

Procedure (CALIBRATION seeds; the report is on different EVALUATION seeds):
1. accel_psd: kalman on all three kinds for each q of ``CV_GRID``. The calibration loss is
   L = Σ_h Σ_p (coverage_p(h) − p)² over h ∈ {1, 2, 3} s and p ∈ {0.5, 0.9} on the straight cars (CV is
   their right model, and sindy keeps CV for them; a turn or a braking breaks it, and the CV baseline
   is expected to under-cover those). But q is also the filter's: too small a q loses turning and
   braking cars (the gated association splits their track). On these tracks L falls monotonically as
   q → 0 (the straight cars have no acceleration at all), so the choice is the smallest q of the grid
   that keeps every car of every kind as one track (at most ``MAX_LOST`` of the forecasts lost).
2. sindy with that accel_psd, for each n_models of ``ENSEMBLES``: record every forecast's state (x, P)
   and motion model; for each (model_accel_psd, member_spread) of the grid recompute the forecast of
   the tracks that follow an identified model (forecast.py Eq. 1; the filter does not depend on these
   two) and choose the pair minimising L summed over the turn and brake kinds (pooled over kinds, a
   turn's need could hide a brake's). The smallest n_models whose best L is within 25 % of the overall
   best is chosen (an identification's cost grows with it).
3. Report: kalman and sindy with the chosen values on the EVALUATION seeds, per kind and horizon:
   coverage of the 50 % and 90 % discs, mean error, and sindy's 2 s error relative to kalman.

    OMP_NUM_THREADS=1 python benchmarks/forecast_calibration.py [--tracks 40]

Prints the chosen values and writes benchmarks/forecast_calibration.md.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from xnlos_core.motion import ConstantAcceleration, ConstantTurn, ConstantVelocity
from xnlos_core.types import HiddenPoints

KINDS = ("straight", "turn", "brake")
HORIZONS = (1.0, 2.0, 3.0)
LEVELS = (0.5, 0.9)
DT, FRAMES, EVAL_FRAMES = 0.1, 40, (29, 39)
EXTENT = 1.0  # [m] per axis, the centroid's wander over the body
CAL_SEED, EVAL_SEED = 1, 2
CV_GRID = (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 4.0)
MODEL_GRID = (0.1, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
SPREAD_GRID = (0.0, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0)
ENSEMBLES = (5, 10)
MAX_LOST = 0.01  # share of forecasts without exactly one track that accel_psd may cause


def car(kind: str, rng: np.random.Generator):
    """Positions (T, 2) [m] of the true centre at times t (T,) [s] of one random car of ``kind``."""
    speed, heading = rng.uniform(5, 15), rng.uniform(0, 2 * np.pi)
    start = rng.uniform(-20, 20, 2) + [30.0, 0.0]
    if kind == "straight":
        traj = ConstantVelocity(velocity=(speed * np.cos(heading), speed * np.sin(heading)))
        return lambda t: traj.state(t, start, heading).position
    if kind == "turn":
        traj = ConstantTurn(speed=speed, yaw_rate=rng.choice([-1, 1]) * rng.uniform(0.1, 0.4))
        return lambda t: traj.state(t, start, heading).position
    t_b, brake = rng.uniform(0, 2.5), ConstantAcceleration(speed=speed, acceleration=-rng.uniform(2, 6))
    u = np.array([np.cos(heading), np.sin(heading)])
    p_b = start + speed * t_b * u

    def positions(t):
        t = np.atleast_1d(np.asarray(t, np.float64))
        return np.where((t < t_b)[:, None], p_b + speed * (t - t_b)[:, None] * u,
                        brake.state(np.maximum(t - t_b, 0.0), p_b, heading).position)
    return positions


def observations(kind: str, rng: np.random.Generator):
    """(times (F,), measurements (F, 2), σ_p, truth function) of one car."""
    truth = car(kind, rng)
    t = np.arange(FRAMES) * DT
    sigma = rng.uniform(0.3, 0.5)
    z = truth(t) + EXTENT * rng.standard_normal((FRAMES, 2)) + sigma * rng.standard_normal((FRAMES, 2))
    return t, z, sigma, truth


def dataset(seed: int, tracks: int) -> dict:
    """{kind: [observations, …]} of ``tracks`` cars per kind, seeded by (seed, kind)."""
    return {kind: [observations(kind, rng) for rng in [np.random.default_rng([seed, i])] for _ in range(tracks)]
            for i, kind in enumerate(KINDS)}


def run(tracker, obs) -> list:
    """Feed one car to ``tracker``; per forecast frame a record (x, P, motion, truth (K, 2), forecast (K, 2),
    radius50 (K,), radius90 (K,), label), or None where the tracker does not hold exactly one track."""
    t, z, sigma, truth = obs
    tracker.reset()
    out = []
    for k in range(FRAMES):
        tracks = tracker.update(HiddenPoints(z[k][None], sigma ** 2 * np.eye(2)[None], [0], [0]), t[k])
        if k in EVAL_FRAMES:
            live = [tr for tr in tracker._tracks if tr.confirmed]
            if len(tracks) != 1 or len(live) != 1:
                out.append(None)
                continue
            tr = live[0]
            out.append((tr.x.copy(), tr.P.copy(), tracker._motion(tr), truth(t[k] + tracks.horizons),
                        tracks.forecast[0], tracks.radius50[0], tracks.radius90[0], tracks.model[0]))
    return out


def records(tracker, data: dict) -> dict:
    return {kind: [r for obs in cars for r in run(tracker, obs)] for kind, cars in data.items()}


def covered(recs: list, q_cv: float | None = None, q_model: float | None = None, spread: float | None = None,
            models_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(hits (N, levels, K) bool, errors (N, K) [m]) of the kept records; with q_cv/q_model/spread given,
    the forecast is recomputed with them (forecast.py Eq. 1), else the tracker's own is used."""
    from estimators.trackers import forecast as fc

    hits, errs = [], []
    for r in recs:
        if r is None or (models_only and r[2].is_cv):
            continue
        x, P, motion, truth, mean, r50, r90, _ = r
        if q_cv is not None:
            mean, cov = fc.forecast(motion, x, P, HORIZONS, q_cv if motion.is_cv else q_model, spread)
            r50, r90 = fc.radii(cov)
        e = np.linalg.norm(mean - truth, axis=1)
        hits.append([e <= r50, e <= r90]), errs.append(e)
    return np.array(hits).reshape(-1, len(LEVELS), len(HORIZONS)), np.array(errs).reshape(-1, len(HORIZONS))


def loss(hits: np.ndarray) -> float:
    """L = Σ_h Σ_p (coverage_p(h) − p)² (module docstring); inf without records."""
    if len(hits) == 0:
        return np.inf
    return float(np.sum((hits.mean(axis=0) - np.array(LEVELS)[:, None]) ** 2))


def calibrate(tracks: int, log=print) -> dict:
    from estimators.trackers.kalman import KalmanTracker
    from estimators.trackers.sindy import SindyTracker

    cal = dataset(CAL_SEED, tracks)
    h = list(HORIZONS)
    cv_loss, robust = {}, []
    for q in CV_GRID:
        recs = records(KalmanTracker({"accel_psd": q, "horizons": h}), cal)
        hits, _ = covered(recs["straight"])
        lost = {k: np.mean([r is None for r in recs[k]]) for k in KINDS}
        cv_loss[q] = loss(hits)
        if max(lost.values()) <= MAX_LOST:
            robust.append(q)
        log(f"accel_psd {q:5.2f}: straight coverage 50 % {hits[:, 0].mean():.2f}, 90 % {hits[:, 1].mean():.2f}, "
            f"L = {cv_loss[q]:.4f}; lost " + ", ".join(f"{k} {v:.2f}" for k, v in lost.items()))
    q_cv = min(robust, key=cv_loss.get) if robust else max(CV_GRID)
    best = {}
    for n in ENSEMBLES:
        recs = records(SindyTracker({"accel_psd": q_cv, "n_models": n, "horizons": h}), cal)
        grid = {(qm, s): sum(loss(covered(recs[k], q_cv, qm, s, models_only=True)[0]) for k in ("turn", "brake"))
                for qm in MODEL_GRID for s in SPREAD_GRID}
        (qm, s) = min(grid, key=grid.get)
        best[n] = (grid[(qm, s)], qm, s)
        n_model = {k: sum(r is not None and not r[2].is_cv for r in recs[k]) for k in KINDS}
        log(f"n_models {n}: model_accel_psd {qm}, member_spread {s}, L = {grid[(qm, s)]:.4f} "
            f"(forecasts with a model: {n_model})")
    top = min(v[0] for v in best.values())
    n = min(k for k, v in best.items() if v[0] <= 1.25 * top)
    return {"accel_psd": q_cv, "n_models": n, "model_accel_psd": best[n][1], "member_spread": best[n][2]}


def report(chosen: dict, tracks: int) -> list[str]:
    from estimators.trackers.kalman import KalmanTracker
    from estimators.trackers.sindy import SindyTracker

    data = dataset(EVAL_SEED, tracks)
    h = list(HORIZONS)
    res = {"kalman": records(KalmanTracker({"accel_psd": chosen["accel_psd"], "horizons": h}), data),
           "sindy": records(SindyTracker({**chosen, "horizons": h}), data)}
    lines = ["| tracker | kind | forecasts (lost) | with a model | " + " | ".join(
        f"{int(p * 100)} % cover {x:g} s" for p in LEVELS for x in HORIZONS) + " | " +
        " | ".join(f"mean error {x:g} s [m]" for x in HORIZONS) + " |", "|---" * (4 + 3 * len(HORIZONS)) + "|"]
    err2 = {}
    for name, only in (("kalman", False), ("sindy", False), ("sindy, forecasts with a model", True)):
        recs = res[name.split(",")[0]]
        for kind in KINDS:
            hits, errs = covered(recs[kind], models_only=only)
            if len(hits) == 0:
                continue
            lost = sum(r is None for r in recs[kind])
            models = sum(r is not None and not r[2].is_cv for r in recs[kind])
            cov = hits.mean(axis=0)
            err2[name, kind] = errs[:, 1].mean()
            lines.append(f"| {name} | {kind} | {len(hits)} ({lost}) | {models} | "
                         + " | ".join(f"{c:.2f}" for c in cov.ravel()) + " | "
                         + " | ".join(f"{e:.2f}" for e in errs.mean(axis=0)) + " |")
    lines += ["", "sindy / kalman mean error 2 s ahead: " + ", ".join(
        f"{k} {err2['sindy', k] / err2['kalman', k]:.2f}" for k in KINDS)]
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tracks", type=int, default=40, help="cars per kind and seed set")
    a = ap.parse_args()
    t0 = time.perf_counter()
    log = []

    def say(msg):
        print(msg, flush=True)
        log.append(msg)
    chosen = calibrate(a.tracks, say)
    say(f"chosen: {chosen}")
    table = report(chosen, a.tracks)
    text = "\n".join([f"# Forecast calibration ({a.tracks} cars per kind, 10 Hz, 4 s observed, forecasts at "
                      "t = 2.9 s and 3.9 s)", "", "Calibration (seeds 1):", "", "```", *log, "```", "",
                      "Evaluation (seeds 2), the chosen values:", "", *table, "",
                      f"`OMP_NUM_THREADS=1 python benchmarks/forecast_calibration.py --tracks {a.tracks}` "
                      f"({time.perf_counter() - t0:.0f} s)"]) + "\n"
    print("\n".join(table))
    Path(__file__).with_name("forecast_calibration.md").write_text(text)


if __name__ == "__main__":
    main()
