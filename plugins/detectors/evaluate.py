"""Validation of a dense detector: Macro-F1 over decoding settings, and position calibration.

Decoding at the lowest threshold and then keeping detections with confidence > t gives exactly
the detections of decoding at t (the greedy suppression only lets stronger peaks suppress
weaker ones), so a whole threshold grid costs one decode per map and window.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from xnlos_core.metrics import dense_metrics, match_points
from xnlos_core.types import LOS, MNLOS, Detections, GroundTruth, RAMap

from .heatmaps import peak_cells
from .learned import detections_from_output


def _mean(values: list[float]) -> float:
    vals = [v for v in values if np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("inf")


def summarize(per_map: list[dict]) -> dict[str, float]:
    """Means over maps of F1 (LOS, mNLOS, Macro) and CD [m²] (finite values; inf if none)."""
    out = {}
    for key in ("los", "mnlos", "macro"):
        out[f"{key}_f1"] = float(np.mean([m[key]["f1"] for m in per_map]))
        out[f"{key}_cd"] = _mean([m[key]["cd"] for m in per_map])
    out["n_maps"] = len(per_map)
    return out


def sweep_decoding(outputs: list[np.ndarray], head, maps: list[RAMap], truths: list[GroundTruth],
                   thresholds: list[float], windows: list[tuple[int, int]], radius: float,
                   max_detections: int = 1000, cells: tuple[bool, ...] = (False, True)) -> dict[str, Any]:
    """Per-class thresholds, the window and the resolution-cell suppression (:mod:`.decode`) that
    maximise Macro-F1 on these maps.

    LOS F1 depends only on LOS detections and mNLOS F1 only on mNLOS ones, so each class gets its
    own best threshold; window and ``cells`` are shared (suppression is tried with every window and
    with (1, 1) for a dense head). Suppression keeps the most confident peak of a cell, so it too
    commutes with the threshold. Returns {"best": {threshold: [t_LOS,
    t_mNLOS], window, cells, los_f1, mnlos_f1, macro_f1, CDs …}, "grid": [per (window, cells,
    threshold) rows]}.
    """
    grid, candidates = [], []
    windows = [tuple(w) for w in windows] if head.describe()["kind"] == "dense" else [tuple(windows[0])]
    settings = [(w, c) for w in windows for c in cells]
    if True in cells and head.describe()["kind"] == "dense" and (1, 1) not in windows:
        settings.append(((1, 1), True))  # every cell above threshold, one per resolution cell
    for win, cell in settings:
        dets = [detections_from_output(o, head, m, min(thresholds), tuple(win), True, max_detections, cells=cell)
                for o, m in zip(outputs, maps)]
        rows = []
        for t in thresholds:
            per_map = [dense_metrics(d.select(d.confidence > t), g, radius) for d, g in zip(dets, truths)]
            rows.append({"threshold": t, "window": list(win), "cells": cell, **summarize(per_map)})
        grid.extend(rows)
        bl = max(rows, key=lambda r: (r["los_f1"], -r["threshold"]))
        bm = max(rows, key=lambda r: (r["mnlos_f1"], -r["threshold"]))
        per_map = [dense_metrics(select_per_class(d, (bl["threshold"], bm["threshold"])), g, radius)
                   for d, g in zip(dets, truths)]
        candidates.append({"threshold": [bl["threshold"], bm["threshold"]], "window": list(win), "cells": cell,
                           **summarize(per_map)})
    best = max(candidates, key=lambda r: r["macro_f1"])
    return {"best": best, "grid": grid}


def select_per_class(det: Detections, thresholds: tuple[float, float]) -> Detections:
    """Detections whose confidence exceeds their class's threshold (LOS, mNLOS; others: the lower)."""
    t = np.where(det.label == LOS, thresholds[0], np.where(det.label == MNLOS, thresholds[1], min(thresholds)))
    return det.select(det.confidence > t)


def matched_cells(det: Detections, ra_map: RAMap, truth: GroundTruth, radius: float):
    """Per class (LOS, mNLOS): (indices into ``det`` of the detections matched to ground truth of
    their class within ``radius`` [m], the matched truths' fractional cells (n, 3)). A class with
    ground-truth points off the map is skipped (their cells would not line up)."""
    gt_cells = peak_cells(ra_map, truth, thin=False)
    for label, pts in ((LOS, truth.los_points), (MNLOS, truth.mnlos_points)):
        sel = np.nonzero(det.label == label)[0]
        gcell = gt_cells[gt_cells[:, 2] == label]
        if not len(sel) or not len(pts) or len(gcell) != len(pts):
            continue
        pi, gi = match_points(det.position[sel], pts, radius)
        yield sel[pi], gcell[gi]


def calibrate(outputs: list[np.ndarray], head, maps: list[RAMap], truths: list[GroundTruth],
              threshold: tuple[float, float], window: tuple[int, int], radius: float,
              cells: bool = False) -> dict[str, float]:
    """RMS position error [cells] per axis of detections matched to ground truth (same class,
    within ``radius``): the standard deviations the detector reports. 1/√12 cell when no match."""
    res_r, res_a = [], []
    for o, m, g in zip(outputs, maps, truths):
        det = detections_from_output(o, head, m, threshold, window, True, 1000, cells=cells)
        dr = np.interp(det.range, m.range_axis, np.arange(m.shape[0]))
        da = np.interp(det.azimuth, m.azimuth_axis, np.arange(m.shape[1]))
        for idx, gcell in matched_cells(det, m, g, radius):
            res_r.extend(dr[idx] - gcell[:, 0])
            res_a.extend(da[idx] - gcell[:, 1])
    u = 1.0 / np.sqrt(12.0)
    rms = lambda v: float(np.sqrt(np.mean(np.square(v)))) if len(v) >= 5 else u  # noqa: E731
    return {"range_cells": float(max(rms(res_r), 0.05)), "azimuth_cells": float(max(rms(res_a), 0.05)),
            "n_matches": len(res_r)}
