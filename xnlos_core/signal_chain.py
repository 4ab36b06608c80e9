"""FMCW signal chain (paper Sec. 3.2, Eq. 6): chirp, dechirp synthesis, noise, range FFT, beamforming.

Scaling (documented once, used everywhere):

* The ADC cube holds complex baseband samples in √W: a path of received power P_r [W] per
  virtual channel has amplitude |a| = √P_r; thermal noise has power σ² = ``radar.noise_power``
  per complex sample.
* :func:`range_fft` divides by the coherent gain Σw_r of the range window, and :func:`beamform`
  by Σw_a of the azimuth window. Hence a path centred on a range bin and on an azimuth grid angle
  shows |κ|² = P_r at its RA cell: **the RA-map peak amplitude is the received amplitude per
  virtual channel**. Off-grid targets lose the window's scalloping loss (≤ 1.42 dB for Hann).
* Noise-only RA cells then have E|κ|² = σ²·(Σw_r²/(Σw_r)²)·(Σw_a²/(Σw_a)²) = σ² / G_p
  (:func:`noise_floor`), with the processing gain G_p = N·M / (ENBW_r·ENBW_a)
  (:func:`processing_gain`), N = n_samples, M = n_tx·n_rx, ENBW = N·Σw²/(Σw)² in bins.
  So a point target's RA-map SNR is  SNR_RA = (P_r/σ²)·N·M/(ENBW_r·ENBW_a) — per-sample SNR
  times samples times channels times the two window losses 1/ENBW.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import get_window

from .antenna import azimuth_weights, steering_vector
from .errors import InputError
from .radar import SPEED_OF_LIGHT, RadarConfig
from .types import RAMap
from .validation import as_array

_CHUNK = 2048  # paths per dechirp chunk: bounds the (n_samples, chunk) complex128 temporary


def chirp(radar: RadarConfig, t) -> np.ndarray:
    """Transmitted FMCW waveform g(t) = exp(j(2π f_c t + π (B/T) t²)); t [s] any shape → complex128."""
    t = np.asarray(t, dtype=np.float64)
    # carrier phase in cycles, reduced mod 1 before ×2π: keeps float64 precision at large f_c·t
    cycles = np.mod(radar.carrier_frequency * t, 1.0) + 0.5 * radar.chirp_slope * t**2
    return np.exp(2j * np.pi * cycles)


def beat_frequency(radar: RadarConfig, range_m) -> np.ndarray:
    """Beat frequency f_b = S·τ = 2·R·B/(c·T) [Hz] of a target at one-way range R [m] (Eq. 6)."""
    r = np.asarray(range_m, dtype=np.float64)
    return 2.0 * r * radar.bandwidth / (SPEED_OF_LIGHT * radar.chirp_duration)


def sample_times(radar: RadarConfig) -> np.ndarray:
    """ADC sample instants t_n = n / f_s [s], shape (n_samples,)."""
    return np.arange(radar.n_samples, dtype=np.float64) / radar.sample_rate


def dechirp(radar: RadarConfig, path_length, azimuth, amplitude) -> np.ndarray:
    """Synthesise the dechirped baseband cube of a set of paths (Eq. 6), (n_samples, n_virtual) complex128.

    path_length (P,): unfolded round-trip length L [m] (one-way equivalent range L/2);
    azimuth (P,): arrival azimuth θ [rad]; amplitude (P,): complex amplitude a [√W].

        s_k[n] = Σ_p a_p · exp(j(2π f_b,p t_n + 2π f_c τ_p − π S τ_p²)) · exp(−j 2π y_k sin θ_p / λ)

    with τ = L/c, S = B/T, f_b = S·τ (conjugate product g·g*(t−τ), so f_b > 0). The sum is
    separable, so it is a matrix product (N, P) @ (P, M), done in chunks of paths. The IF
    anti-aliasing low-pass is ideal: paths with f_b ≥ f_s (beyond the unambiguous range) are
    not sampled, instead of aliasing to short range.
    """
    L = np.atleast_1d(np.asarray(path_length, dtype=np.float64))
    th = np.atleast_1d(np.asarray(azimuth, dtype=np.float64))
    a = np.atleast_1d(np.asarray(amplitude, dtype=np.complex128))
    if not (L.shape == th.shape == a.shape and L.ndim == 1):
        raise InputError(f"dechirp: path_length, azimuth, amplitude must be 1-D of equal length, "
                         f"got {L.shape}, {th.shape}, {a.shape}")
    tau = L / SPEED_OF_LIGHT
    fb = radar.chirp_slope * tau
    keep = (fb >= 0) & (fb < radar.sample_rate) & (a != 0)
    L, th, a, tau, fb = L[keep], th[keep], a[keep], tau[keep], fb[keep]
    t = sample_times(radar)
    # constant phase in cycles: f_c τ = L/λ (mod 1 first, float64), minus the residual video phase S τ²/2
    phase0 = np.mod(L / radar.wavelength, 1.0) - 0.5 * radar.chirp_slope * tau**2
    cube = np.zeros((radar.n_samples, radar.n_tx * radar.n_rx), dtype=np.complex128)
    for i in range(0, len(L), _CHUNK):
        sl = slice(i, i + _CHUNK)
        tones = np.exp(2j * np.pi * (np.outer(t, fb[sl]) + phase0[sl]))  # (N, P)
        cube += (tones * a[sl]) @ steering_vector(radar, th[sl]).T  # (P, M)
    return cube


def add_noise(cube: np.ndarray, radar: RadarConfig, rng: np.random.Generator) -> np.ndarray:
    """Return ``cube`` plus circular complex Gaussian noise of power ``radar.noise_power`` [W] per sample."""
    sd = np.sqrt(radar.noise_power / 2.0)
    noise = rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)
    return cube + sd * noise


def _window(name: str, n: int) -> np.ndarray:
    # symmetric taper (fftbins=False), same convention as the azimuth weights
    return np.asarray(get_window(name, n, fftbins=False), dtype=np.float64)


def processing_gain(radar: RadarConfig) -> float:
    """G_p = N·M / (ENBW_r·ENBW_a) (linear): RA-map SNR of a grid-centred point over per-sample SNR."""
    wr = _window(radar.range_window, radar.n_samples)
    wa = azimuth_weights(radar)
    return float(wr.sum() ** 2 / (wr**2).sum() * wa.sum() ** 2 / (wa**2).sum())


def noise_floor(radar: RadarConfig) -> float:
    """Expected |κ|² [W] of a noise-only RA cell: σ² / G_p (see module docstring)."""
    return radar.noise_power / processing_gain(radar)


def range_fft(cube: np.ndarray, radar: RadarConfig) -> np.ndarray:
    """Windowed range FFT along axis 0, cropped to radar.n_range_bins → (n_range_bins, n_virtual) complex128.

    Normalised by the window's coherent gain Σw_r, so a tone of complex amplitude A at the
    centre of bin k gives exactly A in bin k (bin k ↔ range k·ΔR, f_b = k/T).
    """
    w = _window(radar.range_window, radar.n_samples)
    spec = np.fft.fft(cube * (w / w.sum())[:, None], axis=0)
    return spec[: radar.n_range_bins]


def beamform(range_profiles: np.ndarray, radar: RadarConfig) -> np.ndarray:
    """Windowed delay-and-sum onto radar.azimuth_axis: (n_range, n_virtual) → (n_range, n_azimuth).

    κ(r, θ) = Σ_k w_k a_k*(θ) X_k(r) / Σ w_k, so a unit plane wave from a grid angle gives 1.
    """
    w = azimuth_weights(radar)
    weights = (w / w.sum())[:, None] * steering_vector(radar, radar.azimuth_axis).conj()  # (M, n_az)
    return range_profiles @ weights


def ra_map_from_cube(cube: np.ndarray, radar: RadarConfig) -> RAMap:
    """Range FFT + beamforming of a (n_samples, n_virtual) cube → RAMap (complex64). No validation."""
    return RAMap.from_radar(beamform(range_fft(cube, radar), radar).astype(np.complex64), radar)


def adc_to_ra_map(cube, radar: RadarConfig) -> RAMap:
    """Entry point for measured ADC cubes: validate, then :func:`ra_map_from_cube`.

    cube: complex (n_samples, n_tx·n_rx) in √W, virtual channels tx-major like
    radar.virtual_positions. Raises InputError on a wrong shape or non-finite values.
    """
    want = (radar.n_samples, radar.n_tx * radar.n_rx)
    shape = np.shape(cube)
    if tuple(shape) != want:
        raise InputError(f"adc cube: expected shape (n_samples, n_tx*n_rx) = {want} for this radar, "
                         f"got {tuple(shape)}")
    arr = as_array("adc cube", cube, dtype=np.complex128)
    return ra_map_from_cube(arr, radar)
