"""Shared CFAR and peak-extraction helpers for the classical detectors.

Cell-averaging CFAR (CA-CFAR) on linear power P = |κ|² of an RA map (n_range, n_azimuth):
for every cell under test the noise level is the mean of the N training cells in a rectangular
ring around it (guard cells excluded), and the cell is declared a target when

    P > a(N) · mean_train = (Pfa^(−1/N) − 1) · Σ_train P,        a(N) = N·(Pfa^(−1/N) − 1).

For independent exponentially distributed noise power (complex Gaussian κ) this gives exactly
the false-alarm probability Pfa, since P(X > a·S/N) = (1 + a/N)^(−N) with S ~ Gamma(N, 1).

Edge handling: only *valid* training cells are counted. Cells outside the map and cells excluded
by a ``valid`` mask (e.g. the leakage below ``min_range``) contribute neither power nor count, so
N varies per cell near the borders and a(N) is evaluated with each cell's actual N (the false
alarm rate stays Pfa everywhere).

Window sums (:func:`box_sum`): the ring is four rectangles (bands above and below the guard
block, pieces left and right of it), each a separable box, so the sums only ever *add*
non-negative numbers. A running-sum or cumulative-sum difference (``scipy.ndimage.uniform_filter``,
summed-area tables) would cancel catastrophically next to strong peaks with 200 dB of dynamic
range, and a direct correlation with the ring kernel (``scipy.ndimage.correlate``) costs
O(H·W·kernel area) (formerly 63 s per frame at train_cells (128, 128), a MemoryError at (160, 160)).
:func:`box_sum` is the van Herk / Gil-Werman block trick (usually used for running maxima) applied
to sums: cumulative sums within blocks of the window length, so each window sum is one suffix sum
plus one prefix sum — O(H·W) whatever the window, with the rounding of a direct sum (relative error
≤ window·ε). scipy has no cancellation-free running sum, hence this hand-written one.

Window size: the CFAR window, 2·(guard + train) + 1 cells along each axis, must fit in the map
(:func:`window_error`): a ring wider than the map has no training cells on at least one side of
every cell, so its noise estimate would not be the one configured.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from plugins.detectors.detection_doppler import with_cell_velocity
from xnlos_core.errors import InputError
from xnlos_core.numerics import EPS, PEAK_RTOL
from xnlos_core.types import UNCLASSIFIED, Detections, RAMap


def _check_cells(guard, train) -> None:
    (gr, ga), (tr, ta) = guard, train
    if min(gr, ga, tr, ta) < 0 or tr + ta == 0:
        raise InputError(f"CFAR cells: guard {guard} and train {train} must be ≥ 0 with at least one "
                         "training cell along some axis")


def ring_kernel(guard: tuple[int, int], train: tuple[int, int]) -> np.ndarray:
    """CA-CFAR training kernel, shape (2(g_r+t_r)+1, 2(g_a+t_a)+1): ones on the training ring,
    zeros on the guard cells and the cell under test. ``guard``/``train`` are (range, azimuth)."""
    _check_cells(guard, train)
    (gr, ga), (tr, ta) = guard, train
    k = np.ones((2 * (gr + tr) + 1, 2 * (ga + ta) + 1))
    k[tr:tr + 2 * gr + 1, ta:ta + 2 * ga + 1] = 0.0
    return k


def window_error(guard, train, shape: tuple[int, int], where: str) -> str | None:
    """Why the CFAR window (2·(guard + train) + 1 cells per axis) does not fit a map of ``shape``
    (n_range, n_azimuth) [bins], naming the parameter, its value, the map size and the largest value
    allowed; None when it fits. ``where`` names the map in the message."""
    for axis, name in enumerate(("range", "azimuth")):
        g, t, n = int(guard[axis]), int(train[axis]), int(shape[axis])
        if 2 * (g + t) + 1 > n:
            return (f"train_cells = {tuple(train)}, guard_cells = {tuple(guard)}: the CFAR window along "
                    f"{name} is 2·({t} + {g}) + 1 = {2 * (g + t) + 1} cells but {where} has {n} {name} bins; "
                    f"2·(train + guard) + 1 must be ≤ {n}, so train_cells[{axis}] + guard_cells[{axis}] ≤ "
                    f"{(n - 1) // 2}" + (f" (train_cells[{axis}] ≤ {(n - 1) // 2 - g} with guard_cells[{axis}] = {g})"
                                         if (n - 1) // 2 >= g else ""))
    return None


def box_sum(x: np.ndarray, lo: int, hi: int, axis: int) -> np.ndarray:
    """y[i] = Σ_{j=i+lo}^{i+hi} x[j] along ``axis`` (zeros outside), same shape as ``x`` (float64).

    O(x.size) for any window length k = hi − lo + 1 and without subtraction (module doc): with x
    cut into blocks of k, a window starting at offset o > 0 of block b is the suffix sum of block b
    from o plus the prefix sum of block b + 1 up to o − 1; at o = 0 it is block b's total."""
    if hi < lo:
        return np.zeros(x.shape, dtype=np.float64)
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, -1)
    n, k = x.shape[-1], hi - lo + 1
    before = max(0, -lo)
    start = np.arange(n) + lo + before  # window starts in the padded array
    n_blocks = -(-max(int(start[-1]) + k, before + n) // k)  # ceil: every window and x fit
    pad = [(0, 0)] * (x.ndim - 1) + [(before, n_blocks * k - n - before)]
    xb = np.pad(x, pad).reshape(x.shape[:-1] + (n_blocks, k))
    prefix = np.cumsum(xb, axis=-1)
    suffix = np.cumsum(xb[..., ::-1], axis=-1)[..., ::-1]
    b, o = np.divmod(start, k)
    nxt = np.minimum(b + 1, n_blocks - 1)
    out = suffix[..., b, o] + np.where(o > 0, prefix[..., nxt, np.maximum(o - 1, 0)], 0.0)
    return np.moveaxis(out, -1, axis)


def ring_sum(x: np.ndarray, guard: tuple[int, int], train: tuple[int, int]) -> np.ndarray:
    """Σ of ``x`` (H, W) over the CA-CFAR training ring of every cell (zeros outside the map):
    the correlation with :func:`ring_kernel`, as four separable boxes in O(H·W) (module doc)."""
    (gr, ga), (tr, ta) = guard, train
    wa = ga + ta
    rows_full = box_sum(x, -wa, wa, axis=1)  # whole window width, for the bands above and below
    rows_guard = box_sum(x, -gr, gr, axis=0)  # guard height, for the pieces left and right
    return (box_sum(rows_full, -(gr + tr), -(gr + 1), axis=0) + box_sum(rows_full, gr + 1, gr + tr, axis=0)
            + box_sum(rows_guard, -wa, -(ga + 1), axis=1) + box_sum(rows_guard, ga + 1, wa, axis=1))


def cfar_scale(n_train, pfa: float) -> np.ndarray:
    """Threshold scale a(N) = N·(Pfa^(−1/N) − 1) of CA-CFAR (dimensionless); N = 0 gives +inf."""
    if not 0.0 < pfa < 1.0:
        raise InputError(f"pfa: must lie in (0, 1), got {pfa}")
    n = np.asarray(n_train, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = n * np.expm1(-np.log(pfa) / n)
    return np.where(n > 0, a, np.inf)


def cfar_threshold(power: np.ndarray, guard: tuple[int, int], train: tuple[int, int], pfa: float,
                   valid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CA-CFAR threshold of a linear power map.

    power: (H, W) ≥ 0; valid: (H, W) bool, cells usable as training cells (default all).
    Returns (threshold (H, W), noise_mean (H, W) = Σ_train P / N, n_train (H, W) int).
    Cells without any valid training cell get threshold = noise_mean = +inf.
    """
    p = np.asarray(power, dtype=np.float64)
    w = np.ones(p.shape) if valid is None else np.asarray(valid, dtype=np.float64)
    _check_cells(guard, train)
    s = ring_sum(p * w, guard, train)
    n = np.rint(ring_sum(w, guard, train)).astype(np.int64)
    a = cfar_scale(n, pfa)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(n > 0, s / np.maximum(n, 1), np.inf)
        thr = np.where(n > 0, a * mean, np.inf)
    return thr, mean, n


def local_maxima(power: np.ndarray, rtol: float = PEAK_RTOL) -> np.ndarray:
    """One cell per local maximum: cells within ``rtol`` (relative) of the largest of their 3×3
    neighbourhood (borders compare only with cells inside), or within ε of the map's largest power of it,
    are peak cells; of each 8-connected group of
    peak cells (a plateau, or two cells equal up to rounding) only the largest is kept, the first in
    raster order among equals. So two adjacent cells whose powers differ in the last bits give one
    detection on every machine, never one on some and two on others (:mod:`xnlos_core.numerics`; the
    sub-bin refinement puts either cell's peak at the same place)."""
    p = np.asarray(power, dtype=np.float64)
    atol = EPS * float(np.abs(p).max(initial=0.0))  # cells at rounding level of the map (zeros) tie too
    near = p >= (1.0 - rtol) * ndimage.maximum_filter(p, size=3, mode="constant", cval=-np.inf) - atol
    labels, n = ndimage.label(near, structure=np.ones((3, 3), bool))
    out = np.zeros(p.shape, bool)
    if n == 0:
        return out
    flat = labels.ravel()
    cells = np.flatnonzero(flat)
    order = np.lexsort((cells, -p.ravel()[cells]))  # largest first, raster order among equals
    _, first = np.unique(flat[cells[order]], return_index=True)
    out.ravel()[cells[order[first]]] = True
    return out


def parabolic_offset(left: np.ndarray, centre: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Sub-bin offset δ ∈ [−½, ½] [bins] of the vertex of the parabola through three samples
    (−1, 0, +1): δ = ½(ℓ₋ − ℓ₊)/(ℓ₋ − 2ℓ₀ + ℓ₊). Exact for a Gaussian peak when ℓ = log power."""
    den = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(den < 0, 0.5 * (left - right) / den, 0.0)
    return np.clip(np.nan_to_num(d), -0.5, 0.5)


def refine_peaks(power: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fractional (row, col) indices of peaks by parabolic interpolation of log power along each
    axis separately; peaks on the map border are not refined along that axis."""
    logp = np.log(np.maximum(np.asarray(power, dtype=np.float64), np.finfo(np.float64).tiny))
    h, w = logp.shape
    fr = rows.astype(np.float64)
    fc = cols.astype(np.float64)
    inr = (rows > 0) & (rows < h - 1)
    inc = (cols > 0) & (cols < w - 1)
    r, c = rows[inr], cols[inr]
    fr[inr] += parabolic_offset(logp[r - 1, c], logp[r, c], logp[r + 1, c])
    r, c = rows[inc], cols[inc]
    fc[inc] += parabolic_offset(logp[r, c - 1], logp[r, c], logp[r, c + 1])
    return fr, fc


def resolution_stds(ra_map: RAMap, azimuth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1-σ measurement errors from the resolution cell: σ = δ/√12 (a uniform error over one cell).

    Range cell δ_r = max(c/2B, range-bin spacing) [m]. Azimuth cell δ_θ = max(λ/(L·cos θ),
    azimuth-bin spacing) [rad], with L = span of the virtual array + one element spacing (the
    Rayleigh width of the beam, which widens as 1/cos θ off boresight). Returns (range_std (K,),
    azimuth_std (K,)).
    """
    radar = ra_map.radar
    dr = max(radar.range_resolution, float(np.median(np.diff(ra_map.range_axis))))
    aperture = float(np.ptp(radar.virtual_positions)) + radar.rx_spacing * radar.wavelength
    cos_t = np.maximum(np.cos(np.asarray(azimuth, dtype=np.float64)), 0.05)
    da = np.maximum(radar.wavelength / (aperture * cos_t), float(np.median(np.diff(ra_map.azimuth_axis))))
    k = len(cos_t)
    return np.full(k, dr / np.sqrt(12.0)), da / np.sqrt(12.0)


def confirmable_columns(shape: tuple[int, int]) -> np.ndarray:
    """(n_azimuth,) bool: the azimuth columns whose cells can be confirmed as local maxima, all but
    the first and the last.

    The azimuth grid ends at ±field_of_view, but the array receives from beyond it (its element
    pattern reaches ±90°): an echo outside the field of view, or one whose beam peaks just past the
    edge, leaves a map that rises monotonically towards the edge column. That column's cell is then
    larger than its only inner neighbour and passes the 3×3 test, although its maximum lies in the
    cell beyond, which the map does not hold; whether an edge cell is a peak cannot be told. So CFAR
    reports no detection on the edge columns (the field of view of its detections is ±(FOV − one
    azimuth bin)); an echo inside, however close to the edge, peaks on an inner column."""
    cols = np.ones(shape[1], bool)
    cols[[0, -1]] = False
    return cols


def cfar_peaks(ra_map: RAMap, pfa: float, guard: tuple[int, int], train: tuple[int, int],
               min_range: float) -> Detections:
    """CA-CFAR detections of an RA map, all labelled UNCLASSIFIED.

    The CFAR window must fit the map (:func:`window_error`; InputError otherwise).
    A detection is a cell with range ≥ ``min_range`` [m] whose power exceeds the CFAR threshold
    and is a 3×3 local maximum, off the first and last azimuth column (:func:`confirmable_columns`:
    an edge cell's maximum may lie beyond the field of view); cells below ``min_range`` are neither
    tested nor used as training cells (edge columns still train). Range/azimuth are refined to sub-bin accuracy (:func:`refine_peaks`, interpolated on
    the map's axes); confidence = 1 − threshold/power ∈ [0, 1) (how far above the threshold the
    peak is; 1 only if all its training cells are exactly zero); stds from
    :func:`resolution_stds`. Detections are ordered by descending power. With Doppler maps on
    ``ra_map`` each detection carries the radial velocity of its peak cell (before refinement,
    :func:`plugins.detectors.detection_doppler.with_cell_velocity`); without, velocity is None.
    """
    if not isinstance(ra_map, RAMap):
        raise InputError(f"cfar_peaks: expected an RAMap, got {type(ra_map).__name__}")
    bad = window_error(guard, train, ra_map.shape, "the RA map")
    if bad:
        raise InputError(f"CFAR: {bad}")
    p = ra_map.power
    valid = np.broadcast_to((ra_map.range_axis >= min_range)[:, None], p.shape)
    thr, _, _ = cfar_threshold(p, guard, train, pfa, valid)
    hit = valid & (p > thr) & local_maxima(p) & confirmable_columns(p.shape)[None, :]
    rows, cols = np.nonzero(hit)
    if rows.size == 0:
        return Detections.empty()
    order = np.argsort(-p[rows, cols], kind="stable")
    rows, cols = rows[order], cols[order]
    fr, fc = refine_peaks(p, rows, cols)
    rng = np.interp(fr, np.arange(p.shape[0]), ra_map.range_axis)
    az = np.interp(fc, np.arange(p.shape[1]), ra_map.azimuth_axis)
    conf = 1.0 - thr[rows, cols] / p[rows, cols]
    rs, azs = resolution_stds(ra_map, az)
    det = Detections(rng, az, np.full(len(rng), UNCLASSIFIED, np.int8), np.clip(conf, 0.0, 1.0), rs, azs)
    return with_cell_velocity(det, ra_map, rows, cols)
