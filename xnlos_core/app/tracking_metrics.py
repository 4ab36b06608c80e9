"""Tracking and prediction metrics: CLEAR-MOT (MOTA, MOTP) and IDF1 with motmetrics,
prediction ADE/FDE at horizons, and prediction-interval coverage.

A sequence is a list of frames; a frame is ``(ids, positions)`` with ids (n,) integers and
positions (n, 2) [m]. Truth and hypothesis are matched within ``threshold`` [m] (Euclidean).
"""
from __future__ import annotations

from collections.abc import Sequence

import motmetrics as mm
import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.validation import as_array

Frame = tuple[Sequence[int], np.ndarray]


def _frame(name: str, frame) -> tuple[np.ndarray, np.ndarray]:
    try:
        ids, pos = frame
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a pair (ids (n,), positions (n, 2) [m]), got {type(frame).__name__}")
    ids = as_array(f"{name} ids", ids, dtype=np.int64, ndim=1)
    pos = as_array(f"{name} positions", np.asarray(pos, dtype=np.float64).reshape(-1, 2) if np.size(pos) == 0
                   else pos, shape=(len(ids), 2))
    if len(np.unique(ids)) != len(ids):
        raise InputError(f"{name} ids: an id appears twice in one frame: {ids.tolist()}")
    return ids, pos


def mot_metrics(truth: Sequence[Frame], hypotheses: Sequence[Frame], threshold: float) -> dict[str, float]:
    """CLEAR-MOT and identity metrics of ``hypotheses`` against ``truth`` (same number of frames).

    Returns mota = 1 − (misses + false positives + id switches) / truth objects, motp [m] = mean
    distance of the matched pairs, switches included (motmetrics: Σd / (num_matches + num_switches),
    a SWITCH being a match whose id changed; lower is better; NaN without matches), idf1 = 2 IDTP / (truth +
    hypothesis objects) with the best global one-to-one id mapping, and the counts num_switches,
    num_misses, num_false_positives, num_matches. Pairs farther apart than ``threshold`` [m] never match.
    """
    names = ["mota", "motp", "idf1", "num_switches", "num_misses", "num_false_positives", "num_matches"]
    out, _ = mot_matches(truth, hypotheses, threshold)
    return {n: out[n] for n in names}


POOLED = ("num_objects", "num_predictions", "num_matches", "num_switches", "num_misses", "num_false_positives",
          "idtp", "idfp", "idfn")


def mot_matches(truth: Sequence[Frame], hypotheses: Sequence[Frame],
                threshold: float) -> tuple[dict[str, float], list[list[tuple[int, int]]]]:
    """:func:`mot_metrics` plus what pooling over sequences needs, and the CLEAR-MOT matches.

    Returns (metrics, matches): metrics has mota, motp, idf1 and the counts of :data:`POOLED`
    (num_objects: truth objects over all frames; idtp / idfp / idfn of the IDF1 mapping) and
    ``motp_sum`` [m], the summed distance of the matches, switches included (motp × (num_matches +
    num_switches), so that pooled MOTP = Σ motp_sum / Σ (num_matches + num_switches) as motmetrics'
    ``motp_m`` pools it); matches[k] lists the (truth id, hypothesis
    id) pairs matched in frame k (a MATCH or SWITCH event of motmetrics).
    """
    if not (np.isfinite(threshold) and threshold > 0):
        raise InputError(f"mot_metrics: threshold must be a positive distance [m], got {threshold}")
    if len(truth) != len(hypotheses):
        raise InputError(f"mot_metrics: truth has {len(truth)} frames, hypotheses {len(hypotheses)}; "
                         "they must have one entry per frame each")
    acc = mm.MOTAccumulator(auto_id=True)
    for k, (tf, hf) in enumerate(zip(truth, hypotheses)):
        oid, opos = _frame(f"mot_metrics: truth frame {k}", tf)
        hid, hpos = _frame(f"mot_metrics: hypothesis frame {k}", hf)
        d = np.linalg.norm(opos[:, None, :] - hpos[None, :, :], axis=-1)
        acc.update(oid.tolist(), hid.tolist(), np.where(d <= threshold, d, np.nan))
    names = ["mota", "motp", "idf1", *POOLED]
    row = mm.metrics.create().compute(acc, metrics=names, return_dataframe=False)
    out = {n: float(row[n]) for n in names}
    matches: list[list[tuple[int, int]]] = [[] for _ in truth]
    ev = acc.mot_events
    matched = ev[ev.Type.isin(["MATCH", "SWITCH"])]
    out["motp_sum"] = float(matched.D.sum())  # motmetrics' motp numerator: MATCH and SWITCH distances
    for (frame, _), e in matched.iterrows():
        matches[int(frame)].append((int(e.OId), int(e.HId)))
    return out, matches


def prediction_errors(predicted, truth, horizons, at=(1.0, 2.0, 3.0)) -> dict[str, float]:
    """Average and final displacement errors [m] of predicted trajectories.

    predicted, truth: (P, K, 2) [m], P predictions sampled at ``horizons`` (K,) [s] ahead (increasing,
    > 0). For each h in ``at`` (each must be one of ``horizons``): ``ade@{h}s`` = mean over predictions
    and over horizons ≤ h of |predicted − truth|; ``fde@{h}s`` = mean over predictions at horizon h.
    """
    hz = as_array("prediction_errors: horizons", horizons, ndim=1)
    if len(hz) == 0 or hz[0] <= 0 or np.any(np.diff(hz) <= 0):
        raise InputError(f"prediction_errors: horizons must be increasing and > 0 [s], got {hz.tolist()}")
    pred = as_array("prediction_errors: predicted", predicted, shape=(None, len(hz), 2))
    true = as_array("prediction_errors: truth", truth, shape=pred.shape)
    if len(pred) == 0:
        raise InputError("prediction_errors: no predictions given (P = 0)")
    err = np.linalg.norm(pred - true, axis=-1)  # (P, K)
    out = {}
    for h in at:
        k = np.flatnonzero(np.isclose(hz, h))
        if len(k) == 0:
            raise InputError(f"prediction_errors: horizon {h} s is not among the given horizons {hz.tolist()}")
        out[f"ade@{h:g}s"] = float(err[:, : k[0] + 1].mean())
        out[f"fde@{h:g}s"] = float(err[:, k[0]].mean())
    return out


def interval_coverage(center, radius, truth) -> float:
    """Share of ``truth`` (N, 2) [m] inside the disc intervals ``center`` (N, 2) [m], ``radius`` (N,) [m]."""
    c = as_array("interval_coverage: center", center, shape=(None, 2))
    r = as_array("interval_coverage: radius", radius, shape=(len(c),))
    t = as_array("interval_coverage: truth", truth, shape=c.shape)
    if len(c) == 0 or np.any(r < 0):
        raise InputError(f"interval_coverage: need ≥ 1 interval and radii ≥ 0, got {len(c)} intervals")
    return float(np.mean(np.linalg.norm(t - c, axis=1) <= r))
