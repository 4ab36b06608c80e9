"""Rough-wall reflection: coherent specular factor plus a diffuse scattering lobe.

Power budget of a wall patch lit at incidence θ_i (the Kirchhoff / Beckmann picture with
Gaussian height statistics, rms height σ_h):

    reflected power fraction |Γ(θ_i)|²  =  ρ_s·|Γ|²  (coherent, specular, mirror paths)
                                         +  F        (incoherent, diffuse, F = (1 − ρ_s)·|Γ|²)

    ρ_s = exp(−g),   g = (4π σ_h cosθ_i / λ)²           [Rayleigh roughness parameter]

ρ_s is a POWER factor. The FIELD (amplitude) factor is its square root,
    √ρ_s = exp(−g/2) = exp(−8π² σ_h² cos²θ_i / λ²);
a ray tracer multiplying complex path amplitudes (the mirror reflectivity α) must use the field
factor (:func:`specular_field_factor`); radar-equation / power bookkeeping uses ρ_s.

The diffuse remainder F leaves the patch with a normalised angular density f(ŝ) [1/sr],
∫_hemisphere f dΩ = 1, so the scattered radiant intensity of a patch of area dA lit by the power
density S_inc is I(ŝ) = F·S_inc·dA·cosθ_i·f(ŝ) [W/sr]. Two lobes (Degli-Esposti et al., IEEE
Trans. Antennas Propag. 55(1), 2007, "Measurement and modelling of scattering from buildings"):

* ``"lambertian"``: f = cosθ_s / π.
* ``"directive"``: f = ((1 + cosψ_R)/2)^α_R / N(θ_i, α_R), ψ_R the angle between ŝ and the
  specular direction, α_R a positive integer (lobe width; 1 broad … 10 narrow). The hemisphere
  integral N is closed-form (binomial expansion; for odd powers j the Degli-Esposti series)
      N = 2^{−α} Σ_j C(α, j)·I_j,  I_j = 2π/(j+1) (j even),
      I_j = 2π/(j+1)·cosθ_i·Σ_{w=0}^{(j−1)/2} C(2w, w)·sin^{2w}θ_i / 4^w (j odd).

Radar cross section per unit area (dimensionless, m²/m²): σ⁰ = 4π·I/(S_inc·dA) =
4π·F·cosθ_i·f(ŝ). Lambertian bistatic σ⁰ = 4F·cosθ_i·cosθ_s, monostatic σ⁰ = 4F·cos²θ;
directive monostatic (ψ_R = 2θ, ((1 + cos2θ)/2)^α = cos^{2α}θ): σ⁰ = 4π·F·cosθ·cos^{2α}θ / N.
The directive σ⁰ is not reciprocal (N depends on θ_i) — a property of the model.
"""
from __future__ import annotations

import math

import numpy as np

from sims.fresnel import as_eps, as_theta, fresnel
from xnlos_core.errors import InputError

LOBES = ("lambertian", "directive")


def _nonneg(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if not np.isfinite(a).all() or (a < 0).any():
        raise InputError(f"{name} must be finite and ≥ 0 (metres), got {x!r}")
    return a


def _positive(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if not np.isfinite(a).all() or (a <= 0).any():
        raise InputError(f"{name} must be finite and > 0 (metres), got {x!r}")
    return a


def roughness_parameter(sigma_h_m, theta_i, wavelength_m) -> np.ndarray:
    """g = (4π σ_h cosθ_i / λ)² [-] (σ_h rms height [m], θ_i [rad], λ [m]); broadcast float64."""
    s = _nonneg(sigma_h_m, "sigma_h_m")
    lam = _positive(wavelength_m, "wavelength_m")
    th = as_theta(theta_i)
    return (4.0 * np.pi * s * np.cos(th) / lam) ** 2


def specular_factor(sigma_h_m, theta_i, wavelength_m) -> np.ndarray:
    """Coherent specular POWER factor ρ_s = exp(−(4π σ_h cosθ_i / λ)²) ∈ (0, 1].

    sigma_h_m: rms surface height [m]; theta_i: incidence angle from the normal [rad];
    wavelength_m: free-space wavelength [m]. Broadcast, float64. Multiply POWERS (|Γ|², the
    radar equation) by ρ_s; multiply complex FIELD amplitudes (mirror reflectivity α) by
    :func:`specular_field_factor` = √ρ_s instead. ρ_s(σ_h = 0) = 1. For Fig. 2(b) of the paper
    evaluate ρ_s over λ = c/f for σ_h = 0.1 µm, 50 µm and 5 mm.
    """
    return np.exp(-roughness_parameter(sigma_h_m, theta_i, wavelength_m))


def specular_field_factor(sigma_h_m, theta_i, wavelength_m) -> np.ndarray:
    """Coherent specular FIELD (amplitude) factor √ρ_s = exp(−8π² σ_h² cos²θ_i / λ²)."""
    return np.exp(-0.5 * roughness_parameter(sigma_h_m, theta_i, wavelength_m))


def diffuse_fraction(eps_r, sigma_h_m, theta_i, wavelength_m, *, pol: str = "s", gamma=None) -> np.ndarray:
    """F = (1 − ρ_s)·|Γ(θ_i)|²: fraction of the incident power scattered diffusely [-].

    Γ is the half-space Fresnel coefficient of ``eps_r`` (:func:`sims.fresnel.fresnel`), or the
    amplitude reflection coefficient ``gamma`` when given (e.g. a slab value from
    :func:`sims.fdtd.wall_reflection`; then eps_r is ignored and may be None).
    """
    if gamma is None:
        g2 = np.abs(fresnel(as_eps(eps_r), theta_i, pol)[0]) ** 2
    else:
        g2 = np.abs(np.asarray(gamma, dtype=np.complex128)) ** 2
        if not np.all(np.isfinite(g2)) or np.any(g2 > 1 + 1e-9):
            raise InputError("gamma must be finite amplitude reflection coefficients with |gamma| ≤ 1")
    return (1.0 - specular_factor(sigma_h_m, theta_i, wavelength_m)) * g2


def _alpha(alpha_r) -> int:
    try:
        ok = not isinstance(alpha_r, bool) and float(alpha_r).is_integer() and 1 <= alpha_r <= 100
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"alpha_r must be an integer in [1, 100] (directive lobe width), got {alpha_r!r}")
    return int(alpha_r)


def lobe_normalisation(theta_i, alpha_r: int) -> np.ndarray:
    """N(θ_i, α_R) = ∫_hemisphere ((1 + cosψ_R)/2)^α_R dΩ [sr], closed form (see module doc).

    theta_i [rad] any shape → float64 of that shape; α_R integer in [1, 100]. N(0, 1) = 3π/2.
    """
    al = _alpha(alpha_r)
    th = as_theta(theta_i)
    c, s2 = np.cos(th), np.sin(th) ** 2
    total = np.zeros_like(th)
    odd_series = np.zeros_like(th)  # Σ_{w ≤ (j−1)/2} C(2w, w) s^{2w}/4^w, grown as j increases
    w_next = 0
    for j in range(al + 1):
        if j % 2 == 0:
            ij = 2.0 * np.pi / (j + 1)
        else:
            while w_next <= (j - 1) // 2:
                odd_series = odd_series + math.comb(2 * w_next, w_next) * s2**w_next / 4.0**w_next
                w_next += 1
            ij = 2.0 * np.pi / (j + 1) * c * odd_series
        total = total + math.comb(al, j) * ij
    return total / 2.0**al


def _unit(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise InputError(f"{name} must have shape (..., 3), got {a.shape}")
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if not np.all(np.isfinite(a)) or np.any(n == 0):
        raise InputError(f"{name} must be finite non-zero 3-vectors")
    return a / n


def scattering_pattern(to_tx, to_rx, normal, *, lobe: str = "lambertian", alpha_r: int = 4) -> np.ndarray:
    """Normalised diffuse lobe f(ŝ) [1/sr], ∫_hemisphere f dΩ = 1 for every incidence.

    to_tx: (..., 3) direction from the wall patch towards the transmitter; to_rx: (..., 3) towards
    the receiver; normal: (..., 3) wall normal on the lit side (all normalised here, broadcast).
    Zero when either end lies behind the wall. lobe: 'lambertian' or 'directive' (α_R = alpha_r).
    """
    ui, us, n = _unit(to_tx, "to_tx"), _unit(to_rx, "to_rx"), _unit(normal, "normal")
    ci = np.sum(ui * n, axis=-1)
    cs = np.sum(us * n, axis=-1)
    lit = (ci > 0) & (cs > 0)
    if lobe == "lambertian":
        f = cs / np.pi
    elif lobe == "directive":
        al = _alpha(alpha_r)
        spec = 2.0 * ci[..., None] * n - ui  # specular direction of the ray arriving from the TX
        cpsi = np.clip(np.sum(us * spec, axis=-1), -1.0, 1.0)
        f = ((1.0 + cpsi) / 2.0) ** al / lobe_normalisation(np.arccos(np.clip(ci, 0.0, 1.0)), al)
    else:
        raise InputError(f"lobe must be one of {LOBES}, got {lobe!r}")
    return np.where(lit, f, 0.0)


def bistatic_sigma0(eps_r, sigma_h_m, wavelength_m, to_tx, to_rx, normal, *, lobe: str = "lambertian",
                    alpha_r: int = 4, pol: str = "s", gamma=None) -> np.ndarray:
    """Diffuse bistatic σ⁰ [m²/m²] of a rough wall patch: σ⁰ = 4π·F(θ_i)·cosθ_i·f(ŝ).

    Derivation: the patch intercepts P = S_inc·dA·cosθ_i, scatters F·P diffusely with angular
    density f (:func:`scattering_pattern`), so I = F·S_inc·dA·cosθ_i·f and
    σ⁰ = 4π·I/(S_inc·dA). F = (1 − ρ_s(θ_i))·|Γ(θ_i)|² (:func:`diffuse_fraction`, θ_i from
    to_tx·normal). Vectors as in :func:`scattering_pattern`; eps_r, sigma_h_m [m], wavelength_m [m]
    broadcast against their leading shape.
    """
    ui, n = _unit(to_tx, "to_tx"), _unit(normal, "normal")
    ci = np.clip(np.sum(ui * n, axis=-1), 0.0, 1.0)
    theta = np.arccos(ci)
    F = diffuse_fraction(eps_r, sigma_h_m, theta, wavelength_m, pol=pol, gamma=gamma)
    return 4.0 * np.pi * F * ci * scattering_pattern(to_tx, to_rx, normal, lobe=lobe, alpha_r=alpha_r)


def backscatter_sigma0(eps_r, sigma_h_m, theta_i, wavelength_m, *, lobe: str = "lambertian",
                       alpha_r: int = 4, pol: str = "s", gamma=None) -> np.ndarray:
    """Monostatic (radar line-of-sight) diffuse σ⁰ [m²/m²] of a rough wall at incidence θ_i [rad].

    Lambertian: σ⁰ = 4·F·cos²θ_i. Directive: σ⁰ = 4π·F·cosθ_i·cos^{2α}θ_i / N(θ_i, α).
    F = (1 − ρ_s)|Γ|² as in :func:`diffuse_fraction`; broadcast, float64. A smooth wall
    (σ_h = 0) has σ⁰ = 0: it returns nothing to a monostatic radar except at normal incidence,
    which the specular (mirror) path models.
    """
    th = as_theta(theta_i)
    c = np.cos(th)
    F = diffuse_fraction(eps_r, sigma_h_m, th, wavelength_m, pol=pol, gamma=gamma)
    if lobe == "lambertian":
        return 4.0 * F * c * c
    if lobe == "directive":
        al = _alpha(alpha_r)
        return 4.0 * np.pi * F * c * c ** (2 * al) / lobe_normalisation(th, al)
    raise InputError(f"lobe must be one of {LOBES}, got {lobe!r}")
