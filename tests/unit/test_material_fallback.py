"""Materials at 77 GHz: P.2040 coverage of every material the generators use, and the documented
brick/plywood/marble fallback (held at the range edge, warned once, typed)."""
import warnings

import numpy as np
import pytest

from sims.fresnel import fresnel
from sims.generators import FAMILIES
from sims.material_fallback import HELD_AT_EDGE, has_fallback, material_at
from sims.materials import get_material
from sims.walls import specular_alpha
from xnlos_core.errors import InputError, MaterialFallbackWarning
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import WallSpec

F77 = 77e9


def test_generator_materials_are_covered_at_77ghz_or_have_the_fallback():
    used = {"concrete", "brick", "wood", "metal", "glass"}  # generators' defaults and fixed materials
    for name in used:
        m = get_material(name)
        assert m.covers(F77) or has_fallback(m, F77), name
    assert {n for n in used if not get_material(n).covers(F77)} == {"brick"}  # the only one needing it


def test_brick_fallback_holds_the_40ghz_values_and_differs_little_from_the_power_law():
    brick = get_material("brick")
    with pytest.warns(MaterialFallbackWarning, match=r"brick.*1–40 GHz.*76.5 GHz"):
        held = material_at("brick", 76.5e9)
    assert held.real_permittivity(F77) == pytest.approx(3.91)
    assert held.conductivity(F77) == pytest.approx(0.0238 * 40**0.16, rel=1e-12)  # 0.0430 S/m
    extrap = brick.conductivity(F77, extrapolate=True)
    assert extrap == pytest.approx(0.0477, abs=5e-4) and held.conductivity(F77) == pytest.approx(0.0430, abs=5e-4)
    g_held = abs(fresnel(held.permittivity(F77), 0.0, "s")[0]) ** 2
    g_extr = abs(fresnel(brick.permittivity(F77, extrapolate=True), 0.0, "s")[0]) ** 2
    assert abs(10 * np.log10(g_held / g_extr)) < 0.01  # the documented bound


def test_fallback_warns_once_and_covered_materials_pass_unchanged():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert material_at("concrete", F77) is get_material("concrete")
        assert material_at("brick", 10e9) is get_material("brick")
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        material_at("plywood", 78e9)
        material_at("plywood", 78e9)
    assert [type(w.message) for w in rec] == [MaterialFallbackWarning]


def test_no_fallback_for_grounds_or_beyond_100ghz():
    with pytest.raises(InputError, match="wet_ground.*1–10 GHz"):
        material_at("wet_ground", F77)
    with pytest.raises(InputError, match="brick.*1–40 GHz"):
        material_at("brick", 140e9)
    assert set(HELD_AT_EDGE) == {"brick", "plywood", "marble"}


def test_walls_of_brick_work_at_77ghz_and_generators_accept_it():
    radar = RadarConfig(carrier_frequency=F77)
    wall = WallSpec(start=(10.0, 5.0), end=(10.0, -5.0), material="brick")
    with pytest.warns(MaterialFallbackWarning):
        material_at("brick", 77.0001e9)  # a fresh frequency, so this test sees its own warning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MaterialFallbackWarning)
        a = specular_alpha(wall, radar, 0.0)
        eps = material_at("brick", F77).permittivity(F77)
        assert complex(a) == pytest.approx(complex(fresnel(eps, 0.0, "s")[0]))
        params = FAMILIES["corner_split"].Params(carrier_hz=F77, radar={"carrier_frequency": F77})
    assert "brick" in params.materials
