"""Statistics of raw ADC words that tell a recording's layout from its data.

Each is computed from the samples alone, with no knowledge of the scene beyond what any radar's
beat signal shares:

* :func:`encoding_evidence` — a radar's samples are small around zero: the 16-bit codes read as two's
  complement and as offset binary differ by 32768 in one of the two readings, whose RMS is then
  near full scale.
* :func:`periodicity` — a static scene repeats every chirp loop: the word stream's normalised
  autocorrelation at the loop length (n_samples · receivers · TX slots · words per sample) is close
  to 1, and low at a wrong length (n_samples, n_rx, n_tx, real/complex).
* :func:`spectrum_stats` — the beat signal of a correct decoding is a few tones over a flat floor
  (a peaky range spectrum, peak over median in dB); lanes, I/Q interleave or real/complex decoded
  wrongly split each tone into images, which lowers the peak, and a complex decoding of real or
  mis-paired words puts mirror images at −f (spectral symmetry).
* the same spectrum's near/far balance — echoes weaken with range (R⁻⁴) and leakage sits at the
  nearest bins, so a complex spectrum whose energy sits in its upper half is most likely conjugated:
  I and Q exchanged (Q + jI = j·conj(I + jQ) mirrors every beat frequency f → −f).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft

from ..raw_formats import signed_words


def encoding_evidence(words) -> float:
    """20·log10(RMS as two's complement / RMS as offset binary) [dB] of 16-bit codes ``words``:
    > 0 when the offset-binary reading is the smaller one (the words are offset binary), < 0 when
    two's complement is. |value| < 6 dB: the codes alone cannot tell (full-scale noise, too few)."""
    w = np.asarray(words)
    if w.dtype.itemsize != 2 or w.dtype.kind not in "iu" or w.size == 0:
        return 0.0
    twos = w.astype(np.int32) - (65536 * (w.astype(np.int64) > 32767) if w.dtype.kind == "u" else 0)
    ob = signed_words(w, "offset_binary")
    rt, ro = np.sqrt(np.mean(twos.astype(np.float64) ** 2)), np.sqrt(np.mean(ob.astype(np.float64) ** 2))
    return float(20 * np.log10(max(rt, 0.5) / max(ro, 0.5)))


def periodicity(stream, max_lag: int) -> np.ndarray:
    """Normalised autocorrelation r(ℓ) = Σ x(t)·x(t+ℓ) / √(Σ x(t)² · Σ x(t+ℓ)²), ℓ = 0 … max_lag, of the
    mean-removed real word stream (1-D) — one FFT for every lag. r(ℓ) ≈ 1 when a static scene's
    samples repeat every ℓ words, ≈ 0 for noise. Lags past half the stream are 0 (too little overlap)."""
    x = np.asarray(stream, dtype=np.float64).ravel()
    x = x - x.mean()
    n = x.size
    max_lag = int(min(max_lag, n // 2))
    nfft = scipy.fft.next_fast_len(n + max_lag + 1, real=True)
    f = scipy.fft.rfft(x, nfft)
    acf = scipy.fft.irfft(f * np.conj(f), nfft)[:max_lag + 1]
    c = np.concatenate([[0.0], np.cumsum(x * x)])
    lag = np.arange(max_lag + 1)
    head = c[n - lag]              # Σ_{t < n−ℓ} x(t)²
    tail = c[n] - c[lag]           # Σ_{t ≥ ℓ} x(t)²
    den = np.sqrt(head * tail)
    r = np.divide(acf, den, out=np.zeros_like(acf), where=den > 0)
    return np.clip(r, -1.0, 1.0)


@dataclass(frozen=True)
class SpectrumStats:
    """Fast-time spectrum of a decoded frame.

    peak_db: mean of the 3 strongest bins over the median bin [dB] (DC bins left out); symmetry: the
    share of the power above twice the median that has a mirror image at −f, Σ min(P(f), P(−f)) / Σ P(f)
    ∈ [0, 1] (complex only: a beat signal has no mirror images, real or mis-paired words do); near_far_db: energy below half the band over energy
    above it [dB] (complex only; > 0 for a radar scene, < 0 when I and Q are exchanged)."""

    peak_db: float
    symmetry: float
    near_far_db: float


def spectrum_stats(cube: np.ndarray, complex_samples: bool) -> SpectrumStats:
    """:class:`SpectrumStats` of decoded samples ``cube`` (n_samples, chirps, receivers) [counts],
    complex (I/Q) or real (``complex_samples`` False: the one-sided spectrum). Power is averaged over
    chirps and receivers after a Hann window; bins within one of DC are left out (offsets, leakage)."""
    z = np.asarray(cube)
    n = z.shape[0]
    w = np.hanning(n + 2)[1:-1]
    spec = scipy.fft.fft(z * w[:, None, None], axis=0)
    p = (np.abs(spec) ** 2).reshape(n, -1).mean(axis=1)
    if complex_samples:
        valid = np.r_[2:n - 1]
    else:
        p = p[:n // 2]
        valid = np.r_[2:n // 2 - 1]
    pv = p[valid]
    med = float(np.median(pv))
    if med <= 0 or pv.size < 8:
        return SpectrumStats(0.0, 0.0, 0.0)
    peak = float(np.sort(pv)[-3:].mean())
    if not complex_samples:
        return SpectrumStats(float(10 * np.log10(peak / med)), 0.0, 0.0)
    k = np.arange(2, n - 1)
    above = np.maximum(p[k] - 2 * med, 0.0)  # energy above the floor
    mirrored = np.maximum(p[n - k] - 2 * med, 0.0)
    total = float(above.sum())
    sym = float(np.minimum(above, mirrored).sum() / total) if total > 0 else 0.0
    low, high = p[2:n // 2].sum(), p[n // 2 + 1:n - 1].sum()
    near_far = float(10 * np.log10(max(low, 1e-300) / max(high, 1e-300)))
    return SpectrumStats(float(10 * np.log10(peak / med)), sym, float(np.clip(near_far, -40, 40)))
