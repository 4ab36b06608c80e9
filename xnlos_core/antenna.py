"""Antenna model: element pattern (B_t, B_r of Eq. 1–6), virtual-array steering and beam metrics.

Conventions (DESIGN.md): the virtual uniform linear array lies along the ego y axis at
``radar.virtual_positions`` y_k [m]; azimuth θ = atan2(y, x) [rad], positive to the left.
A path arriving from θ is shorter at element k by y_k·sin θ (round trip through the MIMO virtual
element), so its phase there is advanced: the steering vector is a_k(θ) = exp(−j 2π y_k sin θ / λ).
This is the same sign that :func:`xnlos_core.signal_chain.dechirp` uses for the synthetic cube.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import get_window

from .radar import RadarConfig


def element_gain(radar: RadarConfig, theta) -> np.ndarray:
    """Power gain of one patch-like element, G_e(θ) = G0·cos(θ)^q (linear, not dB).

    This is B_t = B_r of Eq. 1/3/5. G0 = 10^(element_gain_dbi/10), q = element_pattern_exponent.
    θ [rad], any shape; the pattern is zero for |θ| ≥ 90° (a patch radiates into its half-space).
    """
    th = np.angle(np.exp(1j * np.asarray(theta, dtype=np.float64)))  # wrap to (−π, π]
    g0 = 10.0 ** (radar.element_gain_dbi / 10.0)
    c = np.cos(th)
    front = np.abs(th) < np.pi / 2
    # clip before the power: cos^q of a negative number is NaN for non-integer q
    return np.where(front, g0 * np.clip(c, 0.0, None) ** radar.element_pattern_exponent, 0.0)


def steering_vector(radar: RadarConfig, theta) -> np.ndarray:
    """Array response a_k(θ) = exp(−j 2π y_k sin θ / λ), shape (n_virtual, n_theta), complex128.

    θ [rad]: scalar or 1-D. Unit modulus per element; no element pattern included.
    """
    th = np.atleast_1d(np.asarray(theta, dtype=np.float64))
    y = radar.virtual_positions  # float64 [m]
    return np.exp(-2j * np.pi * np.outer(y, np.sin(th)) / radar.wavelength)


def azimuth_weights(radar: RadarConfig, window: str | None = None) -> np.ndarray:
    """Real taper over the virtual elements (n_virtual,), symmetric; default radar.azimuth_window."""
    name = radar.azimuth_window if window is None else window
    # symmetric (fftbins=False) so the beam is symmetric about the steering angle
    return np.asarray(get_window(name, radar.n_tx * radar.n_rx, fftbins=False), dtype=np.float64)


def array_factor(radar: RadarConfig, theta, steer_to: float = 0.0, window: str = "boxcar") -> np.ndarray:
    """Normalised power array factor |Σ w_k a_k(θ) a_k*(θ₀)|² / (Σ w_k)², shape like ``theta``.

    Equals 1 at θ = θ₀ = ``steer_to`` [rad]; ``window`` is a scipy.signal window name.
    Element pattern not included (multiply by :func:`element_gain` for the full two-way beam).
    """
    th = np.asarray(theta, dtype=np.float64)
    w = azimuth_weights(radar, window)
    a = steering_vector(radar, th.ravel())
    a0 = steering_vector(radar, steer_to)[:, 0]
    af = (w * a0.conj()) @ a / w.sum()
    return (np.abs(af) ** 2).reshape(th.shape)


def beam_metrics(radar: RadarConfig, window: str | None = None, step: float = 2e-5) -> dict[str, float]:
    """Numerical beam metrics of the delay-and-sum beam steered to boresight.

    window: scipy window name, default ``radar.azimuth_window`` (what the RA map uses).
    Returns a dict:
      ``beamwidth_3db`` [rad]: full width between the −3 dB points (the azimuth resolution);
      ``first_null`` [rad]: angle of the first minimum of the main lobe (from boresight);
      ``peak_sidelobe_db`` [dB]: highest array-factor level beyond the first null, ≤ 0;
      ``*_deg`` copies in degrees. Grid: ``step`` [rad] over [0, π/2] (the beam is symmetric).
    """
    th = np.arange(0.0, np.pi / 2, step)
    af = array_factor(radar, th, 0.0, radar.azimuth_window if window is None else window)
    # −3 dB crossing: linear interpolation between the bracketing grid points
    i = int(np.argmax(af < 0.5))
    half = th[i - 1] + (0.5 - af[i - 1]) * (th[i] - th[i - 1]) / (af[i] - af[i - 1])
    # first null: first point where the main lobe stops falling
    rising = np.flatnonzero(np.diff(af) > 0)
    j = int(rising[0]) if len(rising) else len(af) - 1
    sidelobe = float(af[j:].max()) if j < len(af) - 1 else 0.0
    out = {
        "beamwidth_3db": float(2 * half),
        "first_null": float(th[j]),
        "peak_sidelobe_db": float(10 * np.log10(max(sidelobe, 1e-30))),
    }
    out["beamwidth_3db_deg"] = float(np.degrees(out["beamwidth_3db"]))
    out["first_null_deg"] = float(np.degrees(out["first_null"]))
    return out
