"""1-D FDTD slab solver against the analytic Airy slab, its caches, and wall_reflection."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy.constants import epsilon_0, speed_of_light

import sims.fdtd as fdtd
from sims.fdtd import (
    cache_dir,
    clear_cache,
    fdtd_coefficients,
    fdtd_reflection,
    simulate_slab,
    wall_reflection,
)
from sims.fresnel import fresnel, slab
from sims.materials import Material, get_material
from sims.roughness import specular_field_factor
from xnlos_core.errors import InputError

DEG = np.pi / 180
LOSSLESS4 = Material("lossless4", 4.0, 0.0, 0.0, 0.0, 1e9, 100e9, "test dielectric ε = 4")


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XNLOS_CACHE_DIR", str(tmp_path / "cache"))
    clear_cache()
    yield
    clear_cache()


def _analytic(material, d, f, theta=0.0, pol="s"):
    return slab(get_material(material).permittivity(f), d, theta, f, pol)


CASES = [
    ("concrete", 10e9, 0.001), ("concrete", 10e9, 0.02), ("concrete", 10e9, 0.3),
    ("glass", 10e9, 0.006), ("glass", 10e9, 0.1), ("wood", 10e9, 0.05),
    ("concrete", 77e9, 0.005), ("concrete", 77e9, 0.1), ("glass", 77e9, 0.01), ("wood", 77e9, 0.03),
]


@pytest.mark.parametrize("material,f,d", CASES)
def test_fdtd_matches_analytic_slab(material, f, d):
    R, T = fdtd_coefficients(material, d, f, cache=False)
    Ra, Ta = _analytic(material, d, f)
    assert abs(abs(R) - abs(Ra)) < 0.03
    assert abs(R - Ra) < 0.03  # the phase agrees too (same e^{jωt} convention and reference)
    assert abs(T - Ta) < 0.03


@pytest.mark.parametrize("f", [10e9, 77e9])
@pytest.mark.parametrize("material", [LOSSLESS4, "concrete"])
def test_half_wave_slab_vanishes(material, f):
    m = get_material(material)
    d = speed_of_light / f / (2 * np.sqrt(m.real_permittivity(f)))
    R, T = fdtd_coefficients(m, d, f, cache=False)
    Ra, _ = _analytic(m, d, f)
    assert abs(abs(R) - abs(Ra)) < 0.03
    if m is LOSSLESS4:
        assert abs(R) < 0.01
        assert abs(R) ** 2 + abs(T) ** 2 == pytest.approx(1.0, abs=0.01)


def test_lossless_energy_and_lossy_bound():
    res = simulate_slab(4.0, 0.0, 0.023, [8e9, 10e9, 12e9])
    np.testing.assert_allclose(np.abs(res.R) ** 2 + np.abs(res.T) ** 2, 1.0, atol=0.01)
    Ra, _ = slab(4.0, 0.023, 0.0, res.f_hz)
    np.testing.assert_allclose(np.abs(res.R), np.abs(Ra), atol=0.03)
    lossy = simulate_slab(5.24, 0.28, 0.05, 10e9)
    assert abs(lossy.R[0]) ** 2 + abs(lossy.T[0]) ** 2 < 1.0


def test_no_slab_gives_no_reflection():
    res = simulate_slab(5.0, 0.1, 0.0, 10e9)
    assert abs(res.R[0]) < 1e-9 and abs(res.T[0] - 1) < 1e-9 and res.converged


def test_metal_is_a_mirror_and_half_space_from_thick_lossy_slab():
    R = fdtd_reflection("metal", 0.01, 10e9, cache=False)
    assert abs(R) == pytest.approx(1.0, abs=0.01)
    eps = get_material("concrete").permittivity(10e9)
    Rh, Th = fdtd_coefficients("concrete", None, 10e9, cache=False)
    assert abs(Rh - fresnel(eps, 0.0)[0]) < 0.01 and abs(Th) < 1e-2


def test_oblique_te_mapping():
    for mat, d, th in (("concrete", 0.03, 45 * DEG), ("glass", 0.012, 70 * DEG)):
        R, T = fdtd_coefficients(mat, d, 10e9, th, cache=False)
        Ra, Ta = _analytic(mat, d, 10e9, th)
        assert abs(R - Ra) < 0.03 and abs(T - Ta) < 0.03


def test_out_of_range_frequency_and_limits():
    with pytest.raises(InputError, match="brick"):
        fdtd_reflection("brick", 0.1, 77e9)
    with pytest.raises(InputError, match="85"):
        fdtd_reflection("concrete", 0.1, 10e9, 88 * DEG)
    with pytest.raises(InputError, match="lossless"):
        fdtd_reflection(LOSSLESS4, None, 10e9)
    with pytest.raises(InputError, match="eps_real"):
        simulate_slab(0.5, 0.0, 0.01, 10e9)


def test_disk_cache_roundtrip_and_corruption(monkeypatch):
    R1 = fdtd_reflection("concrete", 0.05, 10e9)
    files = list(cache_dir().glob("*.json"))
    assert len(files) == 1
    rec = json.loads(files[0].read_text())
    assert rec["key"]["solver"] == fdtd.SOLVER_VERSION and rec["key"]["thickness_m"] == 0.05
    # in-process: a second call does not touch the solver
    solver = fdtd.simulate_slab
    monkeypatch.setattr(fdtd, "simulate_slab", lambda *a, **k: pytest.fail("cache missed"))
    assert fdtd_reflection("concrete", 0.05, 10e9) == R1
    # from disk after clearing the lru cache
    clear_cache()
    assert fdtd_reflection("concrete", 0.05, 10e9) == R1
    # a corrupt file warns, is recomputed and rewritten
    monkeypatch.setattr(fdtd, "simulate_slab", solver)
    files[0].write_text("{not json")
    clear_cache()
    with pytest.warns(RuntimeWarning, match="corrupt"):
        R2 = fdtd_reflection("concrete", 0.05, 10e9)
    assert R2 == pytest.approx(R1, abs=1e-12)
    assert json.loads(files[0].read_text())["R"] == [R1.real, R1.imag]
    # different settings → different key
    fdtd_reflection("concrete", 0.05, 10e9, ppw=30)
    assert len(list(cache_dir().glob("*.json"))) == 2


def test_wall_reflection_methods_agree():
    th = np.array([0.0, 30 * DEG, 60 * DEG])
    a = wall_reflection("concrete", 0.2, th, 10e9)
    b = wall_reflection("concrete", 0.2, th, 10e9, method="fdtd")
    assert a.shape == b.shape == (3,)
    np.testing.assert_allclose(b, a, atol=0.03)
    # half-space
    h = wall_reflection("glass", None, 0.5, 77e9, pol="p")
    assert h == pytest.approx(fresnel(get_material("glass").permittivity(77e9), 0.5, "p")[0])
    # TM by FDTD: normal incidence only, P.2040 sign
    tm0 = wall_reflection("concrete", 0.2, 0.0, 10e9, method="fdtd", pol="p")
    assert tm0 == pytest.approx(-b[0], abs=1e-12)
    with pytest.raises(InputError, match="TM"):
        wall_reflection("concrete", 0.2, 0.3, 10e9, method="fdtd", pol="p")
    with pytest.raises(InputError, match="method"):
        wall_reflection("concrete", 0.2, 0.3, 10e9, method="mom")


def test_wall_reflection_roughness_is_a_field_factor():
    f = np.array([10e9, 77e9])
    smooth = wall_reflection("concrete", 0.2, 70 * DEG, f)
    rough = wall_reflection("concrete", 0.2, 70 * DEG, f, roughness_m=5e-3)
    np.testing.assert_allclose(rough, smooth * specular_field_factor(5e-3, 70 * DEG, speed_of_light / f))
    assert abs(rough[0]) > 0.7 * abs(smooth[0]) and abs(rough[1]) < 1e-3 * abs(smooth[1])


def test_unconverged_run_warns():
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        res = simulate_slab(4.0, 0.0, 0.05, 10e9, max_steps=200)
    assert not res.converged and any("max_steps" in str(x.message) for x in w)


@pytest.mark.parametrize("e1,sigma,d", [(5.24, 0.28, 1e-4), (1.0, 1e7, 1e-7), (1.0, 1e7, 1e-9)])
def test_sub_cell_sheet(e1, sigma, d):
    res = simulate_slab(e1, sigma, d, 10e9)
    Ra, Ta = slab(e1 - 1j * sigma / (2 * np.pi * 10e9 * epsilon_0), d, 0.0, 10e9)
    assert abs(res.R[0] - Ra) < 0.01 and abs(res.T[0] - Ta) < 0.01
