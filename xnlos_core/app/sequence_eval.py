"""``xnlos eval`` on sequence datasets: tracking and prediction metrics per sequence.

When the pipeline has a tracker, :func:`evaluate_sequences` reads the split's maps in order, groups
consecutive maps of one scene (``frame.meta["scene_index"]``) into a *sequence*, resets the pipeline at
each sequence start (:meth:`Pipeline.reset`: the tracks and a wall estimator's history) and runs the
frames through :meth:`Pipeline.process`. Truth is the per-map object truth of sequence datasets
(``frame.meta["object_truth"]``, :mod:`sims.dataset.truth`). Per sequence (:func:`score_sequence`,
match threshold ``run.match_radius`` [m]):

* MOTA, MOTP [m], IDF1 (:func:`xnlos_core.app.tracking_metrics.mot_matches`) of the tracks' positions
  against the road users' centres. A road user without a mirror path in a frame cannot be seen: it is
  left out of that frame's truth, and tracks within the threshold of it are ignored (neither matches
  nor false positives, the "don't care" rule of MOTChallenge), so a track coasting through a
  blind spot is not punished. Tracks within the threshold of a ground-truth hidden point of a static
  surface (a wall strip or parked object seen in a mirror: a true reflection, not a road user) are
  ignored likewise; ``counts.ignored`` counts the ignored track-frames.
* velocity RMSE [m/s] of the matched tracks' velocity against the road user's.
* prediction errors: every track matched at frame k (CLEAR-MOT matches) with forecast horizons h
  (``Tracks.horizons``; else :data:`DEFAULT_HORIZONS`) is scored against the road user's truth at
  t_k + h, where the sequence reaches it (a map within half a frame interval). ADE@h [m]: mean error
  over forecasts that reach h and their horizons ≤ h; FDE@h [m]: mean error at h (as
  :func:`~xnlos_core.app.tracking_metrics.prediction_errors`). ``model``: the tracker's ``Tracks.forecast``
  (missing, not zero, for a tracker without one); ``cv``: p + v·h from the same track states.
  Split by the road user's motion kind (straight / turning / braking,
  :func:`sims.scene_truth.motion_kind`).
* interval coverage: share of forecast (track, horizon) pairs whose truth lies in the 50 % / 90 % disc
  (``radius50`` / ``radius90``; pairs with a NaN radius left out).
* time-to-appearance (when the tracker's params name a ``region`` polygon [[x, y], …] [m] and the
  tracks carry ``arrival``): the truth arrival is the first map time whose road-user centre lies in the
  region; forecasts made before it, with it ≤ 3 s ahead, give the error predicted − true [s] (MAE over
  finite predictions; ``missed``: NaN predictions), and the share inside ``arrival_interval``.
* un-mirrored radial velocity [m/s] of the hidden points (with Doppler): each reconstructed point o
  with observed component w (``HiddenPoints.velocity``, along ĝ) is matched to the nearest ground-truth
  hidden point of a road user within the threshold; error |w| − ŵᵀv_true; RMSE by range |o| bin
  (:data:`RANGE_BINS`), and beside it the RMSE without gross errors (|error| > :data:`GROSS_RADIAL`,
  a point mirrored through the wrong wall or matched to another scatterer: one such point moves the
  RMSE of a few hundred by tenths of a m/s) with their share.

* ghost rate: share of the reconstructed hidden points (the mNLOS detections the reconstructor
  mirrored, after its visibility gate) that lie within :data:`GHOST_RADIUS` (2 m) of no object: no
  road user's centre and no ground-truth hidden point (of a road user or a static surface); pooled
  as ghosts / points over the frames, with the gate's refusals (``HiddenPoints.gated``) beside it.

Sequence records (``sequences.jsonl``, one fsync'd line per finished sequence) keep sums and counts,
so :func:`summarize` pools them exactly over a run, a family or a motion kind. A killed eval resumes
per whole sequence: map lines of an unfinished sequence are dropped and the sequence is redone.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.io import append_jsonl, read_keyed_jsonl, write_jsonl
from xnlos_core.app.tracking_metrics import POOLED, mot_matches
from xnlos_core.types import Frame, GroundTruth, HiddenPoints, Tracks

DEFAULT_HORIZONS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)  # s, the CV forecast of a tracker without its own
AT = (1.0, 2.0, 3.0)  # s, the horizons ADE/FDE are reported at
ARRIVAL_HORIZON = 3.0  # s, truth arrivals further ahead than this are not scored
RANGE_BINS = ((0.0, 15.0, "<15 m"), (15.0, 25.0, "15–25 m"), (25.0, math.inf, "≥25 m"))
GHOST_RADIUS = 2.0  # m, a hidden point farther than this from every object is a ghost (module docstring)
GROSS_RADIAL = 1.0  # m/s, a radial-velocity error above this is a gross one (module docstring)
SEQUENCES_LOG = "sequences.jsonl"


@dataclass
class Step:
    """One processed map of a sequence: time t [s], object truth (``meta["object_truth"]``), the
    tracker's output, the hidden points and the map's ground truth."""

    t: float
    truth: dict[str, list]
    tracks: Tracks
    hidden: HiddenPoints
    ground_truth: GroundTruth | None


# --- scoring one sequence -------------------------------------------------------------------------

def _truth_of(step: Step) -> dict[int, dict[str, Any]]:
    tr = step.truth
    return {int(i): {"p": np.asarray(p, float), "v": np.asarray(v, float), "mirror": bool(m), "motion": str(k),
                     "name": str(n)}
            for i, p, v, m, k, n in zip(tr["id"], tr["position"], tr["velocity"], tr["mirror"], tr["motion"], tr["name"])}


def _static_points(step: Step, names: set[str]) -> np.ndarray:
    """Ground-truth hidden points (P, 2) [m] of the map that belong to no road user (static surfaces)."""
    gt = step.ground_truth
    if gt is None or not len(gt.hidden_points):
        return np.empty((0, 2))
    static = np.array([gt.object_names[i] not in names for i in gt.mnlos_object], bool)
    return gt.hidden_points[static]


def _mot_frames(steps: list[Step], truth: list[dict], threshold: float):
    """(truth frames, hypothesis frames, ignored track-frames) for motmetrics with the don't-care
    rule of the module doc."""
    tf, hf, ignored = [], [], 0
    for s, objs in zip(steps, truth):
        seen = {i: o["p"] for i, o in objs.items() if o["mirror"]}
        blind = np.concatenate([np.array([o["p"] for o in objs.values() if not o["mirror"]]).reshape(-1, 2),
                                _static_points(s, {o["name"] for o in objs.values()})])
        pos, ids = s.tracks.position, s.tracks.track_id
        keep = np.ones(len(ids), bool)
        if len(blind) and len(ids):
            d_blind = np.linalg.norm(pos[:, None] - blind[None], axis=-1).min(axis=1)
            vis = np.array(list(seen.values())).reshape(-1, 2)
            d_seen = np.linalg.norm(pos[:, None] - vis[None], axis=-1).min(axis=1) if len(vis) else np.full(len(ids), np.inf)
            keep = ~((d_blind <= threshold) & (d_seen > threshold))
        tf.append((list(seen), np.array(list(seen.values())).reshape(-1, 2)))
        hf.append((ids[keep].tolist(), pos[keep]))
        ignored += int((~keep).sum())
    return tf, hf, ignored


def _future(steps: list[Step], truth: list[dict], k: int, oid: int, horizons, half: float) -> list:
    """Truth position of object ``oid`` at t_k + h for each h (None past the sequence's end)."""
    times = np.array([s.t for s in steps])
    out = []
    for h in horizons:
        j = int(np.argmin(np.abs(times - (times[k] + h))))
        ok = abs(times[j] - (times[k] + h)) <= half and oid in truth[j]
        out.append(truth[j][oid]["p"] if ok else None)
    return out


def _arrival_truth(truth: list[dict], times: np.ndarray, oid: int, region) -> float | None:
    from matplotlib.path import Path as Polygon

    poly = Polygon(np.asarray(region, float))
    for objs, t in zip(truth, times):
        if oid in objs and poly.contains_point(objs[oid]["p"]):
            return float(t)
    return None


def _radial(step: Step, threshold: float, names: set[str]) -> dict[str, list[float]]:
    """{range bin: [sum of squared errors, count, the same two without gross errors]} of the
    un-mirrored radial velocities of one map."""
    h, gt = step.hidden, step.ground_truth
    out = {b[2]: [0.0, 0, 0.0, 0] for b in RANGE_BINS}
    if h.velocity is None or gt is None or gt.hidden_velocity is None or not len(h) or not len(gt.hidden_points):
        return out
    own = np.array([gt.object_names[i] in names for i in gt.mnlos_object], bool)
    if not own.any():
        return out
    ref, vel = gt.hidden_points[own], gt.hidden_velocity[own]
    d = np.linalg.norm(h.mean[:, None] - ref[None], axis=-1)
    j = d.argmin(axis=1)
    for i in np.flatnonzero(d[np.arange(len(h)), j] <= threshold):
        w = h.velocity[i]
        speed = float(np.linalg.norm(w))
        if not np.isfinite(speed) or speed == 0:
            continue
        err = speed - float(w @ vel[j[i]]) / speed
        r = float(np.linalg.norm(h.mean[i]))
        label = next(b[2] for b in RANGE_BINS if b[0] <= r < b[1])
        out[label][0] += err * err
        out[label][1] += 1
        if abs(err) <= GROSS_RADIAL:
            out[label][2] += err * err
            out[label][3] += 1
    return out


def ghosts(step: Step, radius: float = GHOST_RADIUS) -> tuple[int, int, int]:
    """(ghosts, hidden points, gated) of one map: the reconstructed hidden points farther than
    ``radius`` [m] from every road user's centre and every ground-truth hidden point (module doc)."""
    hp = step.hidden
    m = len(hp.mean)
    gated = 0 if hp.gated is None else len(hp.gated)
    if m == 0:
        return 0, 0, gated
    objects = [np.asarray(p, float).reshape(-1, 2) for p in step.truth.get("position", [])]
    gt = step.ground_truth
    if gt is not None and len(gt.hidden_points):
        objects.append(np.asarray(gt.hidden_points, float).reshape(-1, 2))
    if not objects:
        return m, m, gated
    obj = np.concatenate(objects)
    d = np.linalg.norm(hp.mean[:, None, :] - obj[None], axis=-1).min(axis=1)
    return int(np.count_nonzero(d > radius)), m, gated


def score_sequence(steps: list[Step], threshold: float, region=None) -> dict[str, Any]:
    """The sums and counts of one sequence (module doc), JSON-ready: {frames, motion, mot {POOLED counts,
    motp_sum, mota, motp, idf1}, velocity [sse, n], forecasts [rows], arrivals [rows], radial {bin: [sse, n]}}.

    A forecast row: {k, object, track, motion, h (K,), err (K,) model error [m] or None, err_cv (K,),
    in50 / in90 (K,) bool or None, and with a forecast model (the track's motion model) and r50 / r90
    (K,) its disc radii [m]}, entries None where the sequence ends before t_k + h. An arrival row:
    {k, object, track, pred [s] or None, truth [s], lo, hi}."""
    if not steps:
        raise InputError("score_sequence: steps is empty; a sequence needs ≥ 1 processed map")
    truth = [_truth_of(s) for s in steps]
    times = np.array([s.t for s in steps])
    half = 0.5 * float(np.min(np.diff(times))) if len(times) > 1 else 0.05
    tf, hf, ignored = _mot_frames(steps, truth, threshold)
    mot, matches = mot_matches(tf, hf, threshold)
    mot["ignored"] = ignored
    rec: dict[str, Any] = {"frames": len(steps), "mot": {k: _num(v) for k, v in mot.items()},
                           "velocity": [0.0, 0], "forecasts": [], "arrivals": [], "radial": {}}
    kinds = sorted({o["motion"] for objs in truth for o in objs.values()})
    rec["motion"] = kinds[0] if len(kinds) == 1 else ("+".join(kinds) or "none")
    names = {o["name"] for objs in truth for o in objs.values()}
    arrive = {}
    for k, (s, pairs) in enumerate(zip(steps, matches)):
        tr = s.tracks
        row_of = {int(i): j for j, i in enumerate(tr.track_id)}
        for oid, hid in pairs:
            j, obj = row_of[hid], truth[k][oid]
            dv = tr.velocity[j] - obj["v"]
            rec["velocity"][0] += float(dv @ dv)
            rec["velocity"][1] += 1
            hz = tuple(float(h) for h in (tr.horizons if tr.horizons is not None else DEFAULT_HORIZONS))
            fut = _future(steps, truth, k, oid, hz, half)
            cv = [tr.position[j] + tr.velocity[j] * h for h in hz]
            err = lambda pred: [None if f is None else float(np.linalg.norm(p - f)) for p, f in zip(pred, fut)]  # noqa: E731
            row = {"k": k, "object": oid, "track": hid, "motion": obj["motion"], "h": list(hz), "err_cv": err(cv),
                   "err": None, "in50": None, "in90": None}
            if tr.forecast is not None:
                row["err"] = err(tr.forecast[j])
                row["model"] = tr.model[j]
                row["r50"], row["r90"] = ([_num(x) for x in r] for r in (tr.radius50[j], tr.radius90[j]))
                for key, r in (("in50", tr.radius50[j]), ("in90", tr.radius90[j])):
                    row[key] = [None if e is None or not np.isfinite(rad) else bool(e <= rad)
                                for e, rad in zip(row["err"], r)]
            rec["forecasts"].append(row)
            if region is not None and tr.arrival is not None:
                if oid not in arrive:
                    arrive[oid] = _arrival_truth(truth, times, oid, region)
                ta = arrive[oid]
                if ta is not None and s.t < ta <= s.t + ARRIVAL_HORIZON:
                    lo, hi = (float(x) for x in tr.arrival_interval[j])
                    rec["arrivals"].append({"k": k, "object": oid, "track": hid, "pred": _num(tr.arrival[j]),
                                            "truth": ta, "lo": _num(lo), "hi": hi if math.isfinite(hi) else None})
    radial = {b[2]: [0.0, 0, 0.0, 0] for b in RANGE_BINS}
    for s in steps:
        for label, sums in _radial(s, threshold, names).items():
            radial[label] = [a + b for a, b in zip(radial[label], sums)]
    rec["radial"] = radial
    rec["ghosts"] = [sum(g) for g in zip(*(ghosts(s) for s in steps))]
    return rec


def _num(v):
    """float, with NaN and ±inf → None (JSON; an undefined ratio or an unbounded interval end)."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


# --- pooling --------------------------------------------------------------------------------------

def _ratio(num: float, den: float) -> float | None:
    return None if den == 0 else float(num / den)


def _prediction(rows: list[dict], key: str) -> dict[str, float | None]:
    """ADE/FDE at :data:`AT` [m] and the number of forecasts scored at each, of ``key`` ("err" or "err_cv")."""
    out: dict[str, float | None] = {}
    for h in AT:
        errs, finals = [], []
        for r in rows:
            e = r[key]
            ks = [i for i, x in enumerate(r["h"]) if x <= h + 1e-9]
            if e is None or not ks or not math.isclose(r["h"][ks[-1]], h) or any(e[i] is None for i in ks):
                continue
            errs += [e[i] for i in ks]
            finals.append(e[ks[-1]])
        out[f"ade@{h:g}s"] = float(np.mean(errs)) if errs else None
        out[f"fde@{h:g}s"] = float(np.mean(finals)) if finals else None
        out[f"n@{h:g}s"] = len(finals)
    return out


def prediction_summary(rows: list[dict]) -> dict[str, Any]:
    """Forecast metrics over forecast rows: {forecasts, model {ade@…, fde@…, n@…}, cv {…}, coverage50,
    coverage90, coverage_pairs}; values None where nothing could be scored (no forecast: missing, not 0)."""
    cover = {}
    for key in ("in50", "in90"):
        vals = [x for r in rows if r[key] is not None for x in r[key] if x is not None]
        cover[key] = (float(np.mean(vals)) if vals else None, len(vals))
    return {"forecasts": len(rows), "model": _prediction(rows, "err"), "cv": _prediction(rows, "err_cv"),
            "coverage50": cover["in50"][0], "coverage90": cover["in90"][0], "coverage_pairs": cover["in90"][1]}


def pool(seqs: list[dict]) -> dict[str, Any]:
    """Tracking metrics pooled over sequence records (sums over sequences, then ratios)."""
    tot = {k: sum(s["mot"].get(k) or 0.0 for s in seqs) for k in (*POOLED, "ignored", "motp_sum")}
    vel = [sum(s["velocity"][i] for s in seqs) for i in (0, 1)]
    arrivals = [a for s in seqs for a in s["arrivals"]]
    finite = [a for a in arrivals if a["pred"] is not None]
    inside = [a["lo"] is not None and a["lo"] <= a["truth"] <= (a["hi"] if a["hi"] is not None else math.inf)
              for a in arrivals]
    radial = {}
    for b in RANGE_BINS:
        # a record written before the gross-error split has [sse, n] only: it counts towards the RMSE alone
        cells = [s["radial"][b[2]] for s in seqs]
        sse, n = sum(c[0] for c in cells), sum(c[1] for c in cells)
        split = [c for c in cells if len(c) == 4]
        sse_in, n_in, n_split = sum(c[2] for c in split), sum(c[3] for c in split), sum(c[1] for c in split)
        radial[b[2]] = {"rmse": math.sqrt(sse / n) if n else None, "points": int(n),
                        "rmse_without_gross": math.sqrt(sse_in / n_in) if n_in else None,
                        "gross_share": (n_split - n_in) / n_split if n_split else None}
    errors = tot["num_misses"] + tot["num_false_positives"] + tot["num_switches"]
    # motmetrics' motp_m: each sequence's MOTP weighted by its detections (matches + switches); from the
    # per-sequence MOTP, so records whose motp_sum counted matches only pool the same way
    motp_num = sum((s["mot"].get("motp") or 0.0) * ((s["mot"].get("num_matches") or 0.0)
                                                     + (s["mot"].get("num_switches") or 0.0)) for s in seqs)
    return {
        "sequences": len(seqs), "frames": int(sum(s["frames"] for s in seqs)),
        "mota": None if tot["num_objects"] == 0 else 1.0 - errors / tot["num_objects"],
        "motp": _ratio(motp_num, tot["num_matches"] + tot["num_switches"]),
        "idf1": _ratio(2 * tot["idtp"], 2 * tot["idtp"] + tot["idfp"] + tot["idfn"]),
        "counts": {k: int(v) for k, v in tot.items() if k != "motp_sum"},
        "velocity_rmse": math.sqrt(vel[0] / vel[1]) if vel[1] else None,
        **prediction_summary([r for s in seqs for r in s["forecasts"]]),
        "arrival": {"scored": len(arrivals), "missed": len(arrivals) - len(finite),
                    "mae_s": float(np.mean([abs(a["pred"] - a["truth"]) for a in finite])) if finite else None,
                    "bias_s": float(np.mean([a["pred"] - a["truth"] for a in finite])) if finite else None,
                    "interval_coverage": float(np.mean(inside)) if arrivals else None},
        "radial_velocity": radial,
        **_ghost_summary([s["ghosts"] for s in seqs if "ghosts" in s]),
    }


def _ghost_summary(cells: list[list[int]]) -> dict[str, Any]:
    """{"ghosts": {rate, ghosts, points, gated}} pooled over sequence records; {} for records written
    before the ghost count."""
    if not cells:
        return {}
    g, m, gated = (int(sum(c[i] for c in cells)) for i in range(3))
    return {"ghosts": {"rate": g / m if m else None, "ghosts": g, "points": m, "gated": gated}}


def summarize(seqs: list[dict]) -> dict[str, Any]:
    """eval.json's ``tracking`` entry: {overall, families {family: pool}, motions {kind: forecast metrics},
    family_motions {"family/kind": forecast metrics}}."""
    fams = sorted({s["family"] for s in seqs})
    rows = [dict(r, family=s["family"]) for s in seqs for r in s["forecasts"]]
    kinds = sorted({r["motion"] for r in rows})
    pairs = sorted({(r["family"], r["motion"]) for r in rows})
    return {"overall": pool(seqs), "families": {f: pool([s for s in seqs if s["family"] == f]) for f in fams},
            "motions": {k: prediction_summary([r for r in rows if r["motion"] == k]) for k in kinds},
            "family_motions": {f"{f}/{k}": prediction_summary([r for r in rows if r["family"] == f and r["motion"] == k])
                               for f, k in pairs}}


# --- running --------------------------------------------------------------------------------------

def sequences(frames: Iterable[Frame]) -> Iterator[tuple[int, list[tuple[int, Frame]]]]:
    """(sequence key, [(position, frame)]) for runs of consecutive maps of one scene
    (``meta["scene_index"]``; a map without it is a sequence of its own, keyed by its index)."""
    key, group = None, []
    for pos, f in enumerate(frames):
        k = int(f.meta.get("scene_index", f.index))
        if group and k != key:
            yield key, group
            group = []
        key = k
        group.append((pos, f))
    if group:
        yield key, group


def evaluate_sequences(pipe, frames: Iterable[Frame], out: Path, done: list[dict], *,
                       record: Callable, figure: Callable | None, figures: int, bar,
                       source: str) -> tuple[list[dict], list[dict]]:
    """Score the maps of ``frames`` sequence by sequence into ``out`` (frames.jsonl, sequences.jsonl).

    done: the map records frames.jsonl already holds; only those of finished sequences (a line in
    sequences.jsonl with as many frames as the sequence has now) are kept, the rest redone. record(result, position) → a map record;
    figure(result, position) draws a map. Returns (map records, sequence records), in order."""
    from xnlos_core.pipeline import timed_frames

    log, slog = out / "frames.jsonl", out / SEQUENCES_LOG
    finished = read_keyed_jsonl(slog, "sequence") if slog.exists() else {}
    maps = [r for r in done if r.get("sequence") in finished]
    write_jsonl(log, maps)
    write_jsonl(slog, finished.values())
    bar.update(len(maps))
    threshold = pipe.config.run.match_radius
    region = pipe.config.tracker.params.get("region")
    seqs = list(finished.values())
    for key, group in sequences(frames):
        if key in finished:
            if finished[key]["frames"] == len(group):
                continue
            # Scored under a smaller `limit` that cut it: redo it whole, its old lines removed.
            maps = [r for r in maps if r.get("sequence") != key]
            seqs = [q for q in seqs if q["sequence"] != key]
            write_jsonl(log, maps)
            write_jsonl(slog, seqs)
        pipe.reset()  # the tracks and a wall estimator's history of LOS detections
        steps, recs = [], []
        for (pos, frame), (_, src) in zip(group, timed_frames(f for _, f in group)):
            if frame.ground_truth is None or "object_truth" not in frame.meta:
                raise InputError(f"{source}: map {frame.index} has no object truth; a tracker is scored on a "
                                 "sequence dataset (frames_per_scene > 1) written by `xnlos simulate`")
            res = pipe.process(frame)
            res.timings = {"source": src, **res.timings}
            if figure is not None and pos < figures:
                figure(res, pos)
            rec = {**record(res, pos), "sequence": key}
            append_jsonl(log, rec)
            recs.append(json.loads(json.dumps(rec)))
            steps.append(Step(frame.timestamp, frame.meta["object_truth"], res.tracks, res.hidden, frame.ground_truth))
            bar.update(1)
        first = group[0][1].meta
        srec = {"sequence": key, "family": str(first.get("family", "unknown")), "scene": first.get("scene"),
                **score_sequence(steps, threshold, region)}
        append_jsonl(slog, srec)
        seqs.append(json.loads(json.dumps(srec)))
        maps += recs
    return sorted(maps, key=lambda r: r["position"]), sorted(seqs, key=lambda s: s["sequence"])


# --- report ---------------------------------------------------------------------------------------

def _f(v, digits: int = 2) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _radial_cell(c: dict) -> str:
    out = f"{_f(c['rmse'])} ({c['points']})"
    if c.get("rmse_without_gross") is not None:
        out += f" · {_f(c['rmse_without_gross'])}, {100 * c['gross_share']:.1f} %"
    return out


def render_tracking(runs: list[dict]) -> list[str]:
    """eval.md lines of the tracking tables (runs with a ``tracking`` entry only)."""
    runs = [r for r in runs if r.get("tracking")]
    if not runs:
        return []
    lines = ["", "## Tracking (sequences)", "",
             "MOTA, IDF1 ↑; MOTP [m], velocity RMSE [m/s], ADE/FDE [m] ↓; '-': not defined or the tracker gives "
             "no forecast. CV: constant-velocity forecast p + v·h from the same track states.", "",
             "| run | method | family | seq | MOTA | MOTP | IDF1 | vel RMSE | ADE@1s | FDE@1s | ADE@2s | FDE@2s | "
             "FDE@3s | CV FDE@2s | cover50 | cover90 | arrival MAE [s] |", "|" + "---|" * 17]
    for r in runs:
        t = r["tracking"]
        for fam, p in [("all", t["overall"]), *t["families"].items()]:
            m, cv = p["model"], p["cv"]
            lines.append(f"| {r['run']} | {r['name']} | {fam} | {p['sequences']} | {_f(p['mota'])} | {_f(p['motp'])} | "
                         f"{_f(p['idf1'])} | {_f(p['velocity_rmse'])} | {_f(m['ade@1s'])} | {_f(m['fde@1s'])} | "
                         f"{_f(m['ade@2s'])} | {_f(m['fde@2s'])} | {_f(m['fde@3s'])} | {_f(cv['fde@2s'])} | "
                         f"{_f(p['coverage50'])} | {_f(p['coverage90'])} | {_f(p['arrival']['mae_s'])} |")
    lines += ["", "### 2 s-ahead error by motion: tracker forecast vs constant velocity", "",
              "| run | method | family / motion | forecasts @2s | FDE@2s | CV FDE@2s | ratio |", "|" + "---|" * 7]
    for r in runs:
        t = r["tracking"]
        for key, p in [*t["motions"].items(), *t["family_motions"].items()]:
            a, b = p["model"]["fde@2s"], p["cv"]["fde@2s"]
            ratio = a / b if a is not None and b else None
            lines.append(f"| {r['run']} | {r['name']} | {key} | {p['cv']['n@2s']} | {_f(a)} | {_f(b)} | {_f(ratio)} |")
    lines += ["", "### Un-mirrored radial velocity of hidden points, RMSE [m/s] (points) by range", "",
              f"Each cell: RMSE (points) · RMSE without gross errors (|error| > {GROSS_RADIAL:g} m/s), their share.", "",
              "| run | method | family | " + " | ".join(b[2] for b in RANGE_BINS) + " |", "|" + "---|" * (3 + len(RANGE_BINS))]
    for r in runs:
        t = r["tracking"]
        for fam, p in [("all", t["overall"]), *t["families"].items()]:
            rv = p["radial_velocity"]
            lines.append(f"| {r['run']} | {r['name']} | {fam} | "
                         + " | ".join(_radial_cell(rv[b[2]]) for b in RANGE_BINS) + " |")
    if any("ghosts" in r["tracking"]["overall"] for r in runs):
        lines += ["", "### Ghosts: reconstructed hidden points within "
                  f"{GHOST_RADIUS:g} m of no object", "",
                  "rate = ghosts / hidden points over every frame; gated: mNLOS detections the visibility gate "
                  "refused before mirroring.", "",
                  "| run | method | family | hidden points | ghosts | rate | gated |", "|" + "---|" * 7]
        for r in runs:
            t = r["tracking"]
            for fam, p in [("all", t["overall"]), *t["families"].items()]:
                g = p.get("ghosts")
                if g:
                    lines.append(f"| {r['run']} | {r['name']} | {fam} | {g['points']} | {g['ghosts']} | "
                                 f"{_f(g['rate'], 3)} | {g['gated']} |")
    return lines
