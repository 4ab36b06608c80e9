"""ITU-R P.2040-3 Table 3 materials: coefficients, ranges, complex permittivity, closed forms."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.constants import epsilon_0

from sims.fresnel import fresnel
from sims.materials import MATERIALS, Material, get_material
from xnlos_core.errors import InputError

# name: (a, b, c, d, f_min GHz, f_max GHz) as printed in P.2040-3 Table 3
TABLE3 = {
    "concrete": (5.24, 0.0, 0.0462, 0.7822, 1, 100),
    "brick": (3.91, 0.0, 0.0238, 0.16, 1, 40),
    "plasterboard": (2.73, 0.0, 0.0085, 0.9395, 1, 100),
    "wood": (1.99, 0.0, 0.0047, 1.0718, 0.001, 100),
    "glass": (6.31, 0.0, 0.0036, 1.3394, 0.1, 100),
    "metal": (1.0, 0.0, 1e7, 0.0, 1, 100),
}


@pytest.mark.parametrize("name", sorted(TABLE3))
def test_table3_entries(name):
    m = MATERIALS[name]
    a, b, c, d, lo, hi = TABLE3[name]
    assert (m.a, m.b, m.c, m.d) == (a, b, c, d)
    assert m.f_min_hz == pytest.approx(lo * 1e9) and m.f_max_hz == pytest.approx(hi * 1e9)


def test_permittivity_is_p2040_eta():
    m = get_material("concrete")
    f = np.array([1e9, 10e9, 77e9])
    eta = m.permittivity(f)
    f_ghz = f / 1e9
    sigma = 0.0462 * f_ghz**0.7822
    np.testing.assert_allclose(eta.real, 5.24)
    np.testing.assert_allclose(eta.imag, -17.98 * sigma / f_ghz, rtol=1e-3)  # 1/(2π·1e9·ε0) ≈ 17.98
    np.testing.assert_allclose(eta.imag, -sigma / (2 * np.pi * f * epsilon_0), rtol=1e-12)
    assert eta.shape == (3,) and eta.dtype == np.complex128


def test_normal_incidence_concrete_and_glass_at_10ghz():
    for name, expected in (("concrete", 0.39), ("glass", 0.43)):
        r, _ = fresnel(get_material(name).permittivity(10e9), 0.0)
        assert abs(r) == pytest.approx(expected, abs=0.01)


def test_metal_is_a_mirror():
    for f in (1e9, 10e9, 77e9):
        for pol in ("s", "p"):
            r, _ = fresnel(get_material("metal").permittivity(f), 0.0, pol)
            assert abs(r) == pytest.approx(1.0, abs=1e-3)
    # a good conductor: 1 − |Γ| ≈ 2·Re(1/√η) ≈ 1.05e-3 at 100 GHz
    r100, _ = fresnel(get_material("metal").permittivity(100e9), 0.0)
    assert 1 - abs(r100) == pytest.approx(2 * (1 / np.sqrt(get_material("metal").permittivity(100e9))).real, rel=1e-3)


def test_out_of_range_frequency_is_an_error():
    with pytest.raises(InputError) as exc:
        get_material("brick").permittivity(77e9)
    msg = str(exc.value)
    assert "brick" in msg and "77" in msg and "1–40 GHz" in msg
    with pytest.raises(InputError, match="wood"):
        get_material("wood").permittivity([10e9, 200e9])  # one bad element is enough
    with pytest.raises(InputError):
        get_material("floorboard").permittivity(10e9)  # floorboard starts at 50 GHz


def test_extrapolate_is_explicit():
    eta = get_material("brick").permittivity(77e9, extrapolate=True)
    assert eta.real == pytest.approx(3.91) and eta.imag < 0


def test_range_edges_are_inclusive():
    m = get_material("concrete")
    m.permittivity([1e9, 100e9])
    assert m.covers(100e9) and not m.covers(100.1e9)


@pytest.mark.parametrize("bad", [0.0, -1e9, np.nan, np.inf])
def test_bad_frequency(bad):
    with pytest.raises(InputError, match="f_hz"):
        get_material("concrete").permittivity(bad)


def test_unknown_material_lists_known_and_suggests():
    with pytest.raises(InputError) as exc:
        get_material("concret")
    msg = str(exc.value)
    assert "did you mean 'concrete'" in msg
    for name in ("brick", "glass", "metal", "wood", "plasterboard"):
        assert name in msg


def test_name_normalisation_and_passthrough():
    assert get_material("Ceiling-Board") is MATERIALS["ceiling_board"]
    assert get_material(" Medium dry ground ") is MATERIALS["medium_dry_ground"]
    m = MATERIALS["glass"]
    assert get_material(m) is m
    with pytest.raises(InputError):
        get_material(3)


def test_material_is_frozen_and_validated():
    m = MATERIALS["concrete"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.a = 1.0
    with pytest.raises(InputError, match="f_min_hz"):
        Material("x", 2.0, 0.0, 0.0, 0.0, 10e9, 1e9)
    with pytest.raises(InputError, match="a"):
        Material("x", -2.0, 0.0, 0.0, 0.0, 1e9, 10e9)
    with pytest.raises(InputError):
        Material("x", float("nan"), 0.0, 0.0, 0.0, 1e9, 10e9)


def test_float32_frequency_is_evaluated_in_float64():
    m = get_material("glass")
    e32 = m.permittivity(np.float32(10e9))
    assert e32.dtype == np.complex128
    assert e32 == pytest.approx(m.permittivity(float(np.float32(10e9))), rel=1e-15)


def test_all_materials_evaluate_inside_their_range():
    for m in MATERIALS.values():
        f = np.geomspace(m.f_min_hz, m.f_max_hz, 5)
        eta = m.permittivity(f)
        assert np.all(np.isfinite(eta)) and np.all(eta.imag <= 0) and np.all(eta.real > 0)
