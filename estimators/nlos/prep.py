"""Input checks and preparation shared by the NLOS solvers: what LCT and f-k both need from a
:class:`xnlos_core.transient.TransientVolume` (a square scan grid, enough time bins, some counts,
bins that start at round trip t = 0), and the checks of their result.

Bounds (InputError naming the input, its value and the range; TransientVolume itself already
refuses NaN, inf, negative counts and non-positive sizes):

* ``bin_width`` within [MIN_BIN_WIDTH, MAX_BIN_WIDTH] = [1 fs, 1 µs]: a path per bin from 0.3 µm to
  300 m, wider than any SPAD's (≈ 1–100 ps) or radar's (≈ 1 ns) bins; beyond it the kernels' squared
  depths under- or overflow;
* ``wall_width``, ``wall_height`` within [MIN_WALL, MAX_WALL] = [1 µm, 20 km] (the scene spans
  ±:data:`xnlos_core.scene.MAX_COORD`);
* ``t0`` within ±MAX_T0 = 2·10 km / c ≈ 66.7 µs, the round trip to the scene's bound, and the bins
  from t = 0 that a positive t0 pads the volume to at most MAX_BINS (16384, four times a 4096-bin
  SPAD histogram): each padded bin costs the solvers (2N)² complex cells of memory.

Dynamic range: the solvers work in float32 by default, whose normal range (≈ 10⁻³⁸ … 3·10³⁸) is far
narrower than the counts a TransientVolume may hold (any finite float64 ≥ 0). :func:`prepare` divides
the counts by a power of four s near their largest value and :meth:`Prepared.result` multiplies the
albedo by s again (in float64): both solvers' albedo is linear in the counts, and a power of four
passes through the square root of f-k, the FFTs and the interpolation exactly, so results in the
working range are unchanged bit for bit while counts of 10⁻³⁰⁰ or 10³⁰⁰ no longer underflow to an
all-zero albedo or overflow to NaN. An albedo that is zero everywhere although the volume holds
counts (or that overflows float64 once scaled back) is refused, naming the cause, instead of
being returned silently.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.nlos_volume import NLOSVolume
from xnlos_core.scene import MAX_COORD
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume

MIN_BINS = 8  # fewer time bins cannot hold a return and its kernel
MAX_BINS = 16384  # time bins from t = 0 that a positive t0 may pad a volume to (module docstring)
MIN_BIN_WIDTH, MAX_BIN_WIDTH = 1e-15, 1e-6  # [s]
MIN_WALL, MAX_WALL = 1e-6, 2 * MAX_COORD  # [m] scan-grid extent
MAX_T0 = 2 * MAX_COORD / SPEED_OF_LIGHT  # [s] round trip to 10 km


@dataclass(frozen=True)
class Prepared:
    """data (M, N, N) of ``dtype``, bin 0 at round trip t = 0, divided by ``scale`` (a power of four,
    module docstring); dx, dy [m] scan spacing along x (W) and y (H); bin_length [m] = c·bin_width,
    the round-trip path per bin; ``who`` names the solver's call in errors, ``peak`` is the largest
    count of the volume."""

    data: np.ndarray
    dx: float
    dy: float
    bin_length: float
    wall_width: float
    wall_height: float
    scale: float = 1.0
    who: str = "reconstruct(volume)"
    peak: float = 1.0

    def result(self, albedo: np.ndarray) -> NLOSVolume:
        """Wrap an (M, N, N) albedo of the scaled data: clipped at 0, times ``scale`` in float64;
        depth z_k = k·bin_length/2 [m] (z = c·t/2). InsufficientDataError when it is zero everywhere,
        InputError when it is not finite (module docstring)."""
        z = np.arange(albedo.shape[0]) * (self.bin_length / 2)
        out = np.maximum(albedo, 0.0).astype(np.float64, copy=False)
        if not np.all(np.isfinite(out)):
            raise InputError(f"{self.who}: the reconstruction of volume.data (largest count {self.peak:.6g}) is not "
                             "finite; expected finite counts and geometry within the solver's bounds")
        with np.errstate(over="ignore", under="ignore"):
            out = out * self.scale
        if not np.all(np.isfinite(out)):
            raise InputError(f"{self.who}: volume.data holds counts up to {self.peak:.6g}, and the albedo they give "
                             "overflows float64; scale the counts down (only relative albedo values mean anything)")
        if not out.any():
            low = float(np.min(albedo))
            why = (f"every reconstructed value is ≤ 0 (least {low:.3g}) and clipped: the deconvolution amplified "
                   "rounding or noise over the signal (lower LCT's snr, or use dtype float64)" if low < 0 else
                   "the signal is below what float64 resolves or below the regularisation (LCT's 1/snr), or all "
                   "counts lie at round trip t = 0, which the fall-off compensation weights by 0")
            raise InsufficientDataError(f"{self.who}: the albedo is zero everywhere although volume.data holds "
                                        f"counts (largest {self.peak:.6g}): {why}")
        return NLOSVolume(out, z, self.wall_width, self.wall_height)


def _power_of_four(peak: float) -> float:
    """A power of four s with peak/s in [1/4, 1) (s ≤ 2¹⁰²² for the largest floats)."""
    _, e = np.frexp(peak)
    return float(np.ldexp(1.0, min(int(e) + (int(e) & 1), 1022)))


def prepare(volume: TransientVolume, solver: str, dtype=np.float32) -> Prepared:
    """Check ``volume`` for ``solver`` (its name, for the messages) and return it as :class:`Prepared`.

    t0 ≠ 0 is a whole number of bins: a positive t0 prepends that many empty bins, a negative one
    drops them, so that bin k is CENTRED at round trip k·bin_width (the project's one depth-bin
    convention, ``sims/spad/transport.py``), and :meth:`Prepared.result` puts it at depth
    z_k = k·c·bin_width/2. Raises InputError naming the input for a
    volume that is not a TransientVolume, a non-square grid (H ≠ W), fewer than MIN_BINS bins,
    all-zero counts, a t0 that is not a whole number of bins, or a bin width, wall size or t0
    beyond the bounds of the module docstring.
    """
    who = f"{solver}.reconstruct(volume)"
    if not isinstance(volume, TransientVolume):
        raise InputError(f"{who}: expected a xnlos_core.transient.TransientVolume, got {type(volume).__name__}")
    t, h, w = volume.shape
    if h != w:
        raise InputError(f"{who}: volume.data has a non-square scan grid H × W = {h} × {w}; "
                         f"{solver} needs H == W")
    if h < 2:
        raise InputError(f"{who}: volume.data has a {h} × {w} scan grid; expected at least 2 × 2")
    if not MIN_BIN_WIDTH <= volume.bin_width <= MAX_BIN_WIDTH:
        raise InputError(f"{who}: volume.bin_width = {volume.bin_width:g} s; expected {MIN_BIN_WIDTH:g} … "
                         f"{MAX_BIN_WIDTH:g} s (a path of {SPEED_OF_LIGHT * MIN_BIN_WIDTH:.3g} … "
                         f"{SPEED_OF_LIGHT * MAX_BIN_WIDTH:.3g} m per bin)")
    for name in ("wall_width", "wall_height"):
        v = getattr(volume, name)
        if not MIN_WALL <= v <= MAX_WALL:
            raise InputError(f"{who}: volume.{name} = {v:g} m; expected {MIN_WALL:g} … {MAX_WALL:g} m")
    if abs(volume.t0) > MAX_T0:
        raise InputError(f"{who}: volume.t0 = {volume.t0:g} s; expected within ±{MAX_T0:.4g} s (the round trip "
                         f"to {MAX_COORD:g} m, the scene bound)")
    shift = volume.t0 / volume.bin_width
    n0 = int(round(shift))
    if abs(shift - n0) > 1e-6:
        raise InputError(f"{who}: volume.t0 = {volume.t0:g} s is not a whole number of bins "
                         f"(bin_width {volume.bin_width:g} s); {solver} needs bins aligned with t = 0")
    if n0 > 0 and n0 + t > max(MAX_BINS, t):
        raise InputError(f"{who}: volume.t0 = {volume.t0:g} s is {n0} bins of {volume.bin_width:g} s, which would "
                         f"pad the {t} bins to {n0 + t} from t = 0; expected at most {MAX_BINS} (crop the empty "
                         "bins before the returns, or use wider bins)")
    data = volume.data
    if n0 > 0:
        data = np.concatenate([np.zeros((n0, h, w)), data])
    elif n0 < 0:
        data = data[-n0:]
    if data.shape[0] < MIN_BINS:
        raise InputError(f"{who}: volume.data has {data.shape[0]} time bins from t = 0 (T = {t}, t0 = "
                         f"{volume.t0:g} s); expected at least {MIN_BINS}")
    peak = float(data.max())
    if not peak > 0:
        raise InputError(f"{who}: volume.data holds no counts (all zero from t = 0); nothing to reconstruct")
    scale = _power_of_four(peak)
    return Prepared(np.ascontiguousarray(data / scale, dtype=dtype), volume.wall_width / w, volume.wall_height / h,
                    volume.bin_length, volume.wall_width, volume.wall_height, scale, who, peak)
