"""Point-cloud metrics of the paper's Table 2: Chamfer distance [m²] and F1 at a match radius.

Conventions for empty sets (so that averages over frames stay defined and comparable):

* Chamfer distance: both sets empty → 0 m²; exactly one empty → +inf (there is nothing to
  measure a distance to; an average over frames then is +inf too, flagging the failure).
* F1: ratios 0/0 are 1 (vacuous: no predictions → no false positives, precision 1; no ground
  truth → nothing missed, recall 1). Hence both empty → P = R = F1 = 1; predictions without
  ground truth → P = 0, R = 1, F1 = 0; ground truth without predictions → P = 1, R = 0, F1 = 0.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .errors import InputError
from .geometry import cartesian_to_polar
from .radar import RadarConfig
from .types import LOS, MNLOS, Detections, GroundTruth, HiddenPoints
from .validation import as_array


def _cloud(name: str, value, dim: int | None = None) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64) if not isinstance(value, np.ndarray) else value
    if arr.size == 0:
        return np.empty((0, dim or 2))
    return as_array(name, arr, shape=(None, dim))


def _pair(pred, gt) -> tuple[np.ndarray, np.ndarray]:
    p = _cloud("pred", pred)
    g = _cloud("gt", gt)
    if len(p) and len(g) and p.shape[1] != g.shape[1]:
        raise InputError(f"pred/gt: point dimensions differ ({p.shape[1]} vs {g.shape[1]})")
    return p, g


def chamfer_distance(pred, gt) -> float:
    """Symmetric Chamfer distance [m²] between point sets pred (N, 2) and gt (M, 2) [m]:

        CD = (1/N) Σ_p min_g |p − g|² + (1/M) Σ_g min_p |g − p|².

    Both empty → 0; exactly one empty → +inf (module doc).
    """
    p, g = _pair(pred, gt)
    if len(p) == 0 and len(g) == 0:
        return 0.0
    if len(p) == 0 or len(g) == 0:
        return float("inf")
    d_pg, _ = cKDTree(g).query(p)
    d_gp, _ = cKDTree(p).query(g)
    return float(np.mean(d_pg**2) + np.mean(d_gp**2))


def match_points(pred, gt, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one matching of pred (N, 2) to gt (M, 2) within ``radius`` [m].

    Maximises the number of pairs closer than ``radius`` (ties: least total distance) by
    linear_sum_assignment on each connected component of the within-radius bipartite graph
    (exact, and memory stays small for large clouds). Returns index arrays (pred_idx, gt_idx).
    """
    if not radius > 0:
        raise InputError(f"radius: the match radius must be > 0 m, got {radius}")
    p, g = _pair(pred, gt)
    empty = (np.empty(0, np.int64), np.empty(0, np.int64))
    if len(p) == 0 or len(g) == 0:
        return empty
    nb = cKDTree(p).query_ball_tree(cKDTree(g), radius)
    rows = np.repeat(np.arange(len(p)), [len(x) for x in nb])
    cols = np.fromiter((j for x in nb for j in x), dtype=np.int64, count=len(rows))
    if len(rows) == 0:
        return empty
    n = len(p) + len(g)
    graph = coo_matrix((np.ones(len(rows)), (rows, len(p) + cols)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    edge_comp = comp[rows]
    out_p, out_g = [], []
    for c in np.unique(edge_comp):
        sel = edge_comp == c
        r_u, r_inv = np.unique(rows[sel], return_inverse=True)
        c_u, c_inv = np.unique(cols[sel], return_inverse=True)
        big = radius * (min(len(r_u), len(c_u)) + 1)  # one more pair always beats any distance sum
        cost = np.full((len(r_u), len(c_u)), big)
        cost[r_inv, c_inv] = np.linalg.norm(p[rows[sel]] - g[cols[sel]], axis=1)
        a, b = linear_sum_assignment(cost)
        ok = cost[a, b] <= radius
        out_p.append(r_u[a[ok]])
        out_g.append(c_u[b[ok]])
    return np.concatenate(out_p), np.concatenate(out_g)


def f1_score(pred, gt, radius: float) -> dict[str, float]:
    """Precision, recall and F1 of pred (N, 2) against gt (M, 2) with one-to-one matches within
    ``radius`` [m] (:func:`match_points`). Returns {precision, recall, f1, tp, fp, fn}; empty
    sets follow the module-doc convention (0/0 = 1)."""
    p, g = _pair(pred, gt)
    tp = len(match_points(p, g, radius)[0])
    fp, fn = len(p) - tp, len(g) - tp
    precision = tp / len(p) if len(p) else 1.0
    recall = tp / len(g) if len(g) else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return {"precision": precision, "recall": recall, "f1": f1, "tp": tp, "fp": fp, "fn": fn}


def _scores(pred, gt, radius: float) -> dict[str, float]:
    out = f1_score(pred, gt, radius)
    out["cd"] = chamfer_distance(pred, gt)
    return out


def dense_metrics(detections: Detections, ground_truth: GroundTruth, radius: float) -> dict:
    """Dense-prediction metrics on the un-mirrored points (Table 2, left block).

    Returns {"los", "mnlos", "all": {precision, recall, f1, tp, fp, fn, cd}, "macro": {f1, cd,
    precision, recall}, "n_unclassified", "classified"}:

    * "los": LOS detections vs ground_truth.los_points; "mnlos": mNLOS detections vs
      ground_truth.mnlos_points (virtual points o'). UNCLASSIFIED detections enter neither.
    * "macro": mean of the LOS and mNLOS entries (the paper's Macro-F1 / Macro-CD).
    * "all": class-agnostic — every detection (LOS, mNLOS and UNCLASSIFIED) against the union of
      LOS and mNLOS ground truth. This is the number to report for a detector that cannot
      classify (plain CFAR, ``classified`` False), where the per-class entries are meaningless
      (the paper prints '-' for them).
    """
    if not isinstance(detections, Detections):
        raise InputError(f"dense_metrics: detections must be Detections, got {type(detections).__name__}")
    if not isinstance(ground_truth, GroundTruth):
        raise InputError(f"dense_metrics: ground_truth must be GroundTruth, got {type(ground_truth).__name__}")
    pos = detections.position
    los = _scores(pos[detections.label == LOS], ground_truth.los_points, radius)
    mnlos = _scores(pos[detections.label == MNLOS], ground_truth.mnlos_points, radius)
    every = _scores(pos, np.concatenate([ground_truth.los_points, ground_truth.mnlos_points]), radius)
    macro = {k: 0.5 * (los[k] + mnlos[k]) for k in ("f1", "precision", "recall", "cd")}
    n_unc = int(np.sum((detections.label != LOS) & (detections.label != MNLOS)))
    return {"los": los, "mnlos": mnlos, "macro": macro, "all": every, "n_unclassified": n_unc,
            "classified": n_unc == 0}


def reconstruction_metrics(hidden_points, ground_truth: GroundTruth, radius: float) -> dict:
    """Reconstruction metrics (Table 2, right block): reconstructed hidden points (HiddenPoints or
    (K, 2) [m]) vs ground_truth.hidden_points.

    Returns {precision, recall, f1, tp, fp, fn, cd [m²], object_error_m {name: [m]}}. A
    reconstructed point is attributed to the object of its nearest true hidden point if that lies
    within 5·radius; object_error_m[name] is the mean distance [m] from the points attributed to
    the object to its nearest true (illuminated) surface point — how far the reconstruction
    lands from the object. A radar sees only the faces a wall illuminates, so a centroid-based
    error would penalise partial views. NaN when no point is attributed (not reconstructed).
    """
    if not isinstance(ground_truth, GroundTruth):
        raise InputError(f"reconstruction_metrics: ground_truth must be GroundTruth, got {type(ground_truth).__name__}")
    pred = hidden_points.mean if isinstance(hidden_points, HiddenPoints) else _cloud("hidden_points", hidden_points, 2)
    gt = ground_truth.hidden_points
    out: dict = _scores(pred, gt, radius)
    errors = {name: float("nan") for name in ground_truth.object_names}
    if len(pred) and len(gt):
        dist, near = cKDTree(gt).query(pred, distance_upper_bound=5.0 * radius)
        ok = np.isfinite(dist)
        owner = np.full(len(pred), -1)
        owner[ok] = ground_truth.mnlos_object[near[ok]]
        for k, name in enumerate(ground_truth.object_names):
            mine = owner == k
            if mine.any():
                errors[name] = float(dist[mine].mean())
    out["object_error_m"] = errors
    return out


def scene_metrics(detections: Detections, hidden_points, ground_truth: GroundTruth, radius: float) -> dict:
    """Reconstruction of the whole scene (Table 2, right block): the complete point cloud after
    the mNLOS points are reflected to where they are.

    Prediction: the LOS detections' positions plus the reconstructed hidden points
    (HiddenPoints or (K, 2) [m]); ground truth: ``los_points`` plus ``hidden_points``. Returns
    {precision, recall, f1, tp, fp, fn, cd [m²]} with the conventions of :func:`f1_score` and
    :func:`chamfer_distance` (both clouds empty: F1 1, CD 0; one empty: F1 0, CD inf).
    """
    if not isinstance(detections, Detections):
        raise InputError(f"scene_metrics: detections must be Detections, got {type(detections).__name__}")
    if not isinstance(ground_truth, GroundTruth):
        raise InputError(f"scene_metrics: ground_truth must be GroundTruth, got {type(ground_truth).__name__}")
    hidden = hidden_points.mean if isinstance(hidden_points, HiddenPoints) else _cloud("hidden_points", hidden_points, 2)
    pred = np.concatenate([detections.position[detections.label == LOS], hidden])
    gt = np.concatenate([ground_truth.los_points, ground_truth.hidden_points])
    return _scores(pred, gt, radius)


@lru_cache(maxsize=32)
def resolution_cell(radar: RadarConfig) -> tuple[float, float]:
    """(range [m], azimuth [rad]) extent of one resolution cell: c/2B and the −3 dB beamwidth."""
    from xnlos_core.signal.antenna import beam_metrics

    return radar.range_resolution, float(beam_metrics(radar)["beamwidth_3db"])


def _cell_groups(points: np.ndarray, cell: tuple[float, float], extra: np.ndarray | None = None,
                 shift: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Group label (K,) of each point's (range, azimuth) resolution cell (and ``extra`` key); the
    grid is offset by ``shift`` cells (range, azimuth)."""
    r, a = cartesian_to_polar(points)
    keys = [np.floor(r / cell[0] + shift[0]), np.floor(a / cell[1] + shift[1])]
    keys = np.stack(keys + ([] if extra is None else [extra]), -1)
    return np.unique(keys, axis=0, return_inverse=True)[1].ravel()


def resolution_groups(points: np.ndarray, radar: RadarConfig, extra: np.ndarray | None = None) -> np.ndarray:
    """Group label (K,) of each bird's-eye point (K, 2) [m]: its radar resolution cell
    (⌊r/δr⌋, ⌊θ/δθ⌋) with (δr, δθ) = :func:`resolution_cell` (and the ``extra`` key, e.g. a class),
    the cells :func:`thin_to_resolution` reduces ground truth to."""
    pts = _cloud("points", points)
    if len(pts) == 0:
        return np.empty(0, dtype=np.int64)
    return _cell_groups(pts, resolution_cell(radar), extra)


def _group_mean(points: np.ndarray, groups: np.ndarray) -> np.ndarray:
    n = groups.max() + 1 if len(groups) else 0
    out = np.zeros((n, 2))
    np.add.at(out, groups, points)
    return out / np.bincount(groups, minlength=n)[:, None]


def _group_max(values: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Per-group maximum of ``values`` (NaN only where every member is NaN)."""
    out = np.full(groups.max() + 1 if len(groups) else 0, np.nan)
    np.fmax.at(out, groups, values)
    return out


def thin_to_resolution(ground_truth: GroundTruth, radar: RadarConfig,
                       shift: tuple[float, float] = (0.0, 0.0)) -> GroundTruth:
    """Ground truth at the density a radar can resolve: one point (the mean) per resolution cell.

    Simulators list scatterers every few centimetres; scoring detections against all of them
    would make recall meaningless. LOS points are grouped by their (range, azimuth) cell;
    mNLOS points by their cell and object, with their hidden points averaged alike (Eq. 7 is
    affine, so the mean hidden point is the mirror of the mean virtual point). A cell's SNR is
    the largest of its points'. ``shift`` offsets the cell grid by that many cells (range,
    azimuth); the scored ground truth uses (0, 0). ``los_object`` is not kept (a LOS cell may mix
    objects and walls): count owners on the unthinned truth.
    """
    cell = resolution_cell(radar)
    gt = ground_truth
    los, los_snr = gt.los_points, gt.los_snr_db
    if len(los):
        g = _cell_groups(los, cell, shift=shift)
        los, los_snr = _group_mean(los, g), _group_max(los_snr, g)
    m, h, obj, m_snr = gt.mnlos_points, gt.hidden_points, gt.mnlos_object, gt.mnlos_snr_db
    if len(m):
        g = _cell_groups(m, cell, obj, shift)
        m, h, m_snr = _group_mean(m, g), _group_mean(h, g), _group_max(m_snr, g)
        first = np.zeros(g.max() + 1, dtype=np.int64)
        first[g[::-1]] = np.arange(len(g))[::-1]
        obj = obj[first]
    return GroundTruth(los, m, h, obj, gt.object_names, gt.walls, los_snr, m_snr)
