"""Transient (time-resolved) NLOS measurements of the optical modality: the data type shared
by the SPAD forward model (sims), the file readers and writers, and the reconstruction solvers.

Confocal geometry: the laser and the SPAD look at the same point of a planar relay wall. The scan
grid is H × W points on the wall plane, uniform, spanning ``wall_height`` × ``wall_width`` [m]
(centred on the wall's scan origin; row i at height y_i, column j at x_j, :meth:`grid`). A hidden
point at depth z [m] in front of the wall (the hidden side) returns to scan point (x_j, y_i) after
the round trip t = 2·√((x − x_j)² + (y − y_i)² + z²)/c, the wall legs (source → wall, wall →
detector) removed — the usual confocal convention, in which time bin k holds photons of round trip
k·``bin_width``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .types import ReadOnlyArrays, set_attribute
from .validation import as_array

SPEED_OF_LIGHT = 299_792_458.0  # [m/s]


@dataclass(frozen=True, eq=False)
class TransientVolume(ReadOnlyArrays):
    """data (T, H, W) float64 photon counts (or expected counts), ≥ 0 and finite; bin_width [s] of a
    time bin (> 0); wall_width, wall_height [m] the scan grid's extent along W (x) and H (y), > 0;
    t0 [s] the round-trip time at the centre of bin 0 (default 0). Arrays are read-only once validated."""

    data: np.ndarray
    bin_width: float
    wall_width: float
    wall_height: float
    t0: float = 0.0

    def __post_init__(self):
        d = as_array("TransientVolume.data", self.data, ndim=3, readonly=True)
        if d.size == 0:
            raise InputError(f"TransientVolume.data: expected a non-empty (T, H, W) volume, got shape {d.shape}")
        if d.min() < 0:
            raise InputError(f"TransientVolume.data: photon counts must be ≥ 0, got min {d.min():g}")
        set_attribute(self, "data", d)
        for name in ("bin_width", "wall_width", "wall_height"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"TransientVolume.{name}: expected a positive finite value, got {getattr(self, name)}")
            set_attribute(self, name, v)
        t0 = float(self.t0)
        if not np.isfinite(t0):
            raise InputError(f"TransientVolume.t0: expected a finite time [s], got {self.t0}")
        set_attribute(self, "t0", t0)

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.data.shape

    @property
    def bin_length(self) -> float:
        """c·bin_width [m]: round-trip path per bin (a depth step of half of it)."""
        return SPEED_OF_LIGHT * self.bin_width

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Scan-point coordinates x (W,), y (H,) [m], centred on 0, spacing wall_width/W, wall_height/H."""
        _, h, w = self.data.shape
        x = (np.arange(w) - (w - 1) / 2) * (self.wall_width / w)
        y = (np.arange(h) - (h - 1) / 2) * (self.wall_height / h)
        return x, y

    def times(self) -> np.ndarray:
        """Round-trip time of each bin, t0 + k·bin_width [s], shape (T,): bin k is CENTRED there (it
        covers [t_k − Δ/2, t_k + Δ/2)), the convention of the SPAD forward model and the NLOS
        solvers (``sims/spad/transport.py``, ``estimators/nlos/prep.py``)."""
        return self.t0 + np.arange(self.data.shape[0]) * self.bin_width
