"""Warnings for the mistakes made with raw recordings, each a :class:`RecordingWarning`.

* :func:`check_spec` — settings that cannot be right (ConfigError) or likely are not (n_rx > 4 on a DCA1000).
* :func:`check_unsigned` — samples stored unsigned / offset-binary (all ≥ 0, complex parts too): the map peaks at DC.
* :func:`check_bandwidth` — the sweep's bandwidth is S·N/f_s (the sampling window), not S·T_ramp.
* :func:`check_leakage` — near-range TX→RX leakage dominating the map.
* :func:`check_single_receiver` — one channel: the azimuth map is flat, its "peak" means nothing.
* :func:`check_channel_order` — strong echoes fit a plane wave much better in another channel or TX order.

The layout of DCA1000 words (encoding, chirp length, lanes, I/Q) is checked against the data by
:func:`hardware.layout.checks.check_layout`.
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


def check_unsigned(raw, source: str, fmt: str = "npy") -> bool:
    """Warn when the raw samples are unsigned or all ≥ 0 — integers, floats or the real and imaginary
    parts of complex values (vendor-style readers return complex arrays of unsigned counts); a radar's
    I/Q is zero-mean, so the RA map would peak at DC. ``fmt``: the recording's format (the fix named
    differs for DCA1000 words). Returns True when it warned."""
    arr = np.asarray(raw)
    if arr.dtype.kind not in "iufc" or arr.size < 16:
        return False
    parts = (arr.real, arr.imag) if arr.dtype.kind == "c" else (arr,)
    unsigned = arr.dtype.kind == "u"
    if not unsigned and (min(float(p.min()) for p in parts) < 0 or max(float(p.max()) for p in parts) <= 0):
        return False
    mid = float(np.median(np.concatenate([p.ravel() for p in parts])))
    why = f"dtype {arr.dtype}" if unsigned else ("every real and imaginary part is ≥ 0" if arr.dtype.kind == "c"
                                                   else "every sample is ≥ 0")
    fix = (f"set recording.adc_offset = {mid:.0f} (the median count: the ADC's mid-scale), or recording.encoding "
           "= 'offset_binary' for 16-bit codes centred on 32768" if fmt == "dca1000" else
           f"set recording.adc_offset to the ADC's mid-scale count (the median is {mid:.0f}; 32768 for 16-bit "
           "offset binary, 2048 for a 12-bit ADC), or recording.encoding = 'offset_binary' for 16-bit codes")
    warnings.warn(f"{source}: {why}: the samples look unsigned (offset binary), so the RA map will peak at DC "
                  f"(range 0) far above its median; {fix}", RecordingWarning, stacklevel=3)
    return True


def check_spec(spec, radar: RadarConfig, source: str) -> None:
    """Checks of a ``[recording]`` table against the radar before any data is read: ConfigError for
    settings that cannot be right, RecordingWarning for the likely mistakes.

    * DCA1000 words are read as signed int16: ``adc_offset = ±32768`` makes every count wrong
      (offset-binary words are ``encoding = "offset_binary"``), a ConfigError;
    * ``iq_interleave`` orders DCA1000 words only (a cube's I/Q axis is ``sample_format``/``iq_order``);
    * a DCA1000 capture carries one chip's receivers, at most 4 per chirp: one TX with n_rx > 4 is most
      likely an n_tx × n_rx capture read as 1 × (n_tx·n_rx), whose map is right but whose chirp loop is
      n_tx times too short (every velocity × n_tx), a warning.
    """
    if spec.format == "dca1000" and abs(spec.adc_offset) == 32768:
        raise ConfigError(f"{source}: [recording] adc_offset = {spec.adc_offset:g} with format 'dca1000': the .bin "
                          "words are read as signed int16, so an offset-binary code u ≥ 32768 reads as u − 65536 and "
                          "subtracting 32768 leaves it 65536 too low; set encoding = 'offset_binary' and leave "
                          "adc_offset out")
    if spec.format != "dca1000" and spec.iq_interleave != "lanes":
        raise ConfigError(f"{source}: [recording] iq_interleave = '{spec.iq_interleave}' orders the words of a "
                          f"DCA1000 .bin; a {spec.format} cube gives its I/Q layout by sample_format and iq_order")
    if spec.sampling == "real" and spec.iq_order != "iq":
        raise ConfigError(f"{source}: [recording] iq_order = '{spec.iq_order}' needs complex samples; sampling = "
                          "'real' has no Q")
    n_rx = radar.n_channels // radar.n_tdm
    if spec.format == "dca1000" and n_rx > 4 and radar.n_tx == 1:  # the 1 × (n_tx·n_rx) misreading
        warnings.warn(f"{source}: {n_rx} receivers per chirp (radar.n_rx = {radar.n_rx}, n_tx = {radar.n_tx}), but "
                      "a DCA1000 carries one radar chip's receivers, at most 4: a 2 TX × 4 RX capture described as "
                      "n_tx = 1, n_rx = 8 beamforms the same map but takes each chirp loop for one chirp, so every "
                      f"velocity comes out × n_tx; if the chip has fewer receivers, set radar.n_rx to them and "
                      f"radar.n_tx to the transmitters (e.g. n_tx = {n_rx // 4 if n_rx % 4 == 0 else 'k'}, "
                      "n_rx = 4)", RecordingWarning, stacklevel=3)


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


def check_leakage(ra_map: RAMap, source: str, near_range: float = 1.0, threshold_db: float = 30.0,
                  dc_share: float | None = None, explained: tuple[str, ...] = ()) -> bool:
    """Warn when the map's strongest cell lies within ``near_range`` [m] and exceeds the map's median
    power by more than ``threshold_db`` [dB]. The advice follows the data: ``explained`` (settings
    that the earlier checks found wrong, e.g. unsigned samples or n_samples) come first and nothing
    else is advised; ``recording.remove_dc`` only when the strongest cell is the DC bin and the
    samples' mean over a chirp holds ``dc_share`` > ½ of their power (DC); otherwise TX→RX leakage,
    which a background recording removes and remove_dc does not. Returns True when it warned."""
    p = ra_map.power
    k = np.unravel_index(np.argmax(p), p.shape)
    med = float(np.median(p))
    r = float(ra_map.range_axis[k[0]])
    if r > near_range or med <= 0:
        return False
    above = 10 * np.log10(p[k] / med)
    if above <= threshold_db:
        return False
    head = f"{source}: the strongest cell is at {r:.2f} m, {above:.1f} dB above the map's median"
    if explained:
        advice = (f": the warnings above name the cause ({', '.join(explained)}), which puts energy at near range; "
                  "fix that first (remove_dc would hide the symptom, not the fault)")
    elif k[0] == 0 and dc_share is not None and dc_share > 0.5:
        advice = (f": a DC offset (the samples' mean holds {100 * dc_share:.0f} % of their power); set "
                  "recording.remove_dc = true")
    else:
        share = "" if dc_share is None else f" (the samples' mean holds only {100 * dc_share:.0f} % of their power)"
        advice = (f": near-range TX→RX leakage{share}; subtract a background recording or ignore the first range "
                  "bins (recording.remove_dc removes a DC offset only)")
    warnings.warn(head + advice, RecordingWarning, stacklevel=3)
    return True


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


def strong_echoes(profiles: np.ndarray, radar: RadarConfig, skip_range: float, n: int = 3) -> np.ndarray:
    """Range bins of the ``n`` strongest local maxima of the channel-summed power beyond ``skip_range`` [m]
    (each over its neighbours), strongest first."""
    start = int(np.ceil(skip_range / radar.range_resolution))
    power = (np.abs(profiles) ** 2).sum(axis=1)
    peaks = [k for k in range(max(start, 1), power.size - 1) if power[k] >= power[k - 1] and power[k] >= power[k + 1]]
    return np.array(sorted(peaks, key=lambda k: -power[k])[:n], dtype=int)


def array_fit(profiles: np.ndarray, bins: np.ndarray, radar: RadarConfig, perm: np.ndarray | None = None) -> float:
    """Power-weighted mean plane-wave fit (:func:`plane_wave_fit`) of the echoes in range ``bins`` with the
    channels reordered by ``perm`` (None: as given)."""
    x = profiles[bins] if perm is None else profiles[bins][:, perm]
    w = (np.abs(x) ** 2).sum(axis=1)
    return float(sum(wk * plane_wave_fit(xk, radar) for wk, xk in zip(w, x)) / w.sum()) if w.sum() > 0 else 0.0


def check_channel_order(profiles: np.ndarray, radar: RadarConfig, source: str, skip_range: float = 1.0,
                        good: float = 0.9, ratio: float = 4.0, tx_order=None) -> bool:
    """Warn when the strongest echoes beyond ``skip_range`` [m] fit the declared virtual array far worse
    than another channel order: tx-major and rx-major swapped (recording.channel_order) or another
    order of the TX slots (chirp.tx_order). Warns when the best alternative's fit exceeds ``good`` and
    the declared misfit 1 − fit is ``ratio`` times the alternative's. A small array scrambled can still
    resemble a plane wave at another angle (0.96 for 2 × 4), so the orders are compared, and echoes
    near boresight (equal phases on every channel) cannot tell orders apart at all.

    profiles: range profiles (n_range_bins, n_channels) complex, channels as the chain reads them;
    tx_order: the declared chirp.tx_order (None: slots in array order), named in the advice.
    Needs MIMO with n_tx, n_rx > 1 (otherwise nothing to check). Returns True when it warned.
    """
    import itertools

    if not radar.mimo or radar.n_tx < 2 or radar.n_rx < 2:
        return False
    bins = strong_echoes(profiles, radar, skip_range)
    if bins.size == 0:
        return False
    fit = array_fit(profiles, bins, radar)
    i_tx, j_rx = np.divmod(np.arange(radar.n_channels), radar.n_rx)
    swap = j_rx * radar.n_tx + i_tx
    alternatives = {"recording.channel_order (tx-major and rx-major swapped)": swap,
                    "recording.channel_order (rx-major and tx-major swapped)": np.argsort(swap)}
    order = list(range(radar.n_tx)) if tx_order is None else list(tx_order)
    if radar.n_tx <= 4:
        for p in itertools.permutations(range(radar.n_tx)):
            if list(p) != list(range(radar.n_tx)):
                perm = (np.array(p)[:, None] * radar.n_rx + np.arange(radar.n_rx)[None, :]).ravel()
                alternatives[f"chirp.tx_order = {[int(np.argsort(p)[o]) for o in order]}"] = perm
    fits = {name: array_fit(profiles, bins, radar, perm) for name, perm in alternatives.items()}
    name, alt = max(fits.items(), key=lambda kv: kv[1])
    if alt > good and (1.0 - fit) > ratio * (1.0 - alt):
        where = ", ".join(f"{radar.range_axis[k]:.2f}" for k in bins)
        warnings.warn(f"{source}: the strongest echoes ({where} m) fit a plane wave {fit:.2f} on the declared "
                      f"virtual array but {alt:.2f} with {name}: check recording.channel_order and chirp.tx_order "
                      f"(now {order})", RecordingWarning, stacklevel=3)
        return True
    return False
