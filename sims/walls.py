"""Wall electromagnetics for the forward models: specular α, slab transmission and diffuse σ⁰.

One place that turns a :class:`xnlos_core.scene.WallSpec` and the radar into the three numbers
the image method needs at an incidence angle θ_i [rad] (from the wall normal). Materials are
evaluated at the radar carrier through :func:`sims.material_fallback.material_at` (P.2040 where it
covers the carrier, a documented fallback with a warning where not, e.g. brick at 77 GHz):

* α(θ_i): specular amplitude reflectivity per bounce (Eq. 2), the coherent part only:
  Γ_slab(θ_i) · √ρ_s(θ_i) with ρ_s = exp(−(4πσ_h cos θ_i/λ)²) the specular POWER factor, so its
  square root is the FIELD factor (:mod:`sims.roughness`). Constant ``wall.alpha`` without a
  material.
* T(θ_i): one-way slab amplitude transmission (0 for a half-space or a wall without material).
* σ⁰(θ_i): monostatic diffuse backscatter per unit area [m²/m²] from the lobe model for the
  power the roughness takes out of the specular direction; ``wall.sigma0_db``·cos²θ_i without a
  material.

Polarisation: walls are vertical, so the radar's V polarisation is TE (s) and H is TM (p).
"""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig

from . import fdtd, fresnel, roughness
from .material_fallback import material_at
from .materials import get_material


def check_materials(scene) -> None:
    """InputError naming the wall whose ``material`` is not a Table 3 name (with a did-you-mean);
    the forward models' ``check`` calls it, so ``xnlos check`` refuses the scene."""
    for i, wall in enumerate(scene.walls):
        if wall.material is None:
            continue
        try:
            get_material(wall.material)
        except InputError as exc:
            raise InputError(f"scene {scene.name!r}, walls[{i}] ({wall.name!r}): {exc}") from None


def _pol(radar: RadarConfig) -> str:
    return "s" if radar.polarization == "V" else "p"


FDTD_ANGLES = np.radians(np.arange(0.0, 86.0, 5.0))  # FDTD runs on this grid (TE mapping valid ≤ 85°)


def specular_alpha(wall, radar: RadarConfig, theta_i, method: str = "analytic") -> np.ndarray:
    """α(θ_i) (complex amplitude, shape of ``theta_i``) of one specular bounce on ``wall``.

    method "fdtd": the cached FDTD solver on the 5° grid ``FDTD_ANGLES`` (one run per grid angle
    and carrier, cached on disk), interpolated linearly in the real and imaginary parts; angles
    beyond 85° take the analytic value (grazing: |Γ| → 1 there anyway).
    """
    th = np.abs(np.asarray(theta_i, dtype=np.float64))
    if wall.material is None:
        return np.full(th.shape, wall.alpha, dtype=np.complex128)
    mat, f, pol = material_at(wall.material, radar.carrier_frequency), radar.carrier_frequency, _pol(radar)
    gamma = fdtd.wall_reflection(mat, wall.thickness, th, f, method="analytic", pol=pol)
    if method == "fdtd":
        grid = fdtd.wall_reflection(mat, wall.thickness, FDTD_ANGLES, f, method="fdtd", pol=pol)
        inside = th <= FDTD_ANGLES[-1]
        gamma = np.where(inside, np.interp(th, FDTD_ANGLES, grid.real) + 1j * np.interp(th, FDTD_ANGLES, grid.imag),
                         gamma)
    rho = roughness.specular_factor(wall.roughness, th, radar.wavelength)
    return np.asarray(gamma, dtype=np.complex128) * np.sqrt(rho)


def transmission(wall, radar: RadarConfig, theta_i) -> np.ndarray:
    """One-way amplitude transmission T(θ_i) through ``wall`` (complex; 0 when opaque)."""
    th = np.abs(np.asarray(theta_i, dtype=np.float64))
    if wall.material is None or wall.thickness is None:
        return np.zeros(th.shape, dtype=np.complex128)
    eps = material_at(wall.material, radar.carrier_frequency).permittivity(radar.carrier_frequency)
    _, t = fresnel.slab(eps, wall.thickness, th, radar.carrier_frequency, _pol(radar))
    return np.asarray(t, dtype=np.complex128)


def backscatter_sigma0(wall, radar: RadarConfig, theta_i) -> np.ndarray:
    """Monostatic diffuse σ⁰(θ_i) [m²/m²] (shape of ``theta_i``), ≥ 0."""
    th = np.abs(np.asarray(theta_i, dtype=np.float64))
    if wall.material is None:
        return 10 ** (wall.sigma0_db / 10) * np.cos(th) ** 2
    eps = material_at(wall.material, radar.carrier_frequency).permittivity(radar.carrier_frequency)
    gamma = None  # half-space Fresnel inside the lobe model
    if wall.thickness is not None:
        gamma, _ = fresnel.slab(eps, wall.thickness, th, radar.carrier_frequency, _pol(radar))
    return np.asarray(roughness.backscatter_sigma0(eps, wall.roughness, th, radar.wavelength, lobe=wall.lobe,
                                                   alpha_r=int(wall.lobe_exponent), pol=_pol(radar),
                                                   gamma=gamma), dtype=np.float64)


def bistatic_sigma0(wall, radar: RadarConfig, to_tx, to_rx, normal) -> np.ndarray:
    """Diffuse bistatic σ⁰ [m²/m²] of a patch of ``wall``: light arriving from ``to_tx`` and leaving
    towards ``to_rx`` ((..., 3) directions from the patch; ``normal`` (..., 3) on the lit side).

    σ⁰ = 4π·F(θ_i)·cosθ_i·f(ŝ) with F = (1 − ρ_s)|Γ|² (:func:`sims.roughness.bistatic_sigma0`), Γ the
    slab or half-space coefficient at θ_i; 0 for walls given by constants (no lobe model) and for smooth
    walls (σ_h = 0: all reflected power stays in the mirror path).
    """
    to_tx = np.asarray(to_tx, dtype=np.float64)
    shape = np.broadcast_shapes(to_tx.shape, np.shape(to_rx), np.shape(normal))[:-1]
    if wall.material is None or wall.roughness == 0:
        return np.zeros(shape)
    eps = material_at(wall.material, radar.carrier_frequency).permittivity(radar.carrier_frequency)
    gamma = None
    if wall.thickness is not None:
        ui = to_tx / np.linalg.norm(to_tx, axis=-1, keepdims=True)
        nn = np.asarray(normal, dtype=np.float64)
        th = np.arccos(np.clip(np.sum(ui * nn / np.linalg.norm(nn, axis=-1, keepdims=True), axis=-1), 0.0, 1.0))
        gamma, _ = fresnel.slab(eps, wall.thickness, th, radar.carrier_frequency, _pol(radar))
    return np.asarray(roughness.bistatic_sigma0(eps, wall.roughness, radar.wavelength, to_tx, to_rx, normal,
                                                lobe=wall.lobe, alpha_r=int(wall.lobe_exponent), pol=_pol(radar),
                                                gamma=gamma), dtype=np.float64)
