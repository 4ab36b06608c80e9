"""Diffuse NLOS paths: radar → rough relay wall (diffuse) → hidden object → wall (diffuse) → radar.

The mirror (mNLOS) path of a rough relay wall keeps only the coherent part of the reflection,
ρ_s·|Γ|² in power with ρ_s = exp(−(4πσ_h cosθ/λ)²) (:mod:`sims.roughness`); the remainder
F = (1 − ρ_s)|Γ|² leaves the wall in the diffuse lobe. At 77 GHz a facade with σ_h ≈ 1 mm is
almost entirely diffuse (ρ_s(0) ≈ 3·10⁻⁵), at 10 GHz almost a mirror (ρ_s(0) ≈ 0.84) (paper
Sec. 1, Fig. 2b). The diffuse power still reaches hidden objects by the three-bounce path that
optical (SPAD) NLOS imaging uses; this module gives its power. Wall patches a (out) and b (back)
are cells of length Δs and the wall's height h (area dA = Δs·h, as the LOS wall cells), the object
a scattering centre of RCS σ_o:

    P = P_t·G_tx(θ_a)·G_e(θ_a)·G_e(θ_b)·λ²·σ_o·(σ⁰_a dA)(σ⁰_b dA) / ((4π)⁵·r_a²·d_ao²·d_ob²·r_b²·L_sys)

(radar equation with each diffuse patch as a bistatic scatterer σ⁰·dA: σ⁰_a from the radar towards
the object, σ⁰_b from the object towards the radar, :func:`sims.walls.bistatic_sigma0`). Round trip
r_a + d_ao + d_ob + r_b, arrival from θ_b. Every pair (a, b) is a path (a ≠ b included: the echo
leaves the object by any patch), with phase φ_a + φ_o + φ_b from the per-cell and per-centre
random phases.

Energy: σ⁰ integrates to F over the hemisphere (∫ σ⁰/(4π cosθ_i) dΩ = F), so specular plus
diffuse never exceed the incident power: ρ_s|Γ|² + F = |Γ|² ≤ 1 (tests/unit/test_diffuse_nlos.py).

"auto" switches the path on when a relay wall with a material is mostly diffuse at the carrier,
ρ_s(θ = 0) < 1/2, i.e. σ_h > √(ln 2)·λ/(4π) ≈ 0.066 λ (2.0 mm at 10 GHz, 0.26 mm at 77 GHz):
ρ_s is smallest at normal incidence, so below that roughness the mirror path keeps most of the
power at every angle and stays the dominant NLOS echo (the diffuse path spreads its power over a
hemisphere twice and is far weaker).
"""
from __future__ import annotations

import math

import numpy as np

from xnlos_core.antenna import element_gain, transmit_gain
from xnlos_core.radar import RadarConfig

from . import roughness

MOSTLY_DIFFUSE = 0.5  # ρ_s(0) below this: the wall is "mostly diffuse" ("auto" rule, module doc)


def mostly_diffuse(wall, radar: RadarConfig) -> bool:
    """True for a relay wall with a material whose normal-incidence specular factor ρ_s(0) < 1/2."""
    if not wall.relay or wall.material is None or wall.roughness == 0:
        return False
    return float(roughness.specular_factor(wall.roughness, 0.0, radar.wavelength)) < MOSTLY_DIFFUSE


def decide(switch: str, scene, radar: RadarConfig) -> str:
    """"on" or "off: why" for the diffuse NLOS path given switch "auto" / "on" / "off" (module doc)."""
    if switch == "off":
        return "off: switched off"
    if not scene.objects:
        return "off: no object"
    if switch == "on" or any(mostly_diffuse(w, radar) for w in scene.walls):
        return "on"
    return (f"off: no mostly diffuse relay wall (ρ_s(0) < {MOSTLY_DIFFUSE}, σ_h > "
            f"{math.sqrt(math.log(2)) * radar.wavelength / (4 * math.pi) * 1e3:.2g} mm at this carrier)")


def cells(spec, cell_length: float) -> tuple[np.ndarray, float]:
    """Cell centres (K, 2) [m] of ``spec`` cut into K ≈ length/cell_length cells, and the cell length [m]."""
    start, end = np.asarray(spec.start, float), np.asarray(spec.end, float)
    length = math.dist(spec.start, spec.end)
    k = max(1, int(round(length / cell_length)))
    s = (np.arange(k) + 0.5) / k
    return start + s[:, None] * (end - start), length / k


def three_bounce_power(radar: RadarConfig, r_a, az_a, r_b, az_b, d_ao, d_ob, sa_dA, sb_dA, rcs) -> np.ndarray:
    """Received power [W] of the three-bounce path (module doc), broadcast over all arrays.

    r_a, r_b: radar–patch distances [m]; az_a, az_b: their azimuths [rad]; d_ao, d_ob: patch–object
    distances [m]; sa_dA, sb_dA: the patches' bistatic σ⁰·dA [m²]; rcs: the object's σ_o [m²].
    """
    g = transmit_gain(radar, az_a) * element_gain(radar, az_a) * element_gain(radar, az_b)
    loss = 10.0 ** (radar.system_loss_db / 10.0)
    num = radar.transmit_power * g * radar.wavelength**2 * np.asarray(rcs) * sa_dA * sb_dA
    return num / ((4 * np.pi) ** 5 * r_a**2 * d_ao**2 * d_ob**2 * r_b**2 * loss)
