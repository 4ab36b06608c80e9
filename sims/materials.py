"""Building materials after ITU-R P.2040-3, Table 3: ε' = a·f^b, σ = c·f^d (f in GHz).

Each :class:`Material` carries the four Table 3 coefficients and the frequency range over which
the recommendation fitted them. Evaluating a material outside that range raises
:class:`~xnlos_core.errors.InputError` (no silent extrapolation); ``extrapolate=True`` lifts the
check deliberately.

Time convention: P.2040 (and all of ``sims.materials``, ``sims.fresnel``, ``sims.fdtd``) uses
phasors with e^{+jωt}, the convention of the FMCW chain in :mod:`xnlos_core.signal.chain`.
A plane wave travelling along +z is E·e^{j(ωt − kz)}; a lossy medium has a *negative* imaginary
permittivity, η = ε' − jε''; a propagation delay τ multiplies a phasor by e^{−jωτ}. A reflection
coefficient Γ = |Γ|e^{jφ} therefore advances the reflected wave by φ (φ < 0 is a lag). Anyone
working in the physics convention e^{−iωt} must conjugate every complex value returned here.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

import numpy as np
from scipy.constants import epsilon_0

from xnlos_core.errors import InputError

GHZ = 1e9


@dataclass(frozen=True)
class Material:
    """One ITU-R P.2040-3 Table 3 material class.

    a, b: real relative permittivity ε' = a·f_GHz^b [-];
    c, d: conductivity σ = c·f_GHz^d [S/m];
    f_min_hz, f_max_hz: frequency range [Hz] over which the fit is valid (inclusive);
    notes: provenance / caveats.
    """

    name: str
    a: float
    b: float
    c: float
    d: float
    f_min_hz: float
    f_max_hz: float
    notes: str = ""

    def __post_init__(self):
        for key in ("a", "b", "c", "d", "f_min_hz", "f_max_hz"):
            v = getattr(self, key)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"Material {self.name!r}: {key} must be a finite number, got {v!r}")
        if self.a <= 0:
            raise InputError(f"Material {self.name!r}: a (ε' coefficient) must be > 0, got {self.a}")
        if self.c < 0:
            raise InputError(f"Material {self.name!r}: c (σ coefficient) must be ≥ 0, got {self.c}")
        if not 0 < self.f_min_hz < self.f_max_hz:
            raise InputError(
                f"Material {self.name!r}: need 0 < f_min_hz < f_max_hz, got {self.f_min_hz}, {self.f_max_hz}"
            )

    # -- evaluation -------------------------------------------------------------------------
    def _f_ghz(self, f_hz, extrapolate: bool) -> np.ndarray:
        f = np.asarray(f_hz, dtype=np.float64)
        if not np.isfinite(f).all() or (f <= 0).any():
            raise InputError(f"f_hz must be finite and > 0 (Hz), got {f_hz!r}")
        if not extrapolate:
            bad = (f < self.f_min_hz * (1 - 1e-12)) | (f > self.f_max_hz * (1 + 1e-12))
            if bad.any():
                fb = float(np.atleast_1d(f)[np.atleast_1d(bad)][0])
                raise InputError(
                    f"material {self.name!r} is defined by ITU-R P.2040-3 only for "
                    f"{self.f_min_hz / GHZ:g}–{self.f_max_hz / GHZ:g} GHz; f_hz = {fb:.6g} Hz "
                    f"({fb / GHZ:g} GHz) is outside that range (pass extrapolate=True to evaluate "
                    f"the fit outside its range on purpose)"
                )
        return f / GHZ

    def real_permittivity(self, f_hz, *, extrapolate: bool = False) -> np.ndarray:
        """ε'(f) = a·f_GHz^b [-]; f_hz [Hz] any shape → float64 of the same shape."""
        return self.a * self._f_ghz(f_hz, extrapolate) ** self.b

    def conductivity(self, f_hz, *, extrapolate: bool = False) -> np.ndarray:
        """σ(f) = c·f_GHz^d [S/m]; f_hz [Hz] any shape → float64 of the same shape."""
        return self.c * self._f_ghz(f_hz, extrapolate) ** self.d

    def permittivity(self, f_hz, *, extrapolate: bool = False) -> np.ndarray:
        """Complex relative permittivity η = ε' − jσ/(2π f ε0) (e^{jωt} convention).

        Numerically η = ε' − j·17.98·σ/f_GHz (ITU-R P.2040-3: ε'' = σ/(ωε0)). f_hz [Hz], any
        shape → complex128 of the same shape, Im η ≤ 0. Frequencies outside [f_min_hz, f_max_hz] raise
        InputError naming the material, the frequency and the range, unless ``extrapolate=True``
        (then the power laws are evaluated as they stand; the result is not covered by P.2040).
        """
        f_ghz = self._f_ghz(f_hz, extrapolate)
        eps1 = self.a * f_ghz**self.b
        sigma = self.c * f_ghz**self.d
        return eps1 - 1j * sigma / (2 * np.pi * f_ghz * GHZ * epsilon_0)

    def covers(self, f_hz) -> bool:
        """True if every frequency [Hz] lies inside the P.2040 validity range."""
        f = np.asarray(f_hz, dtype=np.float64)
        return bool(((f >= self.f_min_hz) & (f <= self.f_max_hz)).all())


def _m(name, a, b, c, d, f_lo_ghz, f_hi_ghz, notes=""):
    return Material(name, a, b, c, d, f_lo_ghz * GHZ, f_hi_ghz * GHZ,
                    notes or "ITU-R P.2040-3 Table 3")


_TABLE3 = [
    _m("vacuum", 1.0, 0.0, 0.0, 0.0, 0.001, 100.0, "ITU-R P.2040-3 Table 3 (≈ air)"),
    _m("concrete", 5.24, 0.0, 0.0462, 0.7822, 1.0, 100.0),
    _m("brick", 3.91, 0.0, 0.0238, 0.16, 1.0, 40.0),
    _m("plasterboard", 2.73, 0.0, 0.0085, 0.9395, 1.0, 100.0),
    _m("wood", 1.99, 0.0, 0.0047, 1.0718, 0.001, 100.0),
    _m("glass", 6.31, 0.0, 0.0036, 1.3394, 0.1, 100.0,
       "ITU-R P.2040-3 Table 3, 0.1–100 GHz row (a second row covers 220–450 GHz)"),
    _m("ceiling_board", 1.48, 0.0, 0.0011, 1.075, 1.0, 100.0,
       "ITU-R P.2040-3 Table 3, 1–100 GHz row (a second row covers 220–450 GHz)"),
    _m("chipboard", 2.58, 0.0, 0.0217, 0.78, 1.0, 100.0),
    _m("plywood", 2.71, 0.0, 0.33, 0.0, 1.0, 40.0),
    _m("marble", 7.074, 0.0, 0.0055, 0.9262, 1.0, 60.0),
    _m("floorboard", 3.66, 0.0, 0.0044, 1.3515, 50.0, 100.0),
    _m("metal", 1.0, 0.0, 1e7, 0.0, 1.0, 100.0,
       "ITU-R P.2040-3 Table 3: ε' = 1, σ = 10⁷ S/m (a good conductor, |η| ~ 10⁶–10⁸)"),
    _m("very_dry_ground", 3.0, 0.0, 0.00015, 2.52, 1.0, 10.0),
    _m("medium_dry_ground", 15.0, -0.1, 0.035, 1.63, 1.0, 10.0),
    _m("wet_ground", 30.0, -0.4, 0.15, 1.30, 1.0, 10.0),
]

#: name → Material, every ITU-R P.2040-3 Table 3 class (first frequency row of each).
MATERIALS: dict[str, Material] = {m.name: m for m in _TABLE3}


def get_material(name: str | Material) -> Material:
    """The Table 3 material called ``name`` (case-insensitive; '-', ' ' read as '_').

    A Material passes through unchanged. Unknown names raise InputError listing the known
    materials, with the closest match when there is one.
    """
    if isinstance(name, Material):
        return name
    if not isinstance(name, str):
        raise InputError(f"material must be a name (str) or a Material, got {type(name).__name__}")
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    if key in MATERIALS:
        return MATERIALS[key]
    close = difflib.get_close_matches(key, list(MATERIALS), n=1)
    hint = f" — did you mean {close[0]!r}?" if close else ""
    raise InputError(f"unknown material {name!r}{hint} Known materials: {', '.join(MATERIALS)}")
