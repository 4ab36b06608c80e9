"""NLOSVolume: the result of an NLOS solver — a reconstructed hidden albedo on a
depth × wall-grid volume, the counterpart of :class:`xnlos_core.transient.TransientVolume`.

Same confocal wall grid as the measurement (H × W scan points, centred, spacing wall_width/W and
wall_height/H, :meth:`NLOSVolume.grid`); the depth axis z [m] runs away from the wall into the
hidden scene (z = c·t/2 for the round-trip time t of the measurement's bin).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .types import ReadOnlyArrays, set_attribute
from .validation import as_array, check_ascending


@dataclass(frozen=True, eq=False)
class NLOSVolume(ReadOnlyArrays):
    """albedo (Z, H, W) float64, ≥ 0 and finite (arbitrary units: only relative values mean
    anything); z (Z,) [m] depth of each albedo slice, ascending; wall_width, wall_height [m] the
    lateral extent along W (x) and H (y), > 0. Arrays are read-only once validated."""

    albedo: np.ndarray
    z: np.ndarray
    wall_width: float
    wall_height: float

    def __post_init__(self):
        a = as_array("NLOSVolume.albedo", self.albedo, ndim=3, readonly=True)
        if a.size == 0:
            raise InputError(f"NLOSVolume.albedo: expected a non-empty (Z, H, W) volume, got shape {a.shape}")
        if a.min() < 0:
            raise InputError(f"NLOSVolume.albedo: expected values ≥ 0, got min {a.min():g}")
        z = as_array("NLOSVolume.z", self.z, ndim=1, readonly=True)
        if z.shape[0] != a.shape[0]:
            raise InputError(f"NLOSVolume.z: expected {a.shape[0]} depths (albedo's Z), got {z.shape[0]}")
        check_ascending("NLOSVolume.z", z)
        set_attribute(self, "albedo", a)
        set_attribute(self, "z", z)
        for name in ("wall_width", "wall_height"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"NLOSVolume.{name}: expected a positive finite value [m], got {getattr(self, name)}")
            set_attribute(self, name, v)

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.albedo.shape

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Lateral coordinates x (W,), y (H,) [m], centred on 0 — the same as TransientVolume.grid()."""
        _, h, w = self.albedo.shape
        x = (np.arange(w) - (w - 1) / 2) * (self.wall_width / w)
        y = (np.arange(h) - (h - 1) / 2) * (self.wall_height / h)
        return x, y

    def peak_index(self) -> tuple[int, int, int]:
        """(k, i, j) index of the albedo's maximum (the first one on ties)."""
        return tuple(int(v) for v in np.unravel_index(int(np.argmax(self.albedo)), self.albedo.shape))

    def peak(self) -> tuple[float, float, float]:
        """(z, y, x) [m] of the albedo's maximum."""
        k, i, j = self.peak_index()
        x, y = self.grid()
        return float(self.z[k]), float(y[i]), float(x[j])
