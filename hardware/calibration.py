"""Per-channel gain and phase calibration of a recording: given, or estimated from a corner reflector.

Each receive chain and each transmitter adds its own gain and phase (trace lengths, mixers, ADCs), so
the recorded channel k holds x_k = g_k·x₀_k, with x₀ the plane-wave model the beamformer assumes
(:func:`xnlos_core.signal.antenna.steering_vector`). Uncorrected, the errors raise the map's angle
sidelobes and can move its peaks. ``[recording] calibration`` gives g_k per channel as
``[amplitude, phase_deg]`` pairs (channels tx-major by array position, as the RA map's chain orders
them); :class:`hardware.recording.Recording` divides every chirp cube by it.

:func:`estimate_calibration` measures g from a capture of one strong point scatterer (a corner
reflector) at a known direction (θ, ε): at the range bin of its echo (the strongest bin beyond
``skip_range``, or the one given) the channels' range-FFT values are X_k = c·g_k·a_k(θ, ε) with one
unknown complex c (the reflector's amplitude and range phase, common to all channels), so

    ĝ_k = X_k / a_k(θ, ε),  normalised to phase 0 on channel 0 and mean power Σ|ĝ_k|²/K = 1.

A linear phase across the array is indistinguishable from a change of direction, so θ must be the
reflector's true azimuth (where it was placed; boresight by default): an estimate taken with a wrong θ
calibrates the reflector onto θ. The estimate is noise-limited: its phase error per channel is about
1/√(SNR) rad at the bin (averaged over ``frames``).
"""
from __future__ import annotations

import math

import numpy as np

from xnlos_core.errors import ConfigError, InputError
from xnlos_core.signal.antenna import steering_vector
from xnlos_core.signal.chain import decouple, range_fft


def calibration_gains(pairs, n_channels: int, source: str = "[recording] calibration") -> np.ndarray:
    """(n_channels,) complex128 gains g_k = amplitude·exp(j·phase_deg·π/180) of ``[amplitude, phase_deg]``
    pairs; ConfigError naming ``source`` unless there is one pair per channel, amplitudes > 0, all finite."""
    arr = np.asarray(pairs, dtype=np.float64)
    if arr.ndim != 2 or arr.shape != (n_channels, 2):
        raise ConfigError(f"{source}: expected {n_channels} [amplitude, phase_deg] pairs (one per channel, tx-major "
                          f"by array position: n_tx·n_rx = {n_channels}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr[:, 0] <= 0):
        raise ConfigError(f"{source}: amplitudes must be finite and > 0, phases finite [deg]; got {arr.tolist()}")
    return arr[:, 0] * np.exp(1j * np.radians(arr[:, 1]))


def calibration_table(gains) -> list[list[float]]:
    """``[[amplitude, phase_deg], …]`` of complex gains (phases in (−180, 180]), rounded to 6 significant
    digits in amplitude and 0.001° in phase: the value of ``[recording] calibration``."""
    g = np.asarray(gains, dtype=np.complex128).ravel()
    return [[float(f"{abs(v):.6g}"), round(math.degrees(np.angle(v)), 3)] for v in g]


def channel_profiles(recording, frames: int = 1) -> np.ndarray:
    """Range profiles (n_range, n_channels) complex128 of ``recording``'s first ``frames`` frames, chirps
    and frames summed coherently, any calibration the recording carries undone (the channels' own)."""
    radar = recording.radar
    n = min(int(frames), recording.n_frames)
    if n < 1:
        raise InputError(f"estimate_calibration: frames = {frames}; expected ≥ 1")
    x = 0.0
    for i in range(n):
        x = x + decouple(range_fft(recording.chirp_cube(i).mean(axis=1), radar), radar)
    if recording.spec.calibration is not None:
        x = x * calibration_gains(recording.spec.calibration, radar.n_channels)[None, :]
    return x


def reflector_bin(recording, profiles: np.ndarray, skip_range: float | None = None) -> int:
    """The strongest range bin (Σ_k |X_k|²) of ``profiles`` beyond ``skip_range`` [m] (default the
    recording's ``leakage_range``, which skips the TX→RX leakage)."""
    radar = recording.radar
    skip = recording.spec.leakage_range if skip_range is None else float(skip_range)
    power = np.sum(np.abs(profiles) ** 2, axis=1)
    first = int(np.searchsorted(radar.range_axis, skip, side="right"))
    if first >= len(power):
        raise InputError(f"estimate_calibration: no range bin beyond skip_range = {skip} m "
                         f"(max_range {radar.max_range} m)")
    return first + int(np.argmax(power[first:]))


def estimate_calibration(recording, azimuth: float = 0.0, elevation: float = 0.0, frames: int = 1,
                         range_bin: int | None = None, skip_range: float | None = None) -> np.ndarray:
    """Per-channel gains ĝ (n_channels,) complex128 of ``recording`` (a :class:`hardware.recording.Recording`
    of a corner reflector at azimuth θ = ``azimuth`` and elevation ε = ``elevation`` [rad]), as the module
    doc states: from the first ``frames`` frames (:func:`channel_profiles`), at ``range_bin`` or the
    strongest bin beyond ``skip_range`` [m] (:func:`reflector_bin`). A calibration the recording already
    carries is undone first, so the result is the channels' own. :func:`calibration_table` turns it into
    ``[recording] calibration``."""
    radar = recording.radar
    x = channel_profiles(recording, frames)
    if range_bin is None:
        range_bin = reflector_bin(recording, x, skip_range)
    elif not 0 <= range_bin < x.shape[0]:
        raise InputError(f"estimate_calibration: range_bin = {range_bin}; expected 0 … {x.shape[0] - 1}")
    g = x[range_bin] / steering_vector(radar, float(azimuth), float(elevation))[:, 0]
    if not np.all(np.abs(g) > 0):
        raise InputError(f"estimate_calibration: a channel is zero at range bin {range_bin} "
                         f"({radar.range_axis[range_bin]:.3g} m): no echo to calibrate on")
    g = g * np.exp(-1j * np.angle(g[0]))
    return g / np.sqrt(np.mean(np.abs(g) ** 2))
