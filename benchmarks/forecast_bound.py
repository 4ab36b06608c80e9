"""How far a better motion model could take the 2 s forecast of hidden cars: the tracker's forecast
and constant velocity (CV) against the *true* manoeuvre applied to the same track states.

Runs one case of ``configs/ablations/tracking.toml`` (default: "oracle → sindy + Doppler") on the
``hidden_car_approach`` sequences of a dataset split, and matches each confirmed track to the nearest
mirror-visible car within ``match_radius`` per frame (frame by frame, not CLEAR-MOT's one-to-one
matching that keeps identities: the forecast counts differ from ``xnlos eval``'s). For every match with
the car's truth 2 s ahead:

* CV: p̂ + 2 v̂ from the track state (p̂, v̂); tracker: its own 2 s forecast;
* true Ξ: the track state integrated 2 s under the car's true manoeuvre at that instant in sindy's
  model, dv/dt = βv̂ + ωJv with β = aᵀv̂, ω = aᵀJv/|v|² (a the true acceleration, central difference of
  the true velocities), a braking one up to its stop — the forecast of a perfect identification from
  the same state (the scenes' braking and turning cars follow this model exactly). Its ratio to CV is
  what a motion model can gain on these tracks;
* the state errors: position, velocity, and the velocity error along the car's heading by track age
  (frames since the track's birth), and the speed of the hidden points' centroid (points within
  ``centroid_radius`` of the car) against the car's speed;
* how often the moving, mirror-visible cars are detected (a hidden point within ``centroid_radius``)
  and tracked (a track within ``match_radius``), pooled over frames and per car: a car the detector
  misses leaves only short, young tracks, whose forecasts stay CV;
* for a ``sindy`` tracker, where its forecasts of each motion come from: the matched track's state
  when it forecast (from :meth:`Tracker.state`: its samples in the window and the evidence of its last
  identification) — following a model; CV because it has fewer than ``min_samples`` samples; CV with
  evidence below its bar (``min_evidence``, or ``braking_evidence`` for braking alone); CV otherwise (not yet identified, nothing identified, slower than
  ``min_speed``, or a model outside the road users' envelope, ``max_speedup`` / ``max_lateral``) — with
  each group's share of CV's error and its ratios.

Writes benchmarks/forecast_bound.md.

    python benchmarks/forecast_bound.py [--dataset out/data/sequences_large64] [--split test] [--case 6]
"""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from tracking_case import case_parser, family_sequences

from estimators.trackers.sindy import SindyParams, evidence_bar
from estimators.trackers.sindy_model import GENERATORS, path_under

FAMILY = "hidden_car_approach"
AGES = ((0, 5), (5, 10), (10, 20), (20, 40), (40, 10_000))


def run(config: str, case: int, dataset: str, split: str):
    """[(case name, per sequence: [frame dicts])] of the hidden-car sequences of the split."""
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline

    r = plan_runs(config, dataset=dataset, split=split)[case]
    pipe = Pipeline(r["config"], source=r["source"])
    tracker = pipe.stages["tracker"]
    seqs = [[_record(f, pipe.process(f), tracker) for f in frames] for frames in family_sequences(pipe, FAMILY)]
    return r["name"], seqs, r["config"].run.match_radius, _sindy_params(tracker)


def _sindy_params(tracker) -> SindyParams | None:
    """The SindyParams of a sindy tracker (its min_samples and evidence bars), None for another."""
    return tracker.params if isinstance(tracker.params, SindyParams) else None


def _identification(tracker) -> dict:
    """{track id: (samples in its window, evidence of its last identification or None)} of a sindy
    tracker, from its checkpoint (:meth:`Tracker.state`); {} for another tracker."""
    if _sindy_params(tracker) is None:
        return {}
    out = {}
    for d in tracker.state()["tracks"]:
        ident = d.get("identified")
        out[int(d["id"])] = (len(d.get("history", [])), None if ident is None else float(ident["evidence"]),
                             None if ident is None else ident["rates"])
    return out


def _record(f, res, tracker) -> dict:
    """What :func:`score` needs of one processed map."""
    ot, tr = f.meta["object_truth"], res.tracks
    truth = zip(ot["id"], ot["position"], ot["velocity"], ot["mirror"], ot["motion"])
    return {"t": f.timestamp, "ids": np.asarray(tr.track_id), "pos": np.asarray(tr.position),
            "vel": np.asarray(tr.velocity), "hz": tr.horizons, "fc": tr.forecast, "points": np.asarray(res.hidden.mean),
            "model": tuple(tr.model), "ident": _identification(tracker),
            "truth": {int(i): (np.asarray(p, float), np.asarray(v, float), bool(m), str(k)) for i, p, v, m, k in truth}}


GROUPS = ("follows a model", "CV: fewer than min_samples samples", "CV: evidence below its bar", "CV: otherwise")


def _group(f: dict, j: int, params: SindyParams) -> str:
    """Which of GROUPS track j of map f was in when it forecast (module docstring)."""
    if f["model"][j] != "cv":
        return GROUPS[0]
    n, evidence, rates = f["ident"].get(int(f["ids"][j]), (0, None, None))
    if n < params.min_samples:
        return GROUPS[1]
    if evidence is not None and evidence < evidence_bar(rates, params):
        return GROUPS[2]
    return GROUPS[3]


def _near(f: dict, p: np.ndarray, radius: float) -> np.ndarray:
    """Mask (N,) of map f's hidden points within ``radius`` [m] of the position p (2,)."""
    return np.linalg.norm(f["points"] - p, axis=1) < radius if len(f["points"]) else np.zeros(0, bool)


def _centroid(f: dict, i: int, radius: float) -> np.ndarray | None:
    """Centroid (2,) [m] of the hidden points within ``radius`` of object i's centre (None: < 2 points)."""
    if i not in f["truth"]:
        return None
    near = _near(f, f["truth"][i][0], radius)
    return f["points"][near].mean(0) if np.count_nonzero(near) >= 2 else None


def _true_manoeuvre(s: list, times: np.ndarray, k: int, i: int, v: np.ndarray) -> np.ndarray | None:
    """(β [m/s²], ω [rad/s]) of object i at frame k from its true acceleration a (central difference of
    the true velocities): β = aᵀv̂, ω = aᵀJv/|v|² — sindy's model (dv/dt = βv̂ + ωJv), None at a
    sequence's ends."""
    nb = [q for q in (k - 1, k + 1) if 0 <= q < len(s) and i in s[q]["truth"]]
    if len(nb) < 2:
        return None
    a = (s[nb[1]]["truth"][i][1] - s[nb[0]]["truth"][i][1]) / (times[nb[1]] - times[nb[0]])
    return np.array([a @ v / np.linalg.norm(v), a @ (GENERATORS[1] @ v) / (v @ v)])


def score(seqs, radius: float, params: SindyParams | None = None, centroid_radius: float = 3.5,
          horizon: float = 2.0) -> dict:
    """Per motion kind: lists of the quantities of the module docstring (``params``: a sindy
    tracker's SindyParams, for the grouping)."""
    out = defaultdict(lambda: defaultdict(list))
    for si, s in enumerate(seqs):
        times, born = np.array([f["t"] for f in s]), {}
        for k, f in enumerate(s):
            for tid in f["ids"]:
                born.setdefault(int(tid), k)
            jf = int(np.argmin(np.abs(times - (times[k] + horizon))))
            reaches = abs(times[jf] - times[k] - horizon) <= 0.05
            for i, (p, v, seen, kind) in f["truth"].items():
                speed = np.linalg.norm(v)
                if not seen or speed < 0.5:
                    continue
                o = out[kind]
                c, c_prev = _centroid(f, i, centroid_radius), _centroid(s[k - 1], i, centroid_radius) if k else None
                if c is not None and c_prev is not None:
                    o["centroid_deficit"].append((c - c_prev) @ v / speed / (f["t"] - s[k - 1]["t"]) - speed)
                d = np.linalg.norm(f["pos"] - p, axis=1) if len(f["ids"]) else np.array([np.inf])
                j = int(d.argmin())
                o["seen"].append((si, i, bool(_near(f, p, centroid_radius).any()), bool(d[j] <= radius)))
                if d[j] > radius:
                    continue
                tp, tv = f["pos"][j], f["vel"][j]
                o["pos_err"].append(d[j])
                o["vel_err"].append(np.linalg.norm(tv - v))
                o["along"].append(((tv - v) @ v / speed, k - born[int(f["ids"][j])]))
                truth = _true_manoeuvre(s, times, k, i, v)
                if truth is None or not reaches or i not in s[jf]["truth"]:
                    continue
                future = s[jf]["truth"][i][0]
                o["cv"].append(np.linalg.norm(tp + horizon * tv - future))
                o["true_xi"].append(np.linalg.norm(path_under(truth, tp, tv, [horizon])[0] - future))
                if f["fc"] is not None and len(f["hz"]):
                    h = int(np.argmin(np.abs(np.asarray(f["hz"]) - horizon)))
                    o["tracker"].append(np.linalg.norm(f["fc"][j, h] - future))
                    if params is not None:
                        o["groups"].append((_group(f, j, params), o["cv"][-1], o["tracker"][-1], o["true_xi"][-1]))
    return out


def _groups_table(out: dict, kinds: list[str]) -> list[str]:
    """The 'where the forecasts come from' table (module docstring), [] without groups."""
    if not any(out[k]["groups"] for k in kinds):
        return []
    lines = ["", "Where the tracker's forecasts come from: the matched track when it forecast (share: of CV's "
             "summed error over that motion's forecasts):", "",
             "| motion | track | forecasts | share of CV's error | tracker / CV | true Ξ / CV |", "|---|---|---|---|---|---|"]
    for k in kinds:
        g = out[k]["groups"]
        total = sum(row[1] for row in g)
        for name in GROUPS:
            rows = np.array([row[1:] for row in g if row[0] == name])
            if len(rows):
                cv, trk, tx = rows.sum(0)
                lines.append(f"| {k} | {name} | {len(rows)} | {cv / total:.2f} | {trk / cv:.2f} | {tx / cv:.2f} |")
    return lines


def _detection_table(out: dict, kinds: list[str]) -> list[str]:
    """Per motion: of the frames where a car moves (≥ 0.5 m/s) mirror-visible, the share with a hidden
    point within ``centroid_radius`` of it (detected) and with a track within ``match_radius`` (tracked),
    pooled and per car (median, and cars detected in fewer than 30 % of their frames)."""
    lines = ["", "Moving, mirror-visible cars: share of their frames with a hidden point within 3.5 m (detected) and "
             "with a track within the match radius (tracked):", "",
             "| motion | cars | frames | detected | tracked | detected, median car | cars detected < 30 % |",
             "|---|---|---|---|---|---|---|"]
    for k in kinds:
        rows = out[k]["seen"]
        cars = defaultdict(list)
        for seq, i, near, tracked in rows:
            cars[(seq, i)].append(near)
        per_car = np.array([np.mean(v) for v in cars.values()])
        det, trk = np.mean([r[2] for r in rows]), np.mean([r[3] for r in rows])
        lines.append(f"| {k} | {len(cars)} | {len(rows)} | {det:.2f} | {trk:.2f} | {np.median(per_car):.2f} | "
                     f"{int(np.sum(per_car < 0.3))} |")
    return lines


def report(name: str, out: dict, cmd: str, seconds: float, n_seq: int) -> str:
    kinds = [k for k in ("straight", "turning", "braking") if k in out]
    lines = [f"# Forecast bound: hidden cars, 2 s ahead ({name}, {n_seq} sequences)", "",
             "Ratios are to CV from the same track states; 'true Ξ': the car's true manoeuvre applied to "
             "those states (the most a motion model can gain on them). Errors [m], velocities [m/s]. Each track is "
             "matched to the nearest visible car frame by frame (not `xnlos eval`'s CLEAR-MOT matching: other "
             "forecast counts).", "",
             "| motion | forecasts | CV FDE@2s | tracker FDE@2s | tracker / CV | true Ξ FDE@2s | true Ξ / CV | "
             "position error | velocity error | centroid speed − car speed (median) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for k in kinds:
        o = out[k]
        cv, tx, trk = np.mean(o["cv"]), np.mean(o["true_xi"]), np.mean(o["tracker"]) if o["tracker"] else np.nan
        lines.append(f"| {k} | {len(o['cv'])} | {cv:.2f} | {trk:.2f} | {trk / cv:.2f} | {tx:.2f} | {tx / cv:.2f} | "
                     f"{np.mean(o['pos_err']):.2f} | {np.mean(o['vel_err']):.2f} | "
                     f"{np.median(o['centroid_deficit']):+.2f} |")
    pooled = [out[k] for k in ("turning", "braking") if k in out]
    if pooled:
        cv = np.concatenate([o["cv"] for o in pooled]).mean()
        tx = np.concatenate([o["true_xi"] for o in pooled]).mean()
        trk = np.concatenate([o["tracker"] for o in pooled]).mean()
        lines += ["", f"Turning and braking pooled: tracker / CV {trk / cv:.2f}, true Ξ / CV {tx / cv:.2f}."]
    lines += ["", "Velocity error along the car's heading [m/s] (mean ± SD) by track age [frames]:", "",
              "| motion | " + " | ".join(f"{lo}–{hi if hi < 10_000 else '…'}" for lo, hi in AGES) + " |",
              "|---|" + "---|" * len(AGES)]
    for k in kinds:
        al = np.array(out[k]["along"])
        cells = []
        for lo, hi in AGES:
            sel = al[(al[:, 1] >= lo) & (al[:, 1] < hi), 0]
            cells.append(f"{sel.mean():+.2f} ± {sel.std():.2f} ({len(sel)})" if len(sel) else "–")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += _detection_table(out, kinds)
    lines += _groups_table(out, kinds)
    lines += ["", f"`{cmd}` ({seconds:.0f} s)"]
    return "\n".join(lines) + "\n"


def main():
    ap = case_parser(__doc__, case=6, split="test")
    ap.add_argument("--out", default=str(Path(__file__).with_name("forecast_bound.md")))
    a = ap.parse_args()
    t0 = time.perf_counter()
    name, seqs, radius, params = run(a.config, a.case, a.dataset, a.split)
    cmd = f"python benchmarks/forecast_bound.py --dataset {a.dataset} --split {a.split} --case {a.case}"
    text = report(name, score(seqs, radius, params), cmd, time.perf_counter() - t0, len(seqs))
    print(text)
    Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
