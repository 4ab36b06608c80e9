"""Fresnel half-space and slab coefficients: closed forms, extremes and energy (hypothesis)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.constants import epsilon_0, speed_of_light

from sims.fresnel import brewster_angle, fresnel, slab
from xnlos_core.errors import InputError

DEG = np.pi / 180


def _eta(eps1, sigma, f):
    return eps1 - 1j * sigma / (2 * np.pi * f * epsilon_0)


def test_normal_incidence_closed_form_and_sign_convention():
    for eps in (4.0, 5.24 - 0.5j, 80 - 30j):
        rs, ts = fresnel(eps, 0.0, "s")
        rp, tp = fresnel(eps, 0.0, "TM")
        n = np.sqrt(eps)
        assert rs == pytest.approx((1 - n) / (1 + n), abs=1e-14)
        assert rp == pytest.approx(-rs, abs=1e-14)  # P.2040 Eq. 37b convention
        assert ts == pytest.approx(1 + rs, abs=1e-14)
        assert tp == pytest.approx(2 / (1 + n), abs=1e-14)


@pytest.mark.parametrize("eps", [2.0, 4.0, 6.31, 80.0])
def test_brewster_zero_for_lossless(eps):
    tb = brewster_angle(eps)
    assert tb == pytest.approx(np.arctan(np.sqrt(eps)))
    assert abs(fresnel(eps, tb, "p")[0]) < 1e-12
    assert abs(fresnel(eps, tb, "s")[0]) > 0.1
    # a minimum: slightly off the Brewster angle TM reflection is non-zero
    assert abs(fresnel(eps, tb + 0.05, "p")[0]) > 1e-3


def test_brewster_rejects_lossy():
    with pytest.raises(InputError, match="lossless"):
        brewster_angle(4.0 - 0.1j)
    with pytest.raises(InputError):
        brewster_angle(-1.0)


def test_grazing_incidence_is_total_reflection():
    for eps in (4.0, 5.24 - 0.5j, 1 - 1.8e7j):
        for pol in ("s", "p"):
            r90, _ = fresnel(eps, np.pi / 2, pol)
            assert abs(r90) == pytest.approx(1.0, abs=1e-9)
            if not (pol == "p" and abs(eps) > 1e3):  # metal TM: pseudo-Brewster at ≈ 89.99°
                r, _ = fresnel(eps, 89.9 * DEG, pol)
                assert 0.95 < abs(r) <= 1.0
    # metal TM dips near grazing (pseudo-Brewster angle at arctan|√η|) but stays finite and ≤ 1
    th = np.linspace(89.9, 90.0, 101) * DEG
    r, _ = fresnel(1 - 1.8e7j, th, "p")
    assert np.all(np.isfinite(r)) and np.all(np.abs(r) <= 1) and np.abs(r).min() < 0.5


def test_vacuum_has_no_interface():
    r, t = fresnel(1.0, np.array([0.0, 0.7, np.pi / 2]), "s")
    np.testing.assert_allclose(r, 0.0, atol=1e-15)
    np.testing.assert_allclose(t, 1.0, atol=1e-15)


@pytest.mark.parametrize("eps", [4.0, 6.31])
@pytest.mark.parametrize("f", [10e9, 77e9])
def test_half_wave_slab_is_transparent(eps, f):
    lam = speed_of_light / f
    d = lam / (2 * np.sqrt(eps))
    for pol in ("s", "p"):
        R, T = slab(eps, d, 0.0, f, pol)
        assert abs(R) < 1e-12
        assert abs(R) ** 2 + abs(T) ** 2 == pytest.approx(1.0, abs=1e-12)
    # oblique: vanishes where the normal phase thickness q = π
    th = 40 * DEG
    d_ob = lam / (2 * np.sqrt(eps - np.sin(th) ** 2))
    assert abs(slab(eps, d_ob, th, f, "s")[0]) < 1e-12
    # quarter-wave is a maximum, R = 2r/(1 + r²)
    r = (1 - np.sqrt(eps)) / (1 + np.sqrt(eps))
    assert abs(slab(eps, d / 2, 0.0, f)[0]) == pytest.approx(abs(2 * r / (1 + r * r)), rel=1e-12)


def test_slab_phase_reference():
    f, d, th = 10e9, 0.07, 0.4
    R, T = slab(1.0, d, th, f)
    k0 = 2 * np.pi * f / speed_of_light
    assert abs(R) < 1e-15
    assert T == pytest.approx(np.exp(-1j * k0 * d * np.cos(th)), abs=1e-12)


def test_thick_lossy_slab_tends_to_half_space_without_overflow():
    eta = _eta(5.24, 0.28, 10e9)
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        R, T = slab(eta, np.array([3.0, 1e3, np.inf]), 0.3, 10e9)
        r, _ = fresnel(eta, 0.3)
        np.testing.assert_allclose(R, r, atol=1e-12)
        np.testing.assert_allclose(T, 0.0, atol=1e-12)
        Rm, Tm = slab(_eta(1.0, 1e7, 1e9), np.array([1e-6, 1e-3, 1.0, 100.0]), 89.9 * DEG, 1e9, "p")
    assert np.all(np.isfinite(Rm)) and np.all(np.abs(Rm) <= 1)
    assert abs(Tm[-1]) == 0.0


def test_zero_thickness_is_no_wall():
    R, T = slab(5.0 - 1j, 0.0, 0.3, 10e9)
    assert R == 0 and T == 1


def test_input_errors():
    with pytest.raises(InputError, match="Im"):
        fresnel(4.0 + 0.5j, 0.0)  # e^{-iωt} convention
    with pytest.raises(InputError, match="theta_i"):
        fresnel(4.0, 2.0)
    with pytest.raises(InputError, match="pol"):
        fresnel(4.0, 0.0, "x")
    with pytest.raises(InputError, match="thickness_m"):
        slab(4.0, -1.0, 0.0, 10e9)
    with pytest.raises(InputError, match="f_hz"):
        slab(4.0, 0.1, 0.0, 0.0)
    with pytest.raises(InputError, match="eps_r"):
        fresnel(np.nan, 0.0)


def test_vectorised_broadcast():
    eps = np.array([4.0, 5.24 - 0.5j])[:, None]
    th = np.linspace(0, 1.5, 7)[None, :]
    r, t = fresnel(eps, th, "p")
    assert r.shape == t.shape == (2, 7)
    R, T = slab(eps, 0.1, th, 10e9)
    assert R.shape == (2, 7)


# -- property tests: extremes -------------------------------------------------------------------
theta_st = st.floats(0.0, 89.9, allow_nan=False).map(lambda d: d * DEG)
eps1_st = st.floats(1.0, 100.0)
log_sigma_st = st.floats(-6.0, 7.0)  # σ from 1e-6 to 1e7 S/m (metal)
f_st = st.floats(1e9, 100e9)
pol_st = st.sampled_from(["s", "p"])


@settings(max_examples=200, deadline=None)
@given(eps1=eps1_st, ls=log_sigma_st, th=theta_st, f=f_st, pol=pol_st, f32=st.booleans())
def test_fresnel_extremes_finite_and_bounded(eps1, ls, th, f, pol, f32):
    eta = _eta(eps1, 10.0**ls, f)
    if f32:
        eta, th = np.complex64(eta), np.float32(th)
    r, t = fresnel(eta, th, pol)
    assert r.dtype == np.complex128
    assert np.isfinite(r) and np.isfinite(t)
    assert abs(r) <= 1.0 + 1e-12


@settings(max_examples=200, deadline=None)
@given(eps1=eps1_st, ls=log_sigma_st, th=theta_st, f=f_st, pol=pol_st,
       d=st.floats(0.0, 1.0), f32=st.booleans())
def test_slab_energy_bound(eps1, ls, th, f, pol, d, f32):
    eta = _eta(eps1, 10.0**ls, f)
    args = (np.complex64(eta), np.float32(d), np.float32(th), np.float32(f)) if f32 else (eta, d, th, f)
    R, T = slab(*args, pol=pol)
    assert np.isfinite(R) and np.isfinite(T)
    assert abs(R) ** 2 + abs(T) ** 2 <= 1.0 + 1e-9


@settings(max_examples=200, deadline=None)
@given(eps1=eps1_st, th=theta_st, f=f_st, pol=pol_st, d=st.floats(0.0, 1.0), f32=st.booleans())
def test_lossless_slab_conserves_energy(eps1, th, f, pol, d, f32):
    args = (np.float32(eps1), np.float32(d), np.float32(th), np.float32(f)) if f32 else (eps1, d, th, f)
    R, T = slab(*args, pol=pol)
    assert abs(R) ** 2 + abs(T) ** 2 == pytest.approx(1.0, abs=1e-9)


@settings(max_examples=50, deadline=None)
@given(eps1=eps1_st, ls=log_sigma_st, th=theta_st, f=f_st)
def test_float32_inputs_match_float64_of_the_same_values(eps1, ls, th, f):
    eta32, th32 = np.complex64(_eta(eps1, 10.0**ls, f)), np.float32(th)
    r32, _ = fresnel(eta32, th32)
    r64, _ = fresnel(complex(eta32), float(th32))
    assert r32 == r64
