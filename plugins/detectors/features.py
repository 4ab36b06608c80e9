"""Network input features of a complex RA map κ ∈ ℂ^{H×W} (Sec. 4.1), and padding to a multiple.

Four float32 channels, shape (4, H, W):

0. normalised log power  ℓ = clip((10·log10 max(|κ|², P_floor) − L_ref) / 10 dB, −3, 10):
   decibels above the map's median power L_ref (the noise floor of a sparse map), in units of
   10 dB, kept within [−30 dB, +100 dB] of it. P_floor = max|κ|²·10^(−dynamic_range_db/10).
   Normalising per map makes the features independent of transmit power and absolute
   calibration; the clip bounds them whatever the dynamic range (1e12 or more).
1. cos ∠κ and 2. sin ∠κ: the phase as a point on the unit circle (no 2π wrap), set to 0 where
   |κ|² ≤ P_floor (the phase of nothing).
3. occlusion  o(i, j) = max_{i' < i} ℓ(i', j): the strongest return nearer in range at the same
   azimuth (0 in the first row). A weak peak behind a strong wall is likely a mirrored (mNLOS)
   echo — the geometric cue of Sec. 3 — and this hands it to every network at any receptive field.

An all-zero map gives all-zero features (finite; a detector then finds what its bias says, for
the shipped models nothing). NaN or infinite cells raise :class:`InputError`.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from xnlos_core.errors import InputError

N_FEATURES = 4
LOG_SCALE_DB = 10.0
CLIP = (-3.0, 10.0)


def ra_features(data: np.ndarray, dynamic_range_db: float = 200.0, name: str = "RAMap.data") -> np.ndarray:
    """Features (4, H, W) float32 of a complex map ``data`` (H, W) (module doc)."""
    kappa = np.asarray(data)
    if kappa.ndim != 2:
        raise InputError(f"{name}: expected a 2-D (n_range, n_azimuth) map, got shape {kappa.shape}")
    if not np.all(np.isfinite(kappa)):
        bad = int(kappa.size - np.count_nonzero(np.isfinite(kappa)))
        raise InputError(f"{name}: {bad} of {kappa.size} cells are NaN or infinite; a detector needs a finite map")
    k128 = kappa.astype(np.complex128, copy=False)
    power = k128.real**2 + k128.imag**2
    out = np.zeros((N_FEATURES,) + power.shape, dtype=np.float32)
    pmax = float(power.max()) if power.size else 0.0
    if not pmax > 0.0:
        return out
    floor = max(pmax * 10.0 ** (-dynamic_range_db / 10.0), np.finfo(np.float64).tiny)
    above = power > floor
    level = 10.0 * np.log10(np.maximum(power, floor))
    ref = float(np.median(level))
    out[0] = np.clip((level - ref) / LOG_SCALE_DB, *CLIP)
    if power.shape[0] > 1:
        out[3, 1:] = np.maximum.accumulate(out[0, :-1], axis=0)
    mag = np.sqrt(np.where(above, power, 1.0))
    out[1] = np.where(above, k128.real / mag, 0.0)
    out[2] = np.where(above, k128.imag / mag, 0.0)
    return out


def pad_to_multiple(x: torch.Tensor, multiple: tuple[int, int]) -> tuple[torch.Tensor, tuple[int, int]]:
    """Zero-pad (B, C, H, W) at the far range / high azimuth ends to multiples of ``multiple``.

    Zero features are the noise-floor level with no phase, so padding looks like empty sky.
    Returns (padded tensor, (H, W) to crop back to).
    """
    h, w = x.shape[-2:]
    mh, mw = multiple
    ph, pw = (-h) % mh, (-w) % mw
    if ph or pw:
        x = F.pad(x, (0, pw, 0, ph))
    return x, (h, w)
