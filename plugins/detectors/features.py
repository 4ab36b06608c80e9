"""Network input features of a complex RA map κ ∈ ℂ^{H×W} (Sec. 4.1), and padding to a multiple.

The power-map channels, float32, shape (4, H, W) (:func:`ra_features`, :data:`RA_CHANNELS`):

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

Doppler channels (:func:`doppler_features`, :data:`DOPPLER_CHANNELS`), from a map of Doppler
processing (``RAMap.velocity`` v̂_r and ``RAMap.velocity_std`` σ_v per cell,
:func:`xnlos_core.signal.doppler.doppler_ra_maps`), set to 0 in cells not above the map's median
level (ℓ ≤ 0: noise, whose velocity is a random bin):

4. radial velocity  v̂_r / v_max, clipped to [−3, 3] (v_max = λ₀/(4·T_c·N_tx), the unambiguous
   velocity; resolved folds lie beyond ±1). A wall's own echo is 0; a moving car's mirror is not —
   the cue that tells a static wall echo mirrored through another wall from a road user.
5. velocity σ  (log10(σ_v/Δv) + 3)/4, clipped to [0, 1.25] (Δv the Doppler-bin spacing): about 0
   for a strong echo (σ_v ≤ Δv/1000), 0.75 at σ_v = Δv.
6. Doppler spread  1 − |Σ w·e^{jπv̂/v_max}| / Σ w over the 3 × 3 neighbourhood, weights w = |κ|²
   of the cells above the median: 0 where one rigid reflector fills the neighbourhood, up to 1
   where velocities disagree (a wall edge next to a car, clutter, noise). The phase form makes it
   indifferent to a fold (v and v ± 2·v_max agree).

Previous frames (optional, :func:`previous_channels`): channel 0 of the K ≤ 4 frames before this one
in the same sequence, the last one first — how the echoes moved, for a model that wants it.

A model records its channel names (checkpoint metadata ``features.channels``); :func:`map_features`
builds exactly those, and refuses (InputError) a map without Doppler for a model that wants it.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from xnlos_core.errors import InputError

N_FEATURES = 4  # the power-map channels; a network's input count is its ``in_channels`` hyper-parameter
LOG_SCALE_DB = 10.0
CLIP = (-3.0, 10.0)
RA_CHANNELS = ("log_power_10db_over_median", "cos_phase", "sin_phase", "occlusion")
DOPPLER_CHANNELS = ("radial_velocity_over_vmax", "log_velocity_std_over_bin", "doppler_spread_3x3")
VELOCITY_CLIP = 3.0  # |v̂_r| / v_max: two folds either side
STD_CLIP = (0.0, 1.25)


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


def doppler_features(ra_map, level: np.ndarray, name: str = "RAMap") -> np.ndarray:
    """The Doppler channels (3, H, W) float32 of ``ra_map`` (module doc); ``level`` is the
    normalised log power ℓ (channel 0 of :func:`ra_features`). InputError without Doppler."""
    if ra_map.velocity is None:
        raise InputError(f"{name}: this model's inputs include Doppler channels ({', '.join(DOPPLER_CHANNELS)}), "
                         "but the map has none (RAMap.velocity is None): give it maps from Doppler processing "
                         "(forward model params doppler = true, or a recording with n_chirps > 1), or choose a model "
                         "without Doppler inputs (checkpoint = 'default')")
    radar = ra_map.radar
    vmax, dv = radar.max_unambiguous_velocity, radar.velocity_resolution
    v = np.asarray(ra_map.velocity, np.float64)
    std = np.asarray(ra_map.velocity_std, np.float64)
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(std))):
        raise InputError(f"{name}: RAMap.velocity / velocity_std hold NaN or infinite cells; a detector needs finite "
                         "Doppler maps")
    above = level > 0.0
    out = np.zeros((3,) + v.shape, np.float32)
    out[0] = np.where(above, np.clip(v / vmax, -VELOCITY_CLIP, VELOCITY_CLIP), 0.0)
    rel = np.log10(np.maximum(std / dv, 1e-12))
    out[1] = np.where(above, np.clip((rel + 3.0) / 4.0, *STD_CLIP), 0.0)
    kappa = np.asarray(ra_map.data).astype(np.complex128)
    w = np.where(above, kappa.real**2 + kappa.imag**2, 0.0)
    w = w / w.max() if w.max() > 0 else w  # scale-free; the spread is a ratio of sums of w
    from scipy.signal import convolve2d

    box = np.ones((3, 3))  # sums over each cell's 3 × 3 neighbourhood, zeros beyond the map
    tot_w = convolve2d(w, box, mode="same")
    tot_p = convolve2d(w * np.exp(1j * np.pi * v / vmax), box, mode="same")
    spread = 1.0 - np.abs(tot_p) / np.where(tot_w > 0, tot_w, 1.0)
    out[2] = np.where(above & (tot_w > 0), np.clip(spread, 0.0, 1.0), 0.0)
    return out


MAX_PREVIOUS = 4  # earlier frames a model may read


def previous_channels(k: int) -> tuple[str, ...]:
    """Names of the channels of the ``k`` previous frames' normalised log power (1 = the last one)."""
    return tuple(f"log_power_prev{i}" for i in range(1, k + 1))


def channel_layout(doppler: bool = False, previous: int = 0) -> tuple[str, ...]:
    """The input channels of a model: the power-map ones, then the Doppler ones, then the previous
    frames' log power (module doc)."""
    if isinstance(previous, bool) or not 0 <= int(previous) <= MAX_PREVIOUS:
        from xnlos_core.errors import ConfigError

        raise ConfigError(f"previous frames {previous!r}: expected an integer from 0 to {MAX_PREVIOUS}")
    return RA_CHANNELS + (DOPPLER_CHANNELS if doppler else ()) + previous_channels(int(previous))


def parse_layout(channels) -> tuple[bool, int]:
    """(doppler, previous frames) of a model's recorded input channels; ConfigError for channel names
    this version does not build (a checkpoint made for other inputs)."""
    channels = tuple(channels)
    for doppler in (False, True):
        for k in range(MAX_PREVIOUS + 1):
            if channels == channel_layout(doppler, k):
                return doppler, k
    from xnlos_core.errors import ConfigError

    raise ConfigError(f"model input channels {list(channels)}: this xnlos builds {list(RA_CHANNELS)}, optionally "
                      f"followed by {list(DOPPLER_CHANNELS)} and log_power_prev1 … prev{MAX_PREVIOUS}; the checkpoint "
                      "was made for other inputs")


def map_features(ra_map, channels=RA_CHANNELS, dynamic_range_db: float = 200.0, name: str = "RAMap",
                 previous=()) -> np.ndarray:
    """Features (len(channels), H, W) float32 of ``ra_map`` for a model whose inputs are ``channels``
    (checkpoint metadata ``features.channels``, :func:`channel_layout`). ``previous``: the normalised
    log power (channel 0) of earlier frames of the same sequence, the last one first; where a model
    reads more of them than there are (a sequence's first frames), the oldest given stands in, and
    without any the frame's own (as if the scene stood still). InputError for a map without the
    Doppler a model wants; ConfigError for channel names this version does not know."""
    doppler, k = parse_layout(channels)
    ra = ra_features(ra_map.data, dynamic_range_db, name=f"{name}.data")
    parts = [ra]
    if doppler:
        parts.append(doppler_features(ra_map, ra[0], name))
    if k:
        prev = [np.asarray(p, np.float32) for p in previous if np.shape(p) == ra[0].shape] or [ra[0]]
        parts.append(np.stack([prev[min(i, len(prev) - 1)] for i in range(k)]))
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)


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
