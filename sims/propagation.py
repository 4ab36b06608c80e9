"""Propagation: free-space path loss, the radar equation with antenna patterns, and SNR.

    FSPL(f, d) = (4π d f / c)²                                    (Friis; Fig. 2a in dB)
    P_r = P_t · G_tx(θ, ε) · G_e(θ, ε)² · λ² · σ · |α|⁴ / ((4π)³ · r⁴ · L_sys · L_atm)

for a path with unfolded one-way range r [m] (both legs equal: |o| for a direct echo, |o'| for
a mirrored one, Eq. 4–5), arrival direction (θ, ε), radar cross-section σ [m²] and specular
amplitude reflectivity α per relay bounce (two bounces → |α|⁴). G_e is the element pattern
B_t = B_r (:func:`xnlos_core.signal.antenna.element_gain`), G_tx the factor from transmitting on
several elements at once (:func:`xnlos_core.signal.antenna.transmit_gain`, 1 for MIMO), L_atm the
gaseous loss over the 2r round trip (:mod:`sims.atmosphere`), applied only when asked for.
The SNR in the RA map is P_r·G_p/(k·T·f_s·NF) with the processing gain G_p of
:func:`xnlos_core.signal.chain.processing_gain`.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.signal.antenna import element_gain, transmit_gain
from xnlos_core.errors import InputError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.chain import processing_gain

from . import atmosphere


def free_space_path_loss_db(f_hz, distance_m) -> np.ndarray:
    """FSPL = 20·log10(4π d f / c) [dB], broadcast over f [Hz] and d [m] (both > 0), float64."""
    f = np.asarray(f_hz, dtype=np.float64)
    d = np.asarray(distance_m, dtype=np.float64)
    if np.any(~(f > 0)) or np.any(~(d > 0)) or not (np.all(np.isfinite(f)) and np.all(np.isfinite(d))):
        raise InputError("free_space_path_loss_db: frequency and distance must be finite and > 0")
    return 20.0 * (np.log10(4 * np.pi / SPEED_OF_LIGHT) + np.log10(f) + np.log10(d))


def received_power(radar: RadarConfig, r, theta, sigma, alpha=1.0, elevation=0.0,
                   atmosphere_loss_db=0.0) -> np.ndarray:
    """Radar equation per path [W] (module doc), broadcast over all array arguments.

    r [m] (unfolded one-way range, > 0); θ, ε [rad]; σ [m²]; α amplitude reflectivity per relay
    bounce (complex allowed, |α|⁴ enters); atmosphere_loss_db: round-trip gaseous loss [dB].
    Computed in log space where it matters so that r from 0.5 m to kilometres and σ across
    200 dB stay finite in float64.
    """
    r = np.asarray(r, dtype=np.float64)
    if np.any(~(r > 0)):
        raise InputError("received_power: unfolded range r must be > 0 m")
    g = element_gain(radar, theta, elevation)
    gt = transmit_gain(radar, theta, elevation)
    loss_db = radar.system_loss_db + np.asarray(atmosphere_loss_db, dtype=np.float64)
    num = radar.transmit_power * gt * g * g * radar.wavelength**2 * np.asarray(sigma, dtype=np.float64)
    num = num * np.abs(np.asarray(alpha)) ** 4
    return num / ((4 * np.pi) ** 3 * r**2 * r**2 * 10.0 ** (loss_db / 10.0))


def ra_snr_db(radar: RadarConfig, power) -> np.ndarray:
    """RA-map SNR [dB] of a grid-centred path of received power ``power`` [W] (−inf for 0 W)."""
    with np.errstate(divide="ignore"):
        return 10 * np.log10(np.asarray(power, dtype=np.float64) * processing_gain(radar) / radar.noise_power)


def detectable_snr_db(pd: float = 0.5, pfa: float = 1e-5) -> float:
    """Single-look SNR [dB] at which a steady target is detected with probability ``pd`` at
    false-alarm probability ``pfa`` per cell (Albersheim's approximation, accurate to ≈ 0.2 dB for
    1e-7 ≤ pfa ≤ 1e-3, 0.1 ≤ pd ≤ 0.9):

        A = ln(0.62/pfa),  B = ln(pd/(1 − pd)),  SNR = A + 0.12·A·B + 1.7·B   [linear]

    The default (pd 0.5 at the CFAR detector's default pfa 1e-5) is 10.4 dB: the threshold
    below which simulators leave a return out of the ground truth (:data:`DETECTABLE_SNR_DB`).
    """
    if not (1e-7 <= pfa <= 1e-3):
        raise InputError(f"detectable_snr_db: pfa must lie in [1e-7, 1e-3] (Albersheim's range), got {pfa!r}")
    if not (0.1 <= pd <= 0.9):
        raise InputError(f"detectable_snr_db: pd must lie in [0.1, 0.9] (Albersheim's range), got {pd!r}")
    a, b = np.log(0.62 / pfa), np.log(pd / (1 - pd))
    return float(10 * np.log10(a + 0.12 * a * b + 1.7 * b))


#: Ground-truth detectability threshold [dB]: :func:`detectable_snr_db` (pd 0.5, pfa 1e-5) ≈ 10.4 dB.
DETECTABLE_SNR_DB = round(detectable_snr_db(), 1)


def round_trip_atmosphere_db(radar: RadarConfig, r, **conditions) -> np.ndarray:
    """Gaseous loss [dB] over the 2r round trip at the radar's carrier (ITU-R P.676), r [m]."""
    return atmosphere.attenuation_db(radar.carrier_frequency, 2.0 * np.asarray(r, dtype=np.float64), **conditions)
