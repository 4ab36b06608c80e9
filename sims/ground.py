"""3-D propagation: radar mounting height and tilt, scatterer heights, the elevation pattern, and the ground.

The forward models find their paths in the horizontal plane (vertical walls: a mirror leaves the
height of a point unchanged, so every path unfolds, in plan, into one straight line of horizontal
length d from the radar to the scatterer or its image o'). Heights then enter as in the classical
two-ray model. With the radar at height h_r, boresight tilted up by τ, and a scatterer at height
h_t, a path's one-way legs are

    direct   R_D = √(d² + (h_t − h_r)²),  elevation ε_D = atan2(h_t − h_r, d)
    ground   R_G = √(d² + (h_t + h_r)²),  elevation ε_G = −atan2(h_t + h_r, d)     (the radar's image
                                                                                  below z = 0)

and a ground leg reflects once, at the grazing angle ψ = atan2(h_t + h_r, d), with the ground's
amplitude coefficient Γ(ψ) (:func:`ground_reflection`). A monostatic round trip is one leg out and
one back; all four combinations are modelled, each its own path (:func:`twins`):

    DD: length 2R_D,       amplitude ∝ √(G_t(ε_D) G_r(ε_D)) / (R_D R_D)
    DG: length R_D + R_G,  amplitude ∝ Γ √(G_t(ε_D) G_r(ε_G)) / (R_D R_G)   (out direct, back via ground)
    GD: length R_G + R_D,  amplitude ∝ Γ √(G_t(ε_G) G_r(ε_D)) / (R_G R_D)
    GG: length 2R_G,       amplitude ∝ Γ² √(G_t(ε_G) G_r(ε_G)) / (R_G R_G)

with G_t, G_r the transmit and receive element gains at elevation ε − τ in the board frame
(:func:`xnlos_core.signal.antenna.element_gain`, :func:`~xnlos_core.signal.antenna.transmit_gain`),
relative to the 2-D model's gains at ε = 0 and its 1/d² per leg. DG and GD have equal lengths but
arrive from different elevations, which an array with channels at several heights tells apart, so
they stay two paths. Without a ground only DD remains (the elevation pattern and tilt).

Two-ray nulls: with equal gains on both legs and Γ = −1, the carrier sum is
(e^{−jkR_D} − e^{−jkR_G})², so the received power ∝ sin⁴(k (R_G − R_D)/2): zero where
R_G − R_D = nλ (n = 1, 2, …), the same places as the one-way two-ray nulls, far from the radar at
d_n ≈ 2 h_r h_t / (nλ) (:func:`null_ranges` solves the exact condition). In an FMCW range bin
the paths add with the phase of the middle of the sampled sweep, so λ is that of the sweep's
mean frequency f_c + S·(N − 1)/(2 f_s) (:func:`sweep_wavelength`), not of its start f_c: at
600 MHz over 10 GHz the nulls sit 3 % farther out than the start frequency predicts.

Simplifications: the scatterer keeps its RCS for every combination (an isotropic point), the
incidence angle on a vertical wall is taken in plan (the elevation's effect on it is second order),
walls are taken tall enough to hold every bounce point, the elevation pattern's tilt is a shift of
ε (exact in the boresight plane), and a bistatic (mixed) path of the ray tracer is treated as a
monostatic path of half its length.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.antenna import element_gain, transmit_gain

from .fresnel import fresnel
from .material_fallback import material_at
from .paths import Paths


def ground_reflection(ground, radar: RadarConfig, grazing) -> np.ndarray:
    """Amplitude reflection coefficient Γ (complex, shape of ``grazing``) of ``ground`` (a
    :class:`xnlos_core.scene.GroundSpec`) at grazing angles ψ [rad] (from the ground plane).

    A material: Fresnel at incidence θ = π/2 − ψ from the normal (:func:`sims.fresnel.fresnel`);
    the radar's V polarisation lies in the vertical plane of incidence (TM, ``"p"``), H is TE
    (``"s"``). Both tend to −1 at grazing. A constant ``reflection``: that value at every angle.
    """
    psi = np.asarray(grazing, dtype=np.float64)
    if ground.reflection is not None:
        return np.full(psi.shape, ground.reflection, dtype=np.complex128)
    f = radar.carrier_frequency
    eps = material_at(ground.material, f).permittivity(f)
    r, _ = fresnel(eps, np.pi / 2 - np.clip(psi, 0.0, np.pi / 2), "p" if radar.polarization == "V" else "s")
    return np.asarray(r, dtype=np.complex128)


@dataclasses.dataclass(frozen=True)
class Twins:
    """The 3-D paths of P 2-D paths: Q = P (no ground) or 4P (DD, DG, GD, GG blocks of P each).

    paths: the Q paths (lengths, complex amplitudes with the reflection phases, azimuth, the
    source path's point, object and random phase); source (Q,) int: index of each one's 2-D path;
    elevation (Q,) [rad]: arrival elevation in the board frame (ε − tilt), for the steering vector;
    gain (P,): |Σ of a 2-D path's twins at the carrier|² / its 2-D power — the power factor the
    ground truth's SNR takes (two-ray interference, elevation pattern); 0 where the 2-D power is 0.
    """

    paths: Paths
    source: np.ndarray
    elevation: np.ndarray
    gain: np.ndarray


def centre_height(obj, radar_height: float) -> float:
    """Height above the ground [m] of an object's scattering centres: its ``centre_height``, or the
    radar's mounting height capped at the object's height."""
    return obj.centre_height if obj.centre_height is not None else min(radar_height, obj.height)


def sweep_wavelength(radar: RadarConfig) -> float:
    """Wavelength [m] at the mean frequency f_c + S·(N − 1)/(2 f_s) of the sampled chirp: the phase a
    path has in its range bin (module doc)."""
    f = radar.carrier_frequency + radar.chirp_slope * (radar.n_samples - 1) / (2 * radar.sample_rate)
    return SPEED_OF_LIGHT / f


def heights(paths: Paths, radar_height: float) -> np.ndarray:
    """(P,) scatterer heights [m]: :attr:`Paths.height`, NaN or None read as ``radar_height``."""
    if paths.height is None:
        return np.full(len(paths), float(radar_height))
    return np.where(np.isnan(paths.height), float(radar_height), paths.height)


def _blocks(r_d, d, h_t, th, radar: RadarConfig, radar_height: float, tilt: float, ground) -> list:
    """The round trips of the module doc per scatterer: [(amplitude factor relative to the 2-D path,
    one-way out + back length [m], arrival elevation ε [rad]) for DD, and DG, GD, GG with a ground].
    r_d: direct one-way length [m]; d: its horizontal length [m]; h_t: heights [m]; th: azimuth [rad]
    (broadcast shapes)."""
    h_r = float(radar_height)
    eps_d = np.arctan2(h_t - h_r, d)
    g0 = element_gain(radar, th, 0.0)
    ref = g0 * g0 * transmit_gain(radar, th, 0.0)  # what the 2-D model's power holds (ε = 0, no tilt)

    def leg_pair(out, back):  # legs (elevation, one-way length, reflection, (G_e, G_t) at that elevation)
        (g_out, t_out), (g_in, _) = out[3], back[3]
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.where(ref > 0, np.sqrt(g_out * t_out * g_in / np.where(ref > 0, ref, 1.0)), 0.0)
        return f * r_d * r_d / (out[1] * back[1]) * (out[2] * back[2])

    legs = [(eps_d, r_d, np.ones(np.shape(r_d)))]  # (elevation, one-way length, reflection) per leg kind
    if ground is not None:
        r_g = np.sqrt(d**2 + (h_t + h_r) ** 2)
        psi = np.arctan2(h_t + h_r, d)
        legs.append((-psi, r_g, ground_reflection(ground, radar, psi)))
    legs = [(*leg, (element_gain(radar, th, leg[0] - tilt), transmit_gain(radar, th, leg[0] - tilt))) for leg in legs]
    return [(leg_pair(o, i), o[1] + i[1], i[0]) for o in legs for i in legs]


def twins(paths: Paths, radar: RadarConfig, radar_height: float, tilt: float = 0.0, ground=None) -> Twins:
    """The 3-D twins (module doc) of ``paths`` for a radar at ``radar_height`` [m] tilted up by
    ``tilt`` [rad] over ``ground`` (a GroundSpec, or None: no ground, only the DD path).

    ``paths.length`` is taken as the direct round trip 2R_D the model computed (its horizontal
    length d = √(R_D² − (h_t − h_r)²)), so DD keeps the model's length exactly.
    """
    h_r = float(radar_height)
    if h_r <= 0:
        raise InputError(f"3-D propagation: radar_height must be > 0 m, got {radar_height!r}")
    h_t = heights(paths, h_r)
    if np.any(h_t < 0):
        raise InputError("3-D propagation: scatterer heights must be ≥ 0 m (above the ground)")
    r_d = paths.length / 2
    d = np.sqrt(np.maximum(r_d**2 - (h_t - h_r) ** 2, 0.0))
    base = paths.amp if paths.amp is not None else np.sqrt(paths.power).astype(np.complex128)
    blocks = _blocks(r_d, d, h_t, paths.azimuth, radar, h_r, tilt, ground)  # DD, DG, GD, GG
    n = len(paths)
    factor = np.concatenate([f for f, _, _ in blocks])
    length = np.concatenate([paths.length] + [length for _, length, _ in blocks[1:]])  # DD: the model's own
    elevation = np.concatenate([eps - tilt for _, _, eps in blocks])
    source = np.tile(np.arange(n), len(blocks))
    amp = np.tile(base, len(blocks)) * factor
    lam = sweep_wavelength(radar)
    carrier = np.exp(2j * np.pi * np.mod((length - np.tile(paths.length, len(blocks))) / lam, 1.0))
    total = np.bincount(source, weights=(factor * carrier).real, minlength=n) \
        + 1j * np.bincount(source, weights=(factor * carrier).imag, minlength=n)
    out = dataclasses.replace(
        paths, length=length, azimuth=paths.azimuth[source], power=np.abs(amp) ** 2, amp=amp,
        phase=paths.phase[source], kind=paths.kind[source], order=paths.order[source], pos=paths.pos[source],
        hidden=paths.hidden[source], obj=paths.obj[source], centre=paths.centre[source],
        velocity=None if paths.velocity is None else paths.velocity[source],
        height=None if paths.height is None else paths.height[source])
    return Twins(out, source, elevation, np.abs(total) ** 2)


def power_factor(d, h_t, azimuth, radar: RadarConfig, radar_height: float, tilt: float = 0.0,
                 ground=None) -> np.ndarray:
    """The 3-D terms' power factor G = |Σ twins' amplitude factor · carrier|² (:attr:`Twins.gain`) of a
    scatterer at horizontal distance ``d`` [m], height ``h_t`` [m] and azimuth ``azimuth`` [rad]
    (arrays, broadcast together): the closed form of the module doc without any path — two-ray
    interference over ``ground`` (None: none) and the elevation pattern relative to the 2-D model's
    gains at ε = 0. G = 1 exactly with no ground, no tilt and h_t = h_r."""
    h_r = float(radar_height)
    d, h_t, th = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (d, h_t, azimuth)))
    r_d = np.sqrt(d**2 + (h_t - h_r) ** 2)
    lam = sweep_wavelength(radar)
    total = np.zeros(d.shape, dtype=np.complex128)
    for factor, length, _ in _blocks(r_d, d, h_t, th, radar, h_r, tilt, ground):
        total = total + factor * np.exp(2j * np.pi * np.mod((length - 2 * r_d) / lam, 1.0))
    return np.abs(total) ** 2


def null_ranges(wavelength: float, radar_height: float, target_height: float, n_max: int) -> np.ndarray:
    """Horizontal distances d_n [m], n = 1 … n_max, of the two-ray nulls R_G − R_D = nλ (module
    doc), largest first: the exact solution of √(d² + (h_t + h_r)²) − √(d² + (h_t − h_r)²) = nλ,

        d² = ((nλ)² − 4 h_r h_t)² / (4 (nλ)²) − (h_t − h_r)²,

    for the n where the path difference can reach nλ (it falls from 2 min(h_r, h_t) at d = 0 to 0
    far away); far from the radar d_n ≈ 2 h_r h_t / (nλ).
    """
    n = np.arange(1, int(n_max) + 1, dtype=np.float64)
    dl = n * wavelength
    d2 = (dl**2 - 4 * radar_height * target_height) ** 2 / (4 * dl**2) - (target_height - radar_height) ** 2
    ok = (d2 > 0) & (dl < 2 * min(radar_height, target_height))
    return np.sqrt(d2[ok])
