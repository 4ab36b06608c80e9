"""Input checks and preparation shared by the NLOS solvers: what LCT and f-k both need from a
:class:`xnlos_core.transient.TransientVolume` (a square scan grid, enough time bins, some counts,
bins that start at round trip t = 0)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.nlos_volume import NLOSVolume
from xnlos_core.transient import TransientVolume

MIN_BINS = 8  # fewer time bins cannot hold a return and its kernel


@dataclass(frozen=True)
class Prepared:
    """data (M, N, N) of ``dtype``, bin 0 at round trip t = 0; dx, dy [m] scan spacing along x (W)
    and y (H); bin_length [m] = c·bin_width, the round-trip path per bin."""

    data: np.ndarray
    dx: float
    dy: float
    bin_length: float
    wall_width: float
    wall_height: float

    def result(self, albedo: np.ndarray) -> NLOSVolume:
        """Wrap an (M, N, N) albedo: depth z_k = k·bin_length/2 [m] (z = c·t/2)."""
        z = np.arange(albedo.shape[0]) * (self.bin_length / 2)
        return NLOSVolume(np.maximum(albedo, 0.0).astype(np.float64, copy=False), z,
                          self.wall_width, self.wall_height)


def prepare(volume: TransientVolume, solver: str, dtype=np.float32) -> Prepared:
    """Check ``volume`` for ``solver`` (its name, for the messages) and return it as :class:`Prepared`.

    t0 ≠ 0 is a whole number of bins: a positive t0 prepends that many empty bins, a negative one
    drops them, so that bin k is round trip k·bin_width. Raises InputError naming the input for a
    volume that is not a TransientVolume, a non-square grid (H ≠ W), fewer than MIN_BINS bins,
    all-zero counts, or a t0 that is not a whole number of bins.
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
    shift = volume.t0 / volume.bin_width
    n0 = int(round(shift))
    if abs(shift - n0) > 1e-6:
        raise InputError(f"{who}: volume.t0 = {volume.t0:g} s is not a whole number of bins "
                         f"(bin_width {volume.bin_width:g} s); {solver} needs bins aligned with t = 0")
    data = volume.data
    if n0 > 0:
        data = np.concatenate([np.zeros((n0, h, w)), data])
    elif n0 < 0:
        data = data[-n0:]
    if data.shape[0] < MIN_BINS:
        raise InputError(f"{who}: volume.data has {data.shape[0]} time bins from t = 0 (T = {t}, t0 = "
                         f"{volume.t0:g} s); expected at least {MIN_BINS}")
    if not np.any(data > 0):
        raise InputError(f"{who}: volume.data holds no counts (all zero from t = 0); nothing to reconstruct")
    return Prepared(np.ascontiguousarray(data, dtype=dtype), volume.wall_width / w, volume.wall_height / h,
                    volume.bin_length, volume.wall_width, volume.wall_height)
