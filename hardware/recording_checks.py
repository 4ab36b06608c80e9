"""Warnings for the mistakes made with raw recordings, each a :class:`RecordingWarning`.

* :func:`check_unsigned` — int16 samples stored unsigned / offset-binary (all ≥ 0): the map peaks at DC.
* :func:`check_bandwidth` — the sweep's bandwidth is S·N/f_s (the sampling window), not S·T_ramp.
* :func:`check_leakage` — near-range TX→RX leakage dominating the map.
* :func:`check_single_receiver` — one channel: the azimuth map is flat, its "peak" means nothing.
* :func:`check_channel_order` — a strong echo fits a plane wave much better in the other channel order.
"""
from __future__ import annotations

import warnings

import numpy as np

from xnlos_core.signal.antenna import steering_vector
from xnlos_core.errors import ConfigError, XnlosWarning
from xnlos_core.radar import RadarConfig
from xnlos_core.types import RAMap


class RecordingWarning(XnlosWarning):
    """A raw recording or its description looks wrong in a way the numbers alone will not reveal."""


def check_unsigned(raw, source: str) -> bool:
    """Warn when the raw integer samples are unsigned or all ≥ 0 (offset binary read as signed would have
    both signs; a radar's I/Q is zero-mean). Returns True when it warned."""
    arr = np.asarray(raw)
    if not np.issubdtype(arr.dtype, np.integer) or arr.size < 16:
        return False
    unsigned = np.issubdtype(arr.dtype, np.unsignedinteger)
    if unsigned or arr.min() >= 0:
        why = f"dtype {arr.dtype}" if unsigned else "every sample is ≥ 0"
        warnings.warn(f"{source}: {why}: the samples look unsigned (offset binary), so the RA map will peak at "
                      f"DC (range 0) far above its median; give recording.adc_offset (e.g. 32768 for offset-binary "
                      "int16, or the mean count) or convert to signed int16", RecordingWarning, stacklevel=3)
        return True
    return False


def check_bandwidth(slope: float, sample_rate: float, n_samples: int, ramp_time: float | None,
                    bandwidth_given: float | None, source: str) -> float:
    """Bandwidth of the sampled sweep, B = S·N/f_s [Hz] (slope [Hz/s], ADC rate [Hz]).

    A ramp is longer than its sampling window (ADC start time, settling), so S·T_ramp overstates B
    and every range comes out short by N/(f_s·T_ramp). Warns when an explicit ``bandwidth``
    disagrees with S·N/f_s by more than 1 % (naming S·T_ramp when that is what it equals); raises
    ConfigError when the sampling window N/f_s is longer than the ramp (no chip samples past its ramp).
    """
    b = slope * n_samples / sample_rate
    if ramp_time is not None and ramp_time < n_samples / sample_rate * (1 - 1e-9):
        raise ConfigError(f"{source}: [chirp] ramp_time = {ramp_time * 1e6:.2f} µs is shorter than the sampling window "
                          f"n_samples/sample_rate = {n_samples / sample_rate * 1e6:.2f} µs")
    if bandwidth_given is not None and abs(bandwidth_given - b) > 0.01 * b:
        ramp_b = None if ramp_time is None else slope * ramp_time
        what = " = S·ramp_time, the ramp's sweep" if ramp_b and abs(ramp_b - bandwidth_given) <= 0.01 * ramp_b else ""
        warnings.warn(f"{source}: the bandwidth of the sampling window S·N/f_s = {b / 1e6:.1f} MHz is used; "
                      f"radar.bandwidth = {bandwidth_given / 1e6:.1f} MHz{what} differs, and ranges computed with it "
                      f"would be scaled by {b / bandwidth_given:.3f} (a 5.00 m target would show at "
                      f"{5.0 * b / bandwidth_given:.2f} m)", RecordingWarning, stacklevel=3)
    return b


def check_leakage(ra_map: RAMap, source: str, near_range: float = 1.0, threshold_db: float = 30.0) -> bool:
    """Warn when the map's strongest cell lies within ``near_range`` [m] and exceeds the map's median
    power by more than ``threshold_db`` [dB]: TX→RX leakage (or DC) that hides the scene; remove it
    (recording.remove_dc, a background frame) or ignore those bins. Returns True when it warned."""
    p = ra_map.power
    k = np.unravel_index(np.argmax(p), p.shape)
    med = float(np.median(p))
    r = float(ra_map.range_axis[k[0]])
    if r > near_range or med <= 0:
        return False
    above = 10 * np.log10(p[k] / med)
    if above > threshold_db:
        warnings.warn(f"{source}: the strongest cell is at {r:.2f} m, {above:.1f} dB above the map's median: "
                      "near-range TX→RX leakage or DC; set recording.remove_dc = true, subtract a background "
                      "recording or ignore the first range bins", RecordingWarning, stacklevel=3)
        return True
    return False


def check_single_receiver(radar: RadarConfig, source: str) -> bool:
    """Warn when the radar records one channel: azimuth is not resolvable and any azimuth peak is
    arbitrary (the flat map's first bin, −field_of_view). Returns True when it warned."""
    if radar.n_channels == 1:
        warnings.warn(f"{source}: one receive channel (n_tx·n_rx = 1): azimuth cannot be resolved, the RA map "
                      "is flat in azimuth and an azimuth peak means nothing; use range only",
                      RecordingWarning, stacklevel=3)
        return True
    return False


def plane_wave_fit(x: np.ndarray, radar: RadarConfig, n_dirs: int = 721) -> float:
    """max_θ |a(θ)ᴴx|² / (‖a‖²‖x‖²) ∈ [0, 1]: how well channel vector x (n_channels,) is one plane wave."""
    theta = np.linspace(-np.pi / 2, np.pi / 2, n_dirs)
    a = steering_vector(radar, theta)
    nx = float(np.vdot(x, x).real)
    if nx == 0:
        return 0.0
    return float((np.abs(a.conj().T @ x) ** 2).max() / (radar.n_channels * nx))


def check_channel_order(profiles: np.ndarray, radar: RadarConfig, source: str, skip_range: float = 1.0,
                        good: float = 0.95, ratio: float = 10.0) -> bool:
    """Warn when the strongest echo beyond ``skip_range`` [m] fits a plane wave well (fit > ``good``) after
    swapping tx-major and rx-major, and its misfit 1 − fit in the order used is ``ratio`` times larger.
    (A small array scrambled can still resemble a plane wave at another angle, 0.96 for 2 × 4, so the
    test compares the two orders rather than asking for a poor fit.)

    profiles: range profiles (n_range_bins, n_channels) complex, channels as the chain reads them.
    Needs MIMO with n_tx, n_rx > 1 (otherwise nothing to check). Returns True when it warned.
    """
    if not radar.mimo or radar.n_tx < 2 or radar.n_rx < 2:
        return False
    start = int(np.ceil(skip_range / radar.range_resolution))
    if start >= profiles.shape[0]:
        return False
    k = start + int(np.argmax((np.abs(profiles[start:]) ** 2).sum(axis=1)))
    x = profiles[k]
    fit = plane_wave_fit(x, radar)
    i_tx, j_rx = np.divmod(np.arange(radar.n_channels), radar.n_rx)
    perm = j_rx * radar.n_tx + i_tx
    alt = max(plane_wave_fit(x[perm], radar), plane_wave_fit(x[np.argsort(perm)], radar))
    if alt > good and (1.0 - fit) > ratio * (1.0 - alt):
        warnings.warn(f"{source}: the strongest echo ({radar.range_axis[k]:.2f} m) fits a plane wave "
                      f"{fit:.2f} in this channel order but {alt:.2f} with tx-major and rx-major swapped: "
                      "check recording.channel_order (and chirp.tx_order)", RecordingWarning, stacklevel=3)
        return True
    return False
