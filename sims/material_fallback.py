"""Documented fallbacks for P.2040 materials outside their fitted frequency range (e.g. 77 GHz).

ITU-R P.2040-3 Table 3 fits brick and plywood over 1–40 GHz and marble over 1–60 GHz, so a 77 GHz
radar (preset ``automotive_77ghz``) cannot evaluate them as they stand (:mod:`sims.materials`
raises). For these three the forward models use a fallback instead of failing, and say so once with
a :class:`~xnlos_core.errors.MaterialFallbackWarning` — never a silent extrapolation:

* **Held at the upper range edge.** ε' and σ are the Table 3 values at f_max (40 or 60 GHz), held
  constant up to ``FALLBACK_LIMIT_HZ`` = 100 GHz (the upper limit of the other building materials
  of Table 3). Why this and not the power law: the three fits have b = 0 (ε' independent of
  frequency over the whole fitted range), so only σ = c·f^d would be extrapolated; holding σ uses
  only values P.2040 fitted. The choice barely matters for a reflection: for brick at 77 GHz the
  extrapolated power law gives σ 11 % higher (0.0477 vs 0.0430 S/m), |Γ(0)|² changes by < 0.01 dB
  (tests/unit/test_material_fallback.py checks both numbers).
* **No fallback** for the ground classes (1–10 GHz): wet and dry soils have a water relaxation
  between 10 and 100 GHz, so neither holding nor extrapolating is defensible; they raise InputError.

Materials whose range covers the frequency (concrete, wood, glass, metal, plasterboard, … at
77 GHz) are returned unchanged. :func:`material_at` is what :mod:`sims.walls` evaluates.
"""
from __future__ import annotations

import warnings

import numpy as np

from xnlos_core.errors import InputError, MaterialFallbackWarning

from .materials import GHZ, Material, get_material

FALLBACK_LIMIT_HZ = 100e9  # [Hz] highest frequency a fallback is offered for
#: Table 3 names with a documented fallback above their range: held at f_max (module doc).
HELD_AT_EDGE = ("brick", "plywood", "marble")

_warned: set[tuple[str, float]] = set()


def has_fallback(material: str | Material, f_hz: float) -> bool:
    """True when ``material`` is not P.2040-covered at ``f_hz`` [Hz] but has a documented fallback there."""
    m = get_material(material)
    f = float(f_hz)
    return (not m.covers(f)) and m.name in HELD_AT_EDGE and m.f_max_hz < f <= FALLBACK_LIMIT_HZ


def held_material(material: str | Material) -> Material:
    """The fallback Material: Table 3 ε' and σ at f_max [Hz], constant (b = d = 0) from f_min to 100 GHz."""
    m = get_material(material)
    eps1 = float(m.real_permittivity(m.f_max_hz))
    sigma = float(m.conductivity(m.f_max_hz))
    return Material(m.name, eps1, 0.0, sigma, 0.0, m.f_min_hz, FALLBACK_LIMIT_HZ,
                    f"fallback: ITU-R P.2040-3 Table 3 {m.name} (fitted {m.f_min_hz / GHZ:g}–{m.f_max_hz / GHZ:g} GHz) "
                    f"held at {m.f_max_hz / GHZ:g} GHz: ε' = {eps1:.4g}, σ = {sigma:.4g} S/m (sims.material_fallback)")


def material_at(material: str | Material, f_hz: float) -> Material:
    """The Material to evaluate at carrier ``f_hz`` [Hz]: the Table 3 class where P.2040 covers f, its
    documented fallback (with a MaterialFallbackWarning, once per material and frequency) where one
    exists, else InputError naming the material, the frequency and the range."""
    m = get_material(material)
    f = float(f_hz)
    if not np.isfinite(f) or f <= 0:
        raise InputError(f"f_hz must be finite and > 0 (Hz), got {f_hz!r}")
    if m.covers(f):
        return m
    if has_fallback(m, f):
        held = held_material(m)
        if (m.name, f) not in _warned:
            _warned.add((m.name, f))
            warnings.warn(f"material {m.name!r} is fitted by ITU-R P.2040-3 only for {m.f_min_hz / GHZ:g}–"
                          f"{m.f_max_hz / GHZ:g} GHz; at {f / GHZ:g} GHz the simulator uses its {held.notes}",
                          MaterialFallbackWarning, stacklevel=3)
        return held
    m.permittivity(f)  # raises the InputError that names material, frequency and range
    raise AssertionError("unreachable")  # pragma: no cover
