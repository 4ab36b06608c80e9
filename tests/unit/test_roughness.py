"""Rough-surface specular factor, diffuse lobes (normalisation checked numerically) and σ⁰."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.constants import speed_of_light

from sims.fresnel import fresnel
from sims.materials import get_material
from sims.roughness import (
    backscatter_sigma0,
    bistatic_sigma0,
    diffuse_fraction,
    lobe_normalisation,
    scattering_pattern,
    specular_factor,
    specular_field_factor,
)
from xnlos_core.errors import InputError

DEG = np.pi / 180
LAM10, LAM77 = speed_of_light / 10e9, speed_of_light / 77e9
CONCRETE10 = get_material("concrete").permittivity(10e9)


def _hemisphere(n_t=601, n_p=1201):
    """Directions on the upper hemisphere (z = normal) and trapezoid weights dΩ."""
    t = np.linspace(0, np.pi / 2, n_t)
    p = np.linspace(0, 2 * np.pi, n_p)
    T, P = np.meshgrid(t, p, indexing="ij")
    dirs = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    wt = np.full(n_t, t[1]) * np.sin(t)
    wt[[0, -1]] *= 0.5
    wp = np.full(n_p, p[1])
    wp[[0, -1]] *= 0.5
    return dirs, wt[:, None] * wp[None, :]


def test_smooth_surface_is_a_perfect_mirror():
    assert specular_factor(0.0, 0.3, LAM10) == 1.0
    assert specular_field_factor(0.0, 0.3, LAM10) == 1.0


def test_specular_factor_values():
    # 10 GHz, σ_h = 5 mm, normal incidence: exp(−(4π·5e-3/λ)²) with λ = c/f ≈ 29.98 mm
    expected = np.exp(-((4 * np.pi * 5e-3 / LAM10) ** 2))
    assert specular_factor(5e-3, 0.0, LAM10) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(0.01237, abs=1e-4)
    # field factor is the square root of the power factor
    for s in (1e-7, 5e-5, 5e-3):
        for th in (0.0, 1.0, 1.5):
            fld = specular_field_factor(s, th, LAM77)
            assert fld**2 == pytest.approx(specular_factor(s, th, LAM77), rel=1e-12)
            assert fld == pytest.approx(np.exp(-8 * np.pi**2 * s**2 * np.cos(th) ** 2 / LAM77**2), rel=1e-12)


def test_fig2b_specular_ratio_versus_frequency():
    f = np.geomspace(1e9, 1e12, 200)
    lam = speed_of_light / f
    curves = {s: specular_factor(s, 0.0, lam) for s in (0.1e-6, 50e-6, 5e-3)}
    for c in curves.values():
        assert np.all(np.diff(c) <= 0)  # rougher relative to λ as f grows
    # 0.1 µm: a mirror everywhere on radar bands; 50 µm: mirror at 10 GHz, still > 0.97 at 77 GHz
    assert specular_factor(0.1e-6, 0.0, LAM77) > 0.9999
    assert specular_factor(50e-6, 0.0, LAM10) > 0.999 and specular_factor(50e-6, 0.0, LAM77) > 0.97
    # 5 mm at the grazing incidence of a corner relay wall (75°): mirror-like at 10 GHz, diffuse at 77
    assert specular_factor(5e-3, 75 * DEG, LAM10) > 0.7
    assert specular_factor(5e-3, 75 * DEG, LAM77) < 1e-6
    # ... while at normal incidence 5 mm is already diffuse at 10 GHz (g = 4.39)
    assert specular_factor(5e-3, 0.0, LAM10) < 0.02


def test_power_budget_specular_plus_diffuse_is_fresnel():
    th = np.linspace(0, 1.5, 7)
    g2 = np.abs(fresnel(CONCRETE10, th)[0]) ** 2
    rho = specular_factor(3e-3, th, LAM10)
    F = diffuse_fraction(CONCRETE10, 3e-3, th, LAM10)
    np.testing.assert_allclose(rho * g2 + F, g2, rtol=1e-12)


@pytest.mark.parametrize("alpha", [1, 2, 3, 4, 7, 10])
@pytest.mark.parametrize("theta_deg", [0.0, 30.0, 60.0, 85.0])
def test_directive_lobe_closed_form_matches_quadrature(alpha, theta_deg):
    th = theta_deg * DEG
    dirs, w = _hemisphere(301, 601)
    spec = np.array([-np.sin(th), 0.0, np.cos(th)])  # specular direction for to_tx = (sin, 0, cos)
    numeric = np.sum(((1 + dirs @ spec) / 2) ** alpha * w)
    assert lobe_normalisation(th, alpha) == pytest.approx(numeric, rel=1e-4)


@pytest.mark.parametrize("lobe,alpha", [("lambertian", 4), ("directive", 1), ("directive", 4), ("directive", 10)])
@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 80.0])
def test_diffuse_lobes_integrate_to_the_diffuse_fraction(lobe, alpha, theta_deg):
    th = theta_deg * DEG
    to_tx = np.array([np.sin(th), 0.0, np.cos(th)])
    normal = np.array([0.0, 0.0, 1.0])
    dirs, w = _hemisphere()
    f = scattering_pattern(to_tx, dirs, normal, lobe=lobe, alpha_r=alpha)
    assert np.sum(f * w) == pytest.approx(1.0, abs=2e-4)
    # σ⁰ = 4π I/(S dA) with I = F·S·dA·cosθ_i·f → ∫ σ⁰ dΩ / (4π cosθ_i) = F
    s0 = bistatic_sigma0(CONCRETE10, 5e-3, LAM10, to_tx, dirs, normal, lobe=lobe, alpha_r=alpha)
    F = diffuse_fraction(CONCRETE10, 5e-3, th, LAM10)
    assert np.sum(s0 * w) / (4 * np.pi * np.cos(th)) == pytest.approx(F, rel=2e-4)


def test_monostatic_forms():
    th = np.linspace(0.0, 1.4, 8)
    F = diffuse_fraction(CONCRETE10, 5e-3, th, LAM10)
    lam = backscatter_sigma0(CONCRETE10, 5e-3, th, LAM10)
    np.testing.assert_allclose(lam, 4 * F * np.cos(th) ** 2, rtol=1e-12)
    d4 = backscatter_sigma0(CONCRETE10, 5e-3, th, LAM10, lobe="directive", alpha_r=4)
    np.testing.assert_allclose(d4, 4 * np.pi * F * np.cos(th) ** 9 / lobe_normalisation(th, 4), rtol=1e-12)
    # the bistatic form with receiver = transmitter reproduces both
    to_tx = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], axis=-1)
    for lobe, ref in (("lambertian", lam), ("directive", d4)):
        s0 = bistatic_sigma0(CONCRETE10, 5e-3, LAM10, to_tx, to_tx, [0, 0, 1], lobe=lobe, alpha_r=4)
        np.testing.assert_allclose(s0, ref, rtol=1e-10)


def test_directive_lobe_peaks_in_the_specular_direction():
    th = 50 * DEG
    to_tx = np.array([np.sin(th), 0.0, np.cos(th)])
    phi = np.linspace(-np.pi / 2, np.pi / 2, 181)
    dirs = np.stack([np.sin(phi), np.zeros_like(phi), np.cos(phi)], axis=-1)
    f = scattering_pattern(to_tx, dirs, [0, 0, 1], lobe="directive", alpha_r=6)
    assert phi[np.argmax(f)] == pytest.approx(-th, abs=1 * DEG)


def test_nothing_scatters_behind_the_wall_and_smooth_walls_are_dark():
    s0 = bistatic_sigma0(CONCRETE10, 5e-3, LAM10, [0.3, 0, 1], [0.2, 0, -1], [0, 0, 1])
    assert s0 == 0
    assert backscatter_sigma0(CONCRETE10, 0.0, 0.4, LAM10) == 0


def test_gamma_override_and_errors():
    F = diffuse_fraction(None, 5e-3, 0.2, LAM10, gamma=-0.5)
    assert F == pytest.approx(0.25 * (1 - specular_factor(5e-3, 0.2, LAM10)))
    with pytest.raises(InputError, match="alpha_r"):
        backscatter_sigma0(CONCRETE10, 5e-3, 0.2, LAM10, lobe="directive", alpha_r=2.5)
    with pytest.raises(InputError, match="lobe"):
        backscatter_sigma0(CONCRETE10, 5e-3, 0.2, LAM10, lobe="phong")
    with pytest.raises(InputError, match="sigma_h_m"):
        specular_factor(-1e-3, 0.2, LAM10)
    with pytest.raises(InputError, match="wavelength_m"):
        specular_factor(1e-3, 0.2, 0.0)
    with pytest.raises(InputError, match="normal"):
        scattering_pattern([0, 0, 1], [0, 0, 1], [0, 0, 0])
    with pytest.raises(InputError, match="gamma"):
        diffuse_fraction(None, 1e-3, 0.2, LAM10, gamma=1.5)


@settings(max_examples=150, deadline=None)
@given(sigma_h=st.floats(0.0, 0.1), th=st.floats(0.0, 89.9), f=st.floats(1e9, 100e9),
       ls=st.floats(-6.0, 7.0), alpha=st.integers(1, 20), f32=st.booleans(),
       lobe=st.sampled_from(["lambertian", "directive"]))
def test_roughness_extremes(sigma_h, th, f, ls, alpha, f32, lobe):
    eta = 5.0 - 1j * 10.0**ls * 17.98 / (f / 1e9)
    lam, th = speed_of_light / f, th * DEG
    if f32:
        sigma_h, th, lam, eta = np.float32(sigma_h), np.float32(th), np.float32(lam), np.complex64(eta)
    rho = specular_factor(sigma_h, th, lam)
    assert 0.0 <= rho <= 1.0 and rho.dtype == np.float64
    F = diffuse_fraction(eta, sigma_h, th, lam)
    assert 0.0 <= F <= abs(fresnel(eta, th)[0]) ** 2 + 1e-15
    s0 = backscatter_sigma0(eta, sigma_h, th, lam, lobe=lobe, alpha_r=alpha)
    assert np.isfinite(s0) and s0 >= 0
    bound = 4 * F * np.cos(th) if lobe == "lambertian" else 4 * np.pi * F * np.cos(th) / lobe_normalisation(th, alpha)
    assert s0 <= bound * (1 + 1e-12) + 1e-300
