"""Training targets from ground truth: peak cells, Gaussian heatmaps (Sec. 4.2), per-cell and grid labels.

Ground-truth points are bird's-eye (x, y) [m]; a map cell is (range index, azimuth index). A
point becomes fractional cell coordinates by interpolating its range and azimuth on the map's
axes (:func:`peak_cells`); points outside the map are dropped.

Gaussian target of class k (Eq. 8's Y):  Y_k(i, j) = max_p exp(−½((i − r_p)/σ_r)² − ½((j − a_p)/σ_a)²)
over the class's points p at fractional cell (r_p, a_p), with the point's nearest cell set to
exactly 1 (the focal loss's positives). The Gaussian is centred on the fractional position, so
its two neighbours encode the sub-bin offset that the detector's refinement reads back.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.geometry import cartesian_to_polar
from xnlos_core.metrics import thin_to_resolution
from xnlos_core.types import LOS, MNLOS, GroundTruth, RAMap


def peak_cells(ra_map: RAMap, ground_truth: GroundTruth, thin: bool = True) -> np.ndarray:
    """(P, 3) float64 rows (range index, azimuth index, class LOS=0 / MNLOS=1) of the ground truth.

    thin: first reduce the ground truth to one point per resolution cell
    (:func:`xnlos_core.metrics.thin_to_resolution`), the density the metrics score against.
    """
    gt = thin_to_resolution(ground_truth, ra_map.radar) if thin else ground_truth
    rows = []
    for label, pts in ((LOS, gt.los_points), (MNLOS, gt.mnlos_points)):
        if len(pts) == 0:
            continue
        r, a = cartesian_to_polar(pts)
        ra, aa = ra_map.range_axis, ra_map.azimuth_axis
        inside = (r >= ra[0]) & (r <= ra[-1]) & (a >= aa[0]) & (a <= aa[-1])
        fr = np.interp(r[inside], ra, np.arange(len(ra)))
        fa = np.interp(a[inside], aa, np.arange(len(aa)))
        rows.append(np.stack([fr, fa, np.full(len(fr), float(label))], 1))
    return np.concatenate(rows) if rows else np.empty((0, 3))


def gaussian_heatmap(peaks: np.ndarray, shape: tuple[int, int], sigma: tuple[float, float],
                     truncate: float = 3.0) -> np.ndarray:
    """Gaussian targets Y (2, H, W) float32 in [0, 1] of peaks (P, 3) (module doc).

    sigma: (σ_r, σ_a) [cells]; each Gaussian is evaluated within ``truncate``·σ of its centre.
    The nearest cell of every peak is exactly 1.
    """
    h, w = shape
    out = np.zeros((2, h, w), dtype=np.float32)
    sr, sa = float(sigma[0]), float(sigma[1])
    hr, ha = int(np.ceil(truncate * sr)), int(np.ceil(truncate * sa))
    for r, a, k in np.asarray(peaks, dtype=np.float64).reshape(-1, 3):
        ir, ia, k = int(round(r)), int(round(a)), int(k)
        if not (0 <= ir < h and 0 <= ia < w):
            continue
        r0, r1 = max(ir - hr, 0), min(ir + hr + 1, h)
        a0, a1 = max(ia - ha, 0), min(ia + ha + 1, w)
        gr = np.exp(-0.5 * ((np.arange(r0, r1) - r) / sr) ** 2)
        ga = np.exp(-0.5 * ((np.arange(a0, a1) - a) / sa) ** 2)
        np.maximum(out[k, r0:r1, a0:a1], np.outer(gr, ga).astype(np.float32), out=out[k, r0:r1, a0:a1])
        out[k, ir, ia] = 1.0
    return out


def binary_cells(peaks: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Per-cell labels (2, H, W) float32: 1 at the nearest cell of every peak, else 0
    ("See Further Than CFAR": one labelled cell per point)."""
    h, w = shape
    out = np.zeros((2, h, w), dtype=np.float32)
    p = np.asarray(peaks, dtype=np.float64).reshape(-1, 3)
    ir, ia, k = np.rint(p[:, 0]).astype(int), np.rint(p[:, 1]).astype(int), p[:, 2].astype(int)
    ok = (ir >= 0) & (ir < h) & (ia >= 0) & (ia < w)
    out[k[ok], ir[ok], ia[ok]] = 1.0
    return out


def grid_targets(peaks: np.ndarray, shape: tuple[int, int], stride: tuple[int, int]) -> np.ndarray:
    """Grid labels (6, H/s_r, W/s_a) float32 for a detection head with output stride ``stride``.

    Channels 0–1: occupancy of grid cell (i, j) by a LOS / mNLOS point; 2–3 (LOS) and 4–5
    (mNLOS): the (range, azimuth) position in [0, 1) of the point inside its cell,
    ((r + ½)/s_r − i, (a + ½)/s_a − j) — grid cell i covers fine cells [i·s − ½, (i+1)·s − ½).
    One object per cell and class: where several share one, the point nearest the cell centre.
    """
    sr, sa = stride
    gh, gw = shape[0] // sr, shape[1] // sa
    out = np.zeros((6, gh, gw), dtype=np.float32)
    best = np.full((2, gh, gw), np.inf)
    for r, a, k in np.asarray(peaks, dtype=np.float64).reshape(-1, 3):
        gr, ga, k = (r + 0.5) / sr, (a + 0.5) / sa, int(k)
        i, j = int(np.floor(gr)), int(np.floor(ga))
        if not (0 <= i < gh and 0 <= j < gw):
            continue
        d = (gr - i - 0.5) ** 2 + (ga - j - 0.5) ** 2
        out[k, i, j] = 1.0
        if d < best[k, i, j]:
            best[k, i, j] = d
            out[2 + 2 * k, i, j], out[3 + 2 * k, i, j] = gr - i, ga - j
    return out
