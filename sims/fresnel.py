"""Plane-wave reflection and transmission at an air/material interface and by a slab.

Convention e^{+jωt} (see :mod:`sims.materials`): η = ε' − jε'' with ε'' ≥ 0 for a passive
medium, and the normal wavenumber factor √(η − sin²θ) is taken on the branch with Im ≤ 0 (a wave
decaying into the medium; Re ≥ 0). Incidence is from vacuum; θ is measured from the wall normal.

Polarisations: ``"s"`` ≡ ``"te"`` (E perpendicular to the plane of incidence — a vertically
polarised radar on a vertical wall in the horizontal BEV plane) and ``"p"`` ≡ ``"tm"`` (E in the
plane of incidence). TM coefficients follow ITU-R P.2040-3 Eq. 37b (the Fresnel/Hecht sign
convention): at normal incidence r_p = −r_s, |r_p| = |r_s|.

Everything is computed in float64/complex128 whatever the input dtype (float32 included), and
broadcasts over all array arguments.
"""
from __future__ import annotations

import numpy as np
from scipy.constants import speed_of_light

from xnlos_core.errors import InputError

_HALF_PI = np.pi / 2


def polarisation(pol: str) -> str:
    p = str(pol).strip().lower()
    if p in ("s", "te", "perp", "h"):
        return "s"
    if p in ("p", "tm", "par"):
        return "p"
    raise InputError(f"pol must be 's'/'TE' or 'p'/'TM', got {pol!r}")


def as_eps(eps_r) -> np.ndarray:
    """Complex relative permittivity as complex128; must be finite with Im ≤ 0 (passive, e^{jωt})."""
    e = np.asarray(eps_r)
    if e.dtype == object or not (np.issubdtype(e.dtype, np.number)):
        raise InputError(f"eps_r must be numeric (complex relative permittivity), got dtype {e.dtype}")
    e = e.astype(np.complex128)
    # ndarray methods, not np.all/np.any: the same test without the dispatch wrapper (validation runs per
    # wall bounce in the ray tracer)
    if not np.isfinite(e).all():
        raise InputError("eps_r must be finite")
    if (e.imag > 1e-12 * np.maximum(np.abs(e), 1.0)).any():
        raise InputError(
            "eps_r must have Im(eps_r) ≤ 0 (passive medium in the e^{+jωt} convention, "
            "η = ε' − jσ/(ωε0)); a positive imaginary part suggests the e^{−iωt} convention — conjugate it"
        )
    return e


def as_theta(theta_i) -> np.ndarray:
    """Incidence angle [rad] as float64 in [0, π/2]; values within 1e-9 rad outside are clipped."""
    t = np.asarray(theta_i, dtype=np.float64)
    if not ((t >= -1e-9) & (t <= _HALF_PI + 1e-9)).all():  # one pass; NaN and ±inf fail it too
        if not np.isfinite(t).all():
            raise InputError("theta_i must be finite (radians)")
        raise InputError(f"theta_i must lie in [0, π/2] rad (from the wall normal), got {theta_i!r}")
    return np.clip(t, 0.0, _HALF_PI)


def normal_root(eps: np.ndarray, cos_t: np.ndarray) -> np.ndarray:
    """√(η − sin²θ) = √((η − 1) + cos²θ) on the decaying branch (Im ≤ 0, Re ≥ 0); complex128.

    Written with cos²θ so that η = 1 gives exactly cosθ (no interface) and grazing angles keep
    their precision.
    """
    a = np.sqrt((eps - 1.0) + cos_t * cos_t)
    return np.where(a.imag > 0, -a, a)


def fresnel(eps_r, theta_i, pol: str = "s") -> tuple[np.ndarray, np.ndarray]:
    """Amplitude reflection r and transmission t of the vacuum → η half-space interface.

    eps_r: complex relative permittivity η (any shape); theta_i: incidence angle [rad] from the
    normal, 0 ≤ θ ≤ π/2; pol: 's'/'TE' or 'p'/'TM'. Returns (r, t), complex128, broadcast shape.
    With cosθ = c and a = √(η − sin²θ) (Im a ≤ 0):

        TE (P.2040-3 Eq. 37a):  r_s = (c − a)/(c + a) = (1 − η)/(c + a)²,   t_s = 2c/(c + a) = 1 + r_s
        TM (P.2040-3 Eq. 37b):  r_p = (ηc − a)/(ηc + a),                    t_p = 2√η·c/(ηc + a)

    Field ratios; the power transmittance into the medium is not |t|² (it carries the impedance
    ratio), so energy balance is checked on slabs (air on both sides), not here. |r| ≤ 1 for every
    passive η; |r| → 1 for θ → 90° and for a good conductor (metal, |η| ~ 1e6…1e10).
    The η = 1, θ = 90° corner (no interface, 0/0) returns r = 0, t = 1.
    """
    p = polarisation(pol)
    eps = as_eps(eps_r)
    th = as_theta(theta_i)
    eps, c = np.broadcast_arrays(eps, np.cos(th))
    a = normal_root(eps, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        if p == "s":
            den = c + a
            r = (1.0 - eps) / (den * den)
            t = 2.0 * c / den
        else:
            den = eps * c + a
            r = (eps * c - a) / den
            t = 2.0 * np.sqrt(eps) * c / den
    degenerate = den == 0
    r = np.where(degenerate, 0.0, r)
    t = np.where(degenerate, 1.0, t)
    return r, t


def brewster_angle(eps_r) -> np.ndarray:
    """Brewster angle θ_B = arctan √ε [rad] of a lossless dielectric (TM reflection vanishes).

    eps_r: real relative permittivity > 0 (a complex value must have Im = 0 within 1e-12·|ε|; a
    lossy medium has only a pseudo-Brewster minimum, not a zero). Any shape → float64.
    """
    e = np.asarray(eps_r)
    if np.iscomplexobj(e):
        if np.any(np.abs(e.imag) > 1e-12 * np.abs(e)):
            raise InputError("brewster_angle: eps_r must be lossless (Im = 0); a lossy medium has no TM zero")
        e = e.real
    e = e.astype(np.float64)
    if not np.all(np.isfinite(e)) or np.any(e <= 0):
        raise InputError(f"brewster_angle: eps_r must be finite and > 0, got {eps_r!r}")
    return np.arctan(np.sqrt(e))


def slab(eps_r, thickness_m, theta_i, f_hz, pol: str = "s") -> tuple[np.ndarray, np.ndarray]:
    """Reflection R and transmission T of one homogeneous layer between vacuum half-spaces.

    eps_r: complex relative permittivity η of the layer; thickness_m: d ≥ 0 [m] (``np.inf`` → the
    half-space, T = 0); theta_i: incidence angle [rad]; f_hz: frequency [Hz] > 0; pol as in
    :func:`fresnel`. All broadcast; returns complex128 (R, T).

    Airy multiple-reflection sum, ITU-R P.2040-3 Eqs. 43a/43b with Eq. 44:

        q = (2π d / λ)·√(η − sin²θ),    r' = fresnel(η, θ, pol)
        R = r'·(1 − e^{−2jq}) / (1 − r'²·e^{−2jq})
        T = (1 − r'²)·e^{−jq} / (1 − r'²·e^{−2jq})

    R is referred to the front face. T relates the field leaving the back face to the field
    incident on the front face (P.2040's reference, no free-space phase): with no layer (η = 1)
    T = e^{−jk0·d·cosθ}. The *insertion* coefficient (transmitted field over the unobstructed
    field at the same point) is T·e^{+jk0·d·cosθ}. Since Im q ≤ 0 the exponentials only decay:
    a thick lossy slab or a metal underflows e^{−2jq} → 0 harmlessly and R → r', T → 0.
    Lossless layer: |R|² + |T|² = 1; lossy layer: < 1. R = 0 when 2q = 2πm (lossless), e.g.
    normal incidence at d = λ/(2√ε').
    """
    p = polarisation(pol)
    eps = as_eps(eps_r)
    th = as_theta(theta_i)
    d = np.asarray(thickness_m, dtype=np.float64)
    f = np.asarray(f_hz, dtype=np.float64)
    if np.any(np.isnan(d)) or np.any(d < 0):
        raise InputError(f"thickness_m must be ≥ 0 (metres; np.inf for a half-space), got {thickness_m!r}")
    if not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise InputError(f"f_hz must be finite and > 0 (Hz), got {f_hz!r}")
    r, _ = fresnel(eps, th, p)
    a = normal_root(eps, np.cos(th))
    r, a, d, f = np.broadcast_arrays(r, a, d, f)
    thick = np.isinf(d)
    d_fin = np.where(thick, 0.0, d)
    q = 2.0 * np.pi * d_fin * f / speed_of_light * a
    e1 = np.exp(-1j * q)
    e2 = e1 * e1
    e1 = np.where(thick, 0.0, e1)
    e2 = np.where(thick, 0.0, e2)
    r2 = r * r
    den = 1.0 - r2 * e2
    zero = den == 0  # only |r| = 1 (exact grazing, lossless) with 2q = 2πm: limit is R = r
    den = np.where(zero, 1.0, den)
    R = np.where(zero, r, r * (1.0 - e2) / den)
    T = np.where(zero, 0.0, (1.0 - r2) * e1 / den)
    return R, T
