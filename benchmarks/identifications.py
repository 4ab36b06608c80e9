"""What the sindy tracker's identifications of hidden cars see: their evidence by motion, counted with
the radial residuals' AR(1) share and in full, and the radial errors of the straight cars that pass
(not a test).

Runs one case of ``configs/ablations/tracking.toml`` (a ``sindy`` tracker with Doppler) on the
``hidden_car_approach`` sequences of a dataset split (``Pipeline.reset()`` at each sequence). Every time
a track is identified, its window — the (t, z, ĝ, y) the tracker fitted, read back from
:meth:`Tracker.state` — is identified again offline with ``radial_share`` "ar1" and "full"
(:func:`estimators.trackers.sindy_model.identify_motion`, the tracker's own settings otherwise). The
window's last sample is matched to the nearest car of that frame's truth (within ``--radius``, moving
≥ 1 m/s). Per motion kind:

* identifications, the evidence's median and the share ≥ the tracker's ``min_evidence``, under each
  radial share;
* braking cars: the fitted α along the path against the car's a/v at the window's end (the exponential
  e^{αt} fitted to a constant deceleration lags it);
* straight cars that reach ``min_evidence`` under "full": the largest ĝ step between successive radial
  samples [deg] and the range of y − ĝᵀv_true [m/s] (the radial error of a point mirrored through a
  wrong or misplaced relay wall).

    python benchmarks/identifications.py [--dataset out/data/sequences_large64] [--split train] [--case 6]
"""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from tracking_case import case_parser, family_sequences

from estimators.trackers.sindy_model import identify_motion

FAMILY = "hidden_car_approach"
SHARES = ("ar1", "full")


def _windows(tracker) -> list[tuple[np.ndarray, ...]]:
    """(t, z, ĝ, y) of every track the tracker identified in the frame it has just processed."""
    state = tracker.state()
    out = []
    for d in state["tracks"]:
        if d.get("fitted_frame") != state["frame"] - 1 or d.get("identified") is None:
            continue
        h = d["history"]
        out.append((np.array([e[0] for e in h]), np.array([e[1] for e in h]), np.array([e[3] for e in h]),
                    np.array([np.nan if e[4] is None else e[4] for e in h])))
    return out


def _truth(frame, prev, nxt, z, radius: float):
    """(kind, position, velocity, acceleration) of the car nearest z within radius, or None."""
    ot = frame.meta["object_truth"]
    pos = np.asarray(ot["position"], dtype=np.float64).reshape(-1, 2)
    if not len(pos):
        return None
    i = int(np.argmin(np.linalg.norm(pos - z, axis=1)))
    if np.linalg.norm(pos[i] - z) > radius:
        return None
    v = np.asarray(ot["velocity"][i], dtype=np.float64)
    oid = ot["id"][i]
    vs = [np.asarray(f.meta["object_truth"]["velocity"][list(f.meta["object_truth"]["id"]).index(oid)], np.float64)
          for f in (prev, nxt) if f is not None and oid in list(f.meta["object_truth"]["id"])]
    a = (vs[1] - vs[0]) / (nxt.timestamp - prev.timestamp) if len(vs) == 2 else None
    return str(ot["motion"][i]), pos[i], v, a


def collect(config: str, case: int, dataset: str, split: str, radius: float) -> tuple[str, float, list]:
    """(case name, min_evidence, [(kind, speed, true a/v, {share: (evidence, α)}, window, v_true)])."""
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline

    r = plan_runs(config, dataset=dataset, split=split)[case]
    pipe = Pipeline(r["config"], source=r["source"])
    tracker = pipe.stages["tracker"]
    p = tracker.params
    if not (hasattr(p, "min_evidence") and getattr(p, "use_doppler", False)):
        raise SystemExit(f"case {case} ({r['name']}) is not a sindy tracker with Doppler")
    rows = []
    for frames in family_sequences(pipe, FAMILY):
        for k, frame in enumerate(frames):
            pipe.process(frame)
            for t, z, g, y in _windows(tracker):
                truth = _truth(frame, frames[k - 1] if k else None, frames[k + 1] if k + 1 < len(frames) else None,
                               z[-1], radius)
                if truth is None or np.linalg.norm(truth[2]) < 1.0:
                    continue
                kind, _, v, a = truth
                fits = {}
                for share in SHARES:
                    m = identify_motion(t, z, None, direction=g, radial=y, n_models=p.n_models, seed=p.seed,
                                        radial_share=share)
                    u = v / np.linalg.norm(v)
                    fits[share] = (m.evidence, float(u @ m.coefficients @ u))
                true_alpha = None if a is None else float(a @ v / (v @ v))
                rows.append((kind, float(np.linalg.norm(v)), true_alpha, fits, (t, z, g, y), v))
    return r["name"], p.min_evidence, rows


def report(name: str, min_evidence: float, rows: list, cmd: str, seconds: float) -> str:
    lines = [f"# Identifications of hidden cars ({name})", "",
             f"Each identification's window identified again with the radial residuals' AR(1) share and in full; "
             f"evidence = BIC(CV) − BIC(model), the tracker's bar {min_evidence:g}. Cars moving ≥ 1 m/s.", "",
             "| motion | identifications | median evidence, ar1 | ≥ bar, ar1 | median evidence, full | ≥ bar, full |",
             "|---|---|---|---|---|---|"]
    by = defaultdict(list)
    for row in rows:
        by[row[0]].append(row)
    for kind in ("straight", "turning", "braking"):
        if kind not in by:
            continue
        ev = {s: np.array([r[3][s][0] for r in by[kind]]) for s in SHARES}
        lines.append(f"| {kind} | {len(by[kind])} | {np.median(ev['ar1']):.1f} | {np.mean(ev['ar1'] >= min_evidence):.2f} | "
                     f"{np.median(ev['full']):.1f} | {np.mean(ev['full'] >= min_evidence):.2f} |")
    braking = [r for r in by.get("braking", []) if r[2] is not None and r[3]["full"][0] >= min_evidence]
    if braking:
        fitted = np.array([r[3]["full"][1] for r in braking])
        true = np.array([r[2] for r in braking])
        lines += ["", f"Braking cars whose identification passes the bar under \"full\" ({len(braking)}): the fitted α "
                  f"along the path, median {np.median(fitted):+.2f} 1/s (quartiles {np.quantile(fitted, 0.25):+.2f}, "
                  f"{np.quantile(fitted, 0.75):+.2f}), against the car's a/v at the window's end, median "
                  f"{np.median(true):+.2f} 1/s ({np.quantile(true, 0.25):+.2f}, {np.quantile(true, 0.75):+.2f})."]
    passing = [r for r in by.get("straight", []) if r[3]["full"][0] >= min_evidence]
    if passing:
        lines += ["", "Straight cars that pass the bar under \"full\": the largest step of ĝ between successive "
                  "radial samples, and the radial error y − ĝᵀv_true over the window:", "",
                  "| speed [m/s] | evidence ar1 | evidence full | α [1/s] | largest ĝ step [deg] | y − ĝᵀv_true min … max [m/s] |",
                  "|---|---|---|---|---|---|"]
        for _, speed, _, fits, (t, z, g, y), v in passing:
            ok = np.isfinite(y)
            ang = np.unwrap(np.arctan2(g[ok, 1], g[ok, 0]))
            step = np.degrees(np.max(np.abs(np.diff(ang)))) if ok.sum() > 1 else 0.0
            err = y[ok] - g[ok] @ v
            lines.append(f"| {speed:.1f} | {fits['ar1'][0]:.1f} | {fits['full'][0]:.1f} | {fits['full'][1]:+.2f} | "
                         f"{step:.1f} | {err.min():+.2f} … {err.max():+.2f} |")
    lines += ["", f"`{cmd}` ({seconds:.0f} s)"]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = case_parser(__doc__, case=6, split="train")
    ap.add_argument("--radius", type=float, default=3.0, help="match radius [m] of a window's last sample to a car")
    ap.add_argument("--out", default=str(Path(__file__).with_name("identifications.md")))
    a = ap.parse_args()
    t0 = time.perf_counter()
    name, bar, rows = collect(a.config, a.case, a.dataset, a.split, a.radius)
    cmd = f"python benchmarks/identifications.py --dataset {a.dataset} --split {a.split} --case {a.case}"
    text = report(name, bar, rows, cmd, time.perf_counter() - t0)
    print(text)
    Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
