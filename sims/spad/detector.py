"""SPAD detection: background (dark counts, ambient light), optional pile-up, photon counting.

Per pulse, bin k of a scan point receives μ_k = s_k/N + (r_dark + r_amb)·Δ expected detections
(s_k the expected signal over N pulses, rates [counts/s], Δ the bin width [s]).

* Without pile-up (a detector that counts every photon, or the low-flux limit) the histogram is
  Poisson with mean N·μ_k.
* With pile-up (one detection per pulse, then dead until the next: time-correlated single-photon
  counting), each pulse records its first detection, in bin k with probability
  p_k = (1 − e^{−μ_k}) · e^{−Σ_{j<k} μ_j} (Coates 1968), or nothing with probability e^{−Σ μ_j};
  the histogram over N pulses is multinomial(N, p). :func:`coates_correction` inverts it.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.validation import as_array


def background_per_bin(dark_rate: float, ambient_rate: float, bin_width: float, n_pulses: float) -> float:
    """Expected background counts per bin over ``n_pulses`` pulses: (r_dark + r_amb)·Δ·N."""
    return (dark_rate + ambient_rate) * bin_width * n_pulses


def first_photon_probabilities(mu: np.ndarray) -> np.ndarray:
    """Coates: p_k = (1 − e^{−μ_k}) e^{−Σ_{j<k} μ_j} per pulse, μ (T, ...) detections per pulse per
    bin along axis 0; returns p of the same shape (Σ p ≤ 1, the rest is no detection)."""
    mu = as_array("mu", mu)
    if mu.size and mu.min() < 0:
        raise InputError(f"mu: expected detections per pulse ≥ 0, got min {mu.min():g}")
    before = np.cumsum(mu, axis=0) - mu
    return -np.expm1(-mu) * np.exp(-before)


def coates_correction(counts: np.ndarray, n_pulses: float) -> np.ndarray:
    """Estimate μ_k (T, ...) per pulse from a piled-up histogram ``counts`` (T, ...) of ``n_pulses``:
    μ_k = −ln(1 − h_k / (N − Σ_{j<k} h_j)) (Coates 1968)."""
    h = as_array("counts", counts)
    left = n_pulses - (np.cumsum(h, axis=0) - h)
    if np.any(left <= 0):
        raise InputError(f"counts: histogram holds more than n_pulses = {n_pulses:g} detections")
    return -np.log1p(-np.clip(h / left, 0.0, 1.0 - 1e-15))


def detect(signal: np.ndarray, *, n_pulses: int, bin_width: float, dark_rate: float = 0.0,
           ambient_rate: float = 0.0, pile_up: bool = False, rng: np.random.Generator) -> np.ndarray:
    """Sampled photon counts (T, H, W) from the expected signal (T, H, W) over ``n_pulses`` pulses:
    background added, then Poisson (no pile-up) or multinomial first-photon (pile-up) sampling
    with ``rng`` (a seeded numpy Generator)."""
    s = as_array("signal", signal, ndim=3)
    if s.size and s.min() < 0:
        raise InputError(f"signal: expected counts ≥ 0, got min {s.min():g}")
    if not isinstance(rng, np.random.Generator):
        raise InputError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    if n_pulses < 1:
        raise InputError(f"n_pulses: expected ≥ 1 pulse, got {n_pulses}")
    mean = s + background_per_bin(dark_rate, ambient_rate, bin_width, n_pulses)
    if not pile_up:
        return rng.poisson(mean).astype(np.float64)
    p = first_photon_probabilities(mean / n_pulses)
    t = p.shape[0]
    pv = np.moveaxis(p, 0, -1)  # (H, W, T)
    pv = np.concatenate([pv, np.clip(1.0 - pv.sum(-1, keepdims=True), 0.0, None)], axis=-1)
    pv /= pv.sum(-1, keepdims=True)
    counts = rng.multinomial(int(n_pulses), pv)[..., :t]
    return np.moveaxis(counts, -1, 0).astype(np.float64)
