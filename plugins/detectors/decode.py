"""Network outputs → peaks: local maxima with greedy suppression and sub-bin refinement.

Dense confidence maps c = σ(z) (2, H, W): a peak is a cell whose logit is the maximum of its
``window`` neighbourhood and whose confidence exceeds ``threshold``; candidates are then kept
greedily by descending confidence, dropping any within the window of a kept one (of the same
class, or of either class with ``class_nms``: a cell is LOS or mNLOS, not both). Equal logits
are ordered by raster position, so a plateau yields one peak per window, not one per cell.

Resolution-cell suppression (``cells``, applied by :func:`.learned.detections_from_output` after
refinement): of the peaks that fall into one radar resolution cell (δr = c/2B in range, the −3 dB
beamwidth in azimuth: :func:`xnlos_core.metrics.resolution_groups`), only the most confident is
kept, so a detector reports at most one point per cell and class, the density at which the
ground truth is defined (:func:`xnlos_core.metrics.thin_to_resolution`). With window (1, 1) every
cell above threshold is a candidate and the resolution cell alone decides: along an extended echo
(a wall) the heatmap's ridge then yields one point per cell it crosses.

Sub-bin refinement (the paper's angular upsampling, Sec. 4), per axis, from the peak's two
neighbours c₋, c₊:

* ``"gaussian"``: for a Gaussian of width σ centred at offset δ from the peak cell (the training
  target of :mod:`.heatmaps`), log c₊ − log c₋ = 2δ/σ², so δ = σ²(log c₊ − log c₋)/2. Exact for
  the target whatever the value at the peak cell itself.
* ``"parabolic"``: vertex of the parabola through (log c₋, log c₀, log c₊) (any peak shape).

δ is clipped to ±½ cell; peaks on a border are not refined along that axis. ``"none"`` keeps the
cell centres (the raw grid, for comparison).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from .peaks import parabolic_offset


def _log_sigmoid(z: np.ndarray) -> np.ndarray:
    return -np.logaddexp(0.0, -z)


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return np.exp(_log_sigmoid(z))


def local_peaks(logits: np.ndarray, threshold: float, window: tuple[int, int], class_nms: bool,
                max_peaks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer peaks (rows (K,), cols (K,), class (K,)) of logits (C, H, W), by descending confidence."""
    z = np.asarray(logits, dtype=np.float64)
    zt = np.log(threshold) - np.log1p(-threshold)  # c > threshold ⇔ z > logit(threshold)
    if tuple(window) == (1, 1):  # every cell above threshold (vectorised; no neighbourhood to suppress)
        cand = z > zt
        if class_nms:  # a cell is LOS or mNLOS: the larger logit wins (ties: the lower class)
            best = np.argmax(z, axis=0)
            cand &= np.arange(z.shape[0])[:, None, None] == best[None]
        k, r, a = np.nonzero(cand)
        order = np.argsort(-z[k, r, a], kind="stable")[:max_peaks]
        return r[order], a[order], k[order]
    # Ties (plateaus) broken by raster order: a ramp far below any meaningful logit difference.
    ramp = np.arange(z[0].size, dtype=np.float64).reshape(z.shape[1:]) * (1e-12 * max(1.0, float(np.abs(z).max())))
    zr = z + ramp
    cand = (zr >= ndimage.maximum_filter(zr, size=(1,) + tuple(window), mode="constant", cval=-np.inf)) & (z > zt)
    k, r, a = np.nonzero(cand)
    if len(k) == 0:
        return r, a, k
    order = np.argsort(-zr[k, r, a], kind="stable")
    k, r, a = k[order], r[order], a[order]
    hr, ha = window[0] // 2, window[1] // 2
    taken = np.zeros((1 if class_nms else z.shape[0],) + z.shape[1:], dtype=bool)
    keep = []
    for i in range(len(k)):
        m = 0 if class_nms else k[i]
        sl = (m, slice(max(r[i] - hr, 0), r[i] + hr + 1), slice(max(a[i] - ha, 0), a[i] + ha + 1))
        if taken[sl].any():
            continue
        taken[m, r[i], a[i]] = True
        keep.append(i)
        if len(keep) >= max_peaks:
            break
    keep = np.asarray(keep, dtype=np.int64)
    return r[keep], a[keep], k[keep]


def one_per_cell(groups: np.ndarray, confidence: np.ndarray) -> np.ndarray:
    """Indices (ascending) of the most confident peak of each group (e.g. each radar resolution
    cell, :func:`xnlos_core.metrics.resolution_groups`); ties: the earlier peak."""
    groups = np.asarray(groups)
    if len(groups) == 0:
        return np.empty(0, dtype=np.int64)
    order = np.argsort(-np.asarray(confidence, dtype=np.float64), kind="stable")
    _, first = np.unique(groups[order], return_index=True)
    return np.sort(order[first])


def refine(logits: np.ndarray, rows: np.ndarray, cols: np.ndarray, label: np.ndarray, mode: str,
           sigma: tuple[float, float] = (1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Fractional (rows, cols) of integer peaks of logits (C, H, W) (module doc for ``mode``)."""
    if mode == "none":  # the raw grid (for comparisons)
        return rows.astype(np.float64), cols.astype(np.float64)
    logc = _log_sigmoid(np.asarray(logits, dtype=np.float64))
    _, h, w = logc.shape
    fr, fc = rows.astype(np.float64), cols.astype(np.float64)
    for axis, (n, s, frac) in enumerate(((h, sigma[0], fr), (w, sigma[1], fc))):
        idx = rows if axis == 0 else cols
        inner = (idx > 0) & (idx < n - 1)
        k, r, a = label[inner], rows[inner], cols[inner]
        dr, da = (1, 0) if axis == 0 else (0, 1)
        lm, l0, lp = logc[k, r - dr, a - da], logc[k, r, a], logc[k, r + dr, a + da]
        if mode == "gaussian":
            d = np.clip(0.5 * s * s * (lp - lm), -0.5, 0.5)
        else:
            d = parabolic_offset(lm, l0, lp)
        frac[inner] += d
    return fr, fc


def dense_peaks(logits: np.ndarray, threshold: float, window: tuple[int, int], class_nms: bool,
                max_peaks: int, mode: str, sigma: tuple[float, float]):
    """Peaks of dense logits (2, H, W): (fractional rows, fractional cols, class, confidence)."""
    r, a, k = local_peaks(logits, threshold, window, class_nms, max_peaks)
    conf = _sigmoid(np.asarray(logits, dtype=np.float64)[k, r, a])
    fr, fc = refine(logits, r, a, k, mode, sigma)
    return fr, fc, k, conf


def grid_peaks(out: np.ndarray, stride: tuple[int, int], threshold: float, class_nms: bool, max_peaks: int):
    """Peaks of a grid head (6, H/s_r, W/s_a): every cell whose class confidence exceeds
    ``threshold`` is one point at its regressed position (fine cell = (i + σ(o)) · s − ½);
    with ``class_nms`` a cell keeps only its more confident class."""
    o = np.asarray(out, dtype=np.float64)
    conf = _sigmoid(o[:2])
    hit = conf > threshold
    if class_nms:
        hit &= conf >= conf[::-1]  # keep the larger of LOS / mNLOS (ties: both)
        hit[1] &= ~hit[0]
    k, i, j = np.nonzero(hit)
    c = conf[k, i, j]
    order = np.argsort(-c, kind="stable")[:max_peaks]
    k, i, j, c = k[order], i[order], j[order], c[order]
    pr = _sigmoid(o[2 + 2 * k, i, j])
    pa = _sigmoid(o[3 + 2 * k, i, j])
    return (i + pr) * stride[0] - 0.5, (j + pa) * stride[1] - 0.5, k, c
