"""FMCW signal chain (paper Sec. 3.2, Eq. 6): chirp, dechirp synthesis, noise, range FFT, beamforming.

Scaling (documented once, used everywhere):

* The ADC cube holds complex baseband samples in √W: a path of received power P_r [W] per
  virtual channel has amplitude |a| = √P_r; thermal noise has power σ² = ``radar.noise_power``
  per complex sample (k·T·f_s·NF over the ``n_chirps`` chirps averaged into the cube).
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

import functools

import numpy as np
import scipy.fft

from xnlos_core.signal.antenna import azimuth_weights, coupling_matrix, steering_vector, symmetric_window
from xnlos_core.errors import InputError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.types import RAMap
from xnlos_core.validation import as_array

_CHUNK = 2048  # paths per dechirp chunk: bounds the (n_samples, chunk) complex128 temporary
_FFT_BLOCK_BYTES = 1 << 18  # columns per block of the range FFT: n_samples × block complex128 ≈ 256 KiB


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


def dechirp(radar: RadarConfig, path_length, azimuth, amplitude, elevation=None) -> np.ndarray:
    """Synthesise the dechirped baseband cube of a set of paths (Eq. 6), (n_samples, n_channels) complex128.

    path_length (P,): unfolded round-trip length L [m] (one-way equivalent range L/2);
    azimuth (P,): arrival azimuth θ [rad]; amplitude (P,): complex amplitude a [√W];
    elevation (P,) or None: arrival elevation ε [rad] (None: all in the horizontal plane).

        s_k[n] = Σ_p a_p · exp(j(2π f_b,p t_n + 2π f_c τ_p − π S τ_p²)) · a_k(θ_p, ε_p)

    with a_k the channel steering vector (:func:`xnlos_core.signal.antenna.steering_vector`). When the
    radar has mutual coupling (:func:`xnlos_core.signal.antenna.coupling_matrix`) the channels are mixed
    as the hardware would: s ← s·Cᵀ (x = C·x₀ per sample).

    with τ = L/c, S = B/T, f_b = S·τ (conjugate product g·g*(t−τ), so f_b > 0). The sum is
    separable, so it is a matrix product (N, P) @ (P, M), done in chunks of paths, with the tones
    evaluated without a complex exponential per sample (:func:`dechirp_paths`). The IF
    anti-aliasing low-pass is ideal: paths with f_b ≥ f_s (beyond the unambiguous range) are
    not sampled, instead of aliasing to short range.
    """
    L = np.atleast_1d(np.asarray(path_length, dtype=np.float64))
    th = np.atleast_1d(np.asarray(azimuth, dtype=np.float64))
    a = np.atleast_1d(np.asarray(amplitude, dtype=np.complex128))
    el = np.zeros_like(th) if elevation is None else np.atleast_1d(np.asarray(elevation, dtype=np.float64))
    if not (L.shape == th.shape == a.shape == el.shape and L.ndim == 1):
        raise InputError(f"dechirp: path_length, azimuth, amplitude, elevation must be 1-D of equal length, "
                         f"got {L.shape}, {th.shape}, {a.shape}, {el.shape}")
    return dechirp_paths(radar, L, th, a, el)


def dechirp_paths(radar: RadarConfig, L: np.ndarray, th: np.ndarray, a: np.ndarray, el: np.ndarray,
                   channels: slice | None = None) -> np.ndarray:
    """:func:`dechirp` of validated float64/complex128 path arrays, for the virtual channels ``channels``
    (None: all). th, el (P,); L, a (P,) → (n_samples, n_selected) complex128, or (G, P) → (G, n_samples,
    n_selected): G cubes of the same P arrival directions (the chirps of a chirp sequence), at once.

    Coupling is folded into the steering matrix (s·Cᵀ = tones·(A·Cᵀ)), so a channel subset costs
    only its columns. The tones exp(j2π(f_b·n/f_s + φ₀)) are never evaluated per sample: with
    n = K·q + r (block length K = ⌈√N⌉), exp(j2π f_b n/f_s) = exp(j2π f_b K q/f_s) · exp(j2π f_b r/f_s)
    (the outer-product factorisation exp(j(x+y)) = e^{jx}·e^{jy}), so each path needs K + N/K complex
    exponentials instead of N, and each tone is one product of two directly evaluated factors
    (no recurrence, so no accumulated rounding: a few ulp per sample, relative ~1e-13 to the old
    per-sample evaluation at the default size, tests/unit/test_dechirp_fast.py).
    """
    single = L.ndim == 1
    L, a = np.atleast_2d(L), np.atleast_2d(a)
    tau = L / SPEED_OF_LIGHT
    fb = radar.chirp_slope * tau
    keep = (fb >= 0) & (fb < radar.sample_rate) & (a != 0)
    if single:  # drop the unsampled paths; in a batch they keep their column with amplitude 0
        k1 = keep[0]
        L, a, tau, fb, th, el, keep = L[:, k1], a[:, k1], tau[:, k1], fb[:, k1], th[k1], el[k1], keep[:, k1]
    a = np.where(keep, a, 0.0)
    g, p = L.shape
    n = radar.n_samples
    # constant phase in cycles: f_c τ = L/λ (mod 1 first, float64), minus the residual video phase S τ²/2
    phase0 = np.mod(L / radar.wavelength, 1.0) - 0.5 * radar.chirp_slope * tau**2
    x = fb / radar.sample_rate  # beat frequency in cycles per sample, [0, 1) where kept
    kb = max(1, int(np.ceil(np.sqrt(n))))  # inner block length K; ⌈N/K⌉ outer blocks
    q_blocks = -(-n // kb)
    r_idx = np.arange(kb, dtype=np.float64)[:, None]
    q_idx = np.arange(q_blocks, dtype=np.float64)[:, None] * kb
    steer = steering_vector(radar, th, el).T  # (P, M)
    c = coupling_matrix(radar)
    if c is not None:
        steer = steer @ c.T
    if channels is not None:
        steer = steer[:, channels]
    steer = np.ascontiguousarray(steer)  # a transposed view would send the stacked matmul below off BLAS (~1000× slower)
    nq = q_blocks * kb  # ≥ N rows: the few padding samples are computed and cropped at the end
    cube = np.zeros((g, nq, steer.shape[1]), dtype=np.complex128)
    pc = max(1, min(p, _CHUNK))  # paths per chunk, and cubes per chunk: the (G', N, P') temporary ≤ N·_CHUNK
    gc = max(1, _CHUNK // pc)
    for j in range(0, g, gc):
        gs = slice(j, j + gc)
        for i in range(0, p, pc):
            sl = slice(i, i + pc)
            xs = x[gs, sl][:, None, :]  # (G', 1, P')
            inner = np.exp(2j * np.pi * (r_idx * xs + phase0[gs, sl][:, None, :])) * a[gs, sl][:, None, :]
            outer = np.exp(2j * np.pi * np.mod(q_idx * xs, 1.0))  # (G', N/K, P'): e^{j2π x K q}
            tones = (outer[:, :, None, :] * inner[:, None, :, :]).reshape(-1, xs.shape[2])  # (G'·N, P')
            cube[gs] += (tones @ steer[sl]).reshape(len(xs), nq, -1)  # one gemm (P', M'), not G' small ones
    cube = cube[:, :n] if nq > n else cube
    return np.ascontiguousarray(cube[0] if single else cube)


def add_noise(cube: np.ndarray, radar: RadarConfig, rng: np.random.Generator) -> np.ndarray:
    """Return ``cube`` plus circular complex Gaussian noise of power ``radar.noise_power`` [W] per sample."""
    sd = np.sqrt(radar.noise_power / 2.0)
    noise = rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)
    return cube + sd * noise


def _window(name: str, n: int) -> np.ndarray:
    # symmetric taper (fftbins=False), same convention as the azimuth weights
    return symmetric_window(name, n)


@functools.lru_cache(maxsize=32)
def range_taper(name: str, n: int) -> np.ndarray:
    """Range window over its coherent gain, w / Σw, (n,) float64, read-only (cached per name and size)."""
    w = _window(name, n)
    w = w / w.sum()
    w.flags.writeable = False
    return w


def processing_gain(radar: RadarConfig) -> float:
    """G_p = N·M / (ENBW_r·ENBW_a) (linear): RA-map SNR of a grid-centred point over per-sample SNR."""
    return _processing_gain(radar)


@functools.lru_cache(maxsize=32)
def _processing_gain(radar: RadarConfig) -> float:
    """:func:`processing_gain`, cached per (frozen, hashable) radar: the simulators ask for it per path set."""
    wr = _window(radar.range_window, radar.n_samples)
    wa = azimuth_weights(radar)
    return float(wr.sum() ** 2 / (wr**2).sum() * wa.sum() ** 2 / (wa**2).sum())


def noise_floor(radar: RadarConfig) -> float:
    """Expected |κ|² [W] of a noise-only RA cell: σ² / G_p (see module docstring)."""
    return radar.noise_power / processing_gain(radar)


def range_fft(cube: np.ndarray, radar: RadarConfig, *, workers: int | None = None) -> np.ndarray:
    """Windowed range FFT along axis 0, cropped to radar.n_range_bins → (n_range_bins, n_channels) complex128.

    Normalised by the window's coherent gain Σw_r, so a tone of complex amplitude A at the
    centre of bin k gives exactly A in bin k (bin k ↔ range k·ΔR, f_b = k/T). cube: (n_samples, ...)
    complex (any trailing axes). workers: threads of :func:`scipy.fft.fft` (None: one).

    The columns are windowed and transformed in blocks of ~256 KiB (:data:`_FFT_BLOCK_BYTES`) that stay
    in cache: the same numbers as one call over all columns (the transform of each column does not
    depend on the others), ~1.8× faster for the (512, 2048) chirp-sequence cube.
    """
    w = range_taper(radar.range_window, radar.n_samples)
    arr = np.asarray(cube)
    cols = arr.reshape(arr.shape[0], -1)
    n_out = radar.n_range_bins
    out = np.empty((n_out, cols.shape[1]), dtype=np.result_type(cols.dtype, np.complex128))
    step = max(8, _FFT_BLOCK_BYTES // (16 * max(1, arr.shape[0]))) * max(1, workers or 1)
    for j in range(0, cols.shape[1], step):
        tapered = cols[:, j:j + step] * w[:, None]  # a new array: the FFT may overwrite it
        out[:, j:j + step] = scipy.fft.fft(tapered, axis=0, overwrite_x=True, workers=workers)[:n_out]
    return out.reshape((n_out,) + arr.shape[1:])


def beamform(range_profiles: np.ndarray, radar: RadarConfig) -> np.ndarray:
    """Windowed delay-and-sum onto radar.azimuth_axis: (n_range, n_channels) → (n_range, n_azimuth).

    κ(r, θ) = Σ_k w_k a_k*(θ) X_k(r) / Σ w_k, so a unit plane wave from a grid angle gives 1.
    """
    return range_profiles @ _beam_weights(radar)


def beam_weights(radar: RadarConfig) -> np.ndarray:
    """Delay-and-sum weights w_k a_k*(θ) / Σ w_k of :func:`beamform`, (n_channels, n_azimuth_bins) complex128.

    Computed once per radar (cached, read-only); the caller gets a writable copy."""
    return _beam_weights(radar).copy()


@functools.lru_cache(maxsize=32)
def _beam_weights(radar: RadarConfig) -> np.ndarray:
    w = azimuth_weights(radar)
    out = (w / w.sum())[:, None] * steering_vector(radar, radar.azimuth_axis).conj()
    out.flags.writeable = False
    return out


def decouple(range_profiles: np.ndarray, radar: RadarConfig) -> np.ndarray:
    """Undo mutual coupling, x₀ = C⁻¹x per range bin, when ``radar.coupling_compensation`` is set
    (a calibrated radar); otherwise return the profiles unchanged. (n_range, n_channels)."""
    c = coupling_matrix(radar) if radar.coupling_compensation else None
    if c is None:
        return range_profiles
    try:
        return np.linalg.solve(c, range_profiles.T).T
    except np.linalg.LinAlgError:
        raise InputError("coupling matrix is singular: coupling_compensation cannot invert it") from None


def ra_map_from_cube(cube: np.ndarray, radar: RadarConfig) -> RAMap:
    """Range FFT, coupling compensation (if configured) and beamforming of a (n_samples,
    n_channels) cube → RAMap (complex64). No validation."""
    return RAMap.from_radar(beamform(decouple(range_fft(cube, radar), radar), radar).astype(np.complex64), radar)


def adc_to_ra_map(cube, radar: RadarConfig) -> RAMap:
    """Entry point for measured ADC cubes: validate, then :func:`ra_map_from_cube`.

    cube: complex (n_samples, n_channels) in √W, channels tx-major like
    radar.virtual_positions. Raises InputError on a wrong shape or non-finite values.
    For raw hardware layouts (int16 I/Q, other axis orders, several chirps) see
    :func:`hardware.adc.adc_cube_to_ra_map`.
    """
    want = (radar.n_samples, radar.n_channels)
    shape = np.shape(cube)
    if tuple(shape) != want:
        raise InputError(f"adc cube: expected shape (n_samples, n_channels) = {want} for this radar, "
                         f"got {tuple(shape)}")
    arr = as_array("adc cube", cube, dtype=np.complex128)
    return ra_map_from_cube(arr, radar)
