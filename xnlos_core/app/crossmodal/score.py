"""Scoring of the cross-modality study (paper Sec. 5.1.2, Fig. 5): did a modality
detect and reconstruct THE hidden object of one trial, and the F1 rate over trials.

One trial = one modality, one distance, one seed (one radar frame, one SPAD scan). Each trial
yields booleans:

* ``tp``: some report lies within the tolerance of the hidden object's truth;
* ``fp``: some report lies outside it (a spurious hidden object);
* ``fn``: no report lies within it (``not tp``).

Over n trials, F1 = 2·ΣTP / (2·ΣTP + ΣFP + ΣFN) (:func:`f1_rate`): a rate, 1 when every trial
found the object and nothing else, 0.5 e.g. when half the trials found it cleanly and the rest
reported nothing.

What a "report" and the "truth" are per modality and stage (all distances in metres):

* radar detection: every mNLOS detection, at (r cos θ, r sin θ) [m]; truth: the object's outline
  mirrored across the TRUE relay wall (its virtual image, Eq. 7); within ``gate`` of it.
* radar reconstruction: every hidden point (HiddenPoints.mean, BEV) of the reconstructor; truth:
  the object's outline (top view; a point inside the box is at distance 0); within ``tolerance``.
* SPAD detection: the summed transient h(t) = Σ_scan counts (T,), background b = median(h),
  box-filtered excess e = Σ_w (h − b) over ``window`` bins; reported when max e > k·√(w·b)
  (Poisson, k = ``n_sigma``), at range ρ = c·t/2 of the window's centre bin (bin k centred at
  t0 + kΔ, the convention of ``sims/spad/transport.py`` and the solvers); truth: the interval
  [min, max] of |p − s| over truth points p and scan points s (confocal round trip 2|p − s|),
  widened by ``gate``.
* SPAD reconstruction: the NLOS volume's peak voxel (x, y, z) in wall coordinates over the
  search region ``first_bounce_gate`` ≤ z ≤ ρ + ``gate`` (:func:`volume_peak`). The lower bound
  gates the first bounce: depths next to the relay wall hold the wall's own return in real data and
  the solvers' boundary artefacts (the t⁴ / t² fall-off compensation and the Wiener or Stolt
  filters ring at t = 0); the upper bound, nothing returns from beyond the detected range (the
  solvers' fall-off compensation lifts far-depth photon noise above any real return). The peak
  counts only as a reconstruction when it is an INTERIOR maximum of that region: not on its first
  or last depth slice and not on the scan grid's outer ring of columns and rows (the aperture's
  edge). A maximum on the region's boundary means the albedo still grows toward the boundary —
  noise amplified by the compensation, or an edge artefact — and is scored as a wrong report
  (fp and fn), never as a hit. Reported only when the detection above reported something
  (otherwise the peak is noise). Truth: the hidden surface patches VISIBLE from the scan aperture
  (those that return light to at least one scan point, occlusion included: the transient model's
  ``truth``), not every point of the object — the far side of a car, never seen, cannot confirm a
  peak; within ``tolerance`` [m] of the nearest visible patch centre (3-D distance).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT


@dataclass(frozen=True)
class Outcome:
    """One trial's verdict: tp, fp, fn (booleans, see the module docstring) and the number of reports."""

    tp: bool
    fp: bool
    fn: bool
    n_reports: int = 0

    def as_dict(self) -> dict:
        return {"tp": self.tp, "fp": self.fp, "fn": self.fn, "n_reports": self.n_reports}


def outcome(distances: np.ndarray, tol: float) -> Outcome:
    """Outcome from each report's distance [m] to the truth (shape (R,)) and the tolerance [m]."""
    d = np.asarray(distances, float).reshape(-1)
    if np.any(np.isnan(d)):
        raise InputError("outcome(distances): expected distances without NaN")
    hit = bool(np.any(d <= tol))
    return Outcome(tp=hit, fp=bool(np.any(d > tol)), fn=not hit, n_reports=int(d.size))


def f1_rate(outcomes) -> float | None:
    """F1 = 2TP / (2TP + FP + FN) over trials (dicts or :class:`Outcome`); None for no trials."""
    tp = fp = fn = 0
    n = 0
    for o in outcomes:
        o = o.as_dict() if isinstance(o, Outcome) else o
        tp += bool(o["tp"])
        fp += bool(o["fp"])
        fn += bool(o["fn"])
        n += 1
    if n == 0:
        return None
    den = 2 * tp + fp + fn
    return 2 * tp / den if den else 0.0


def max_range(distances, f1s, threshold: float = 0.5) -> float | None:
    """Largest distance [m] whose F1 ≥ ``threshold`` (None where none reaches it)."""
    ok = [float(d) for d, f in zip(distances, f1s) if f is not None and f >= threshold]
    return max(ok) if ok else None


def outline_points(footprint: np.ndarray, spacing: float = 0.1) -> np.ndarray:
    """Points (K, 2) [m] along a closed polygon footprint (N, 2) at most ``spacing`` apart (a
    single point for N = 1)."""
    fp = np.asarray(footprint, float).reshape(-1, 2)
    if len(fp) == 1:
        return fp
    out = []
    for a, b in zip(fp, np.roll(fp, -1, axis=0)):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + (b - a) * (np.arange(k) / k)[:, None])
    return np.concatenate(out)


def _inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd rule: which points (R, 2) lie inside the polygon (N ≥ 3, 2)."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    return (np.sum(cross & (x < xi), axis=1) % 2) == 1


def distance_to_footprint(points, footprint) -> np.ndarray:
    """Distance [m] from each point (R, 2) to a footprint (N, 2): 0 inside a polygon (N ≥ 3), else to
    its nearest edge; to the point itself for N = 1."""
    p = np.asarray(points, float).reshape(-1, 2)
    fp = np.asarray(footprint, float).reshape(-1, 2)
    if len(p) == 0:
        return np.zeros(0)
    if len(fp) == 1:
        return np.linalg.norm(p - fp[0], axis=1)
    a, b = fp, np.roll(fp, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("rnk,nk->rn", p[:, None] - a[None], ab) / np.maximum(np.sum(ab**2, 1), 1e-300), 0, 1)
    d = np.linalg.norm(p[:, None] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    if len(fp) >= 3:
        d[_inside(p, fp)] = 0.0
    return d


def mirror_points(points, start, end) -> np.ndarray:
    """Points (K, 2) mirrored across the line through wall ``start``, ``end`` (Eq. 7, top view)."""
    p = np.asarray(points, float).reshape(-1, 2)
    a, b = np.asarray(start, float), np.asarray(end, float)
    u = (b - a) / np.linalg.norm(b - a)
    n = np.array([-u[1], u[0]])
    return p - 2 * ((p - a) @ n)[:, None] * n


def radar_detection(det_xy, image_outline, gate: float) -> Outcome:
    """Radar detection trial: mNLOS detections (R, 2) [m] against the virtual image's outline (K, 2)."""
    det_xy = np.asarray(det_xy, float).reshape(-1, 2)
    img = np.asarray(image_outline, float).reshape(-1, 2)
    d = np.linalg.norm(det_xy[:, None] - img[None], axis=2).min(axis=1) if len(det_xy) else np.zeros(0)
    return outcome(d, gate)


def radar_reconstruction(hidden_xy, footprint, tolerance: float) -> Outcome:
    """Radar reconstruction trial: hidden points (R, 2) [m] against the object's footprint."""
    return outcome(distance_to_footprint(hidden_xy, footprint), tolerance)


@dataclass(frozen=True)
class TransientPeak:
    """SPAD detection statistic: detected (bool), range ρ [m] of the peak window's centre, excess
    counts over background in the window, threshold k·√(w·b), background b per bin."""

    detected: bool
    range: float
    excess: float
    threshold: float
    background: float


def transient_peak(data: np.ndarray, bin_width: float, t0: float = 0.0, window: int = 5,
                   n_sigma: float = 5.0) -> TransientPeak:
    """The SPAD detection test of the module docstring on a (T, H, W) count volume."""
    d = np.asarray(data, float)
    if d.ndim != 3 or not np.all(np.isfinite(d)):
        raise InputError(f"transient_peak(data): expected a finite (T, H, W) volume, got shape {d.shape}")
    if window < 1:
        raise InputError(f"transient_peak(window): expected ≥ 1 bin, got {window}")
    h = d.sum(axis=(1, 2))
    b = float(np.median(h))
    e = uniform_filter1d(h - b, size=window, mode="constant") * window
    k = int(np.argmax(e))
    thr = n_sigma * np.sqrt(window * max(b, 1.0))
    rho = SPEED_OF_LIGHT * (t0 + k * bin_width) / 2  # bin k centred at t0 + kΔ (sims/spad/transport.py)
    return TransientPeak(bool(e[k] > thr), float(rho), float(e[k]), float(thr), b)


def range_interval(truth_xyz, scan_x, scan_y) -> tuple[float, float]:
    """[min, max] over truth points (P, 3) and scan points (x, y, 0) of |p − s| [m]."""
    p = np.asarray(truth_xyz, float).reshape(-1, 3)
    sx, sy = np.meshgrid(np.asarray(scan_x, float), np.asarray(scan_y, float))
    s = np.stack([sx.ravel(), sy.ravel(), np.zeros(sx.size)], axis=1)
    r = np.linalg.norm(p[:, None] - s[None], axis=2)
    return float(r.min()), float(r.max())


def spad_detection(peak: TransientPeak, interval: tuple[float, float], gate: float) -> Outcome:
    """SPAD detection trial: the peak's range against the truth's range interval widened by ``gate``."""
    if not peak.detected:
        return Outcome(False, False, True, 0)
    lo, hi = interval
    d = max(lo - peak.range, peak.range - hi, 0.0)
    return outcome(np.array([d]), gate)


@dataclass(frozen=True)
class VolumePeak:
    """Peak voxel of an NLOS albedo volume in wall coordinates: x, y, z [m]; ``interior``: the peak
    is not on the boundary of the search region (:func:`volume_peak`)."""

    x: float
    y: float
    z: float
    interior: bool

    @property
    def xyz(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)


def volume_peak(albedo: np.ndarray, z: np.ndarray, grid: tuple[np.ndarray, np.ndarray],
                max_depth: float, min_depth: float = 0.0) -> VolumePeak:
    """Maximum of ``albedo`` (Z, H, W) over depths ``min_depth`` ≤ z ≤ ``max_depth`` [m]; ``grid`` =
    (x (W,), y (H,)) of the volume, ``z`` (Z,) its depths [m].

    ``interior`` is False when the peak lies on the search region's boundary: the first or last
    depth slice inside [min_depth, max_depth], or column 0 / W − 1 or row 0 / H − 1 of the scan
    grid (the aperture's edge; module docstring). Raises InputError for mismatched shapes or an
    empty depth range (no slice in [min_depth, max_depth])."""
    a = np.asarray(albedo, float)
    z = np.asarray(z, float)
    x, y = (np.asarray(v, float) for v in grid)
    if a.ndim != 3 or a.shape != (len(z), len(y), len(x)):
        raise InputError(f"volume_peak(albedo): expected shape (len(z), len(y), len(x)) = "
                         f"{(len(z), len(y), len(x))}, got {a.shape}")
    keep = np.flatnonzero((z >= min_depth) & (z <= max_depth))
    if not len(keep):
        raise InputError(f"volume_peak(min_depth, max_depth): no depth slice in [{min_depth:g}, {max_depth:g}] m; "
                         f"the volume's depths span [{z[0]:g}, {z[-1]:g}] m")
    sub = a[keep[0]:keep[-1] + 1]
    k, i, j = np.unravel_index(int(np.argmax(sub)), sub.shape)
    h, w = sub.shape[1:]
    interior = bool(0 < k < len(keep) - 1 and 0 < i < h - 1 and 0 < j < w - 1)
    return VolumePeak(float(x[j]), float(y[i]), float(z[keep[0] + k]), interior)


def spad_reconstruction(peak: VolumePeak, visible_xyz, tolerance: float, reported: bool) -> Outcome:
    """SPAD reconstruction trial: the volume's peak against the visible hidden-surface points
    (P, 3) [m]: a hit when the detection reported, the peak is interior and within ``tolerance``
    [m] of a visible point; a boundary peak is a wrong report (module docstring)."""
    if not reported:
        return Outcome(False, False, True, 0)
    if not peak.interior:
        return Outcome(False, True, True, 1)
    t = np.asarray(visible_xyz, float).reshape(-1, 3)
    if not len(t):  # nothing visible: any report is spurious
        return Outcome(False, True, True, 1)
    d = np.linalg.norm(t - np.asarray(peak.xyz, float).reshape(1, 3), axis=1).min(keepdims=True)
    return outcome(d, tolerance)
