"""Radius of the disc around a 2-D Gaussian's mean that holds a given probability.

For X ~ N(0, Σ) with eigenvalues λ₁ ≥ λ₂ of Σ [m²], write X = (√λ₁ ρ cos ψ, √λ₂ ρ sin ψ) in the
eigenbasis with (ρ, ψ) the polar coordinates of a standard normal Z (ρ² ~ χ²₂, ψ uniform). Then
|X| ≤ r ⟺ ρ² ≤ r²/b(ψ), b(ψ) = λ₁cos²ψ + λ₂sin²ψ, and P(ρ² ≤ c) = 1 − exp(−c/2), so

    P(|X| ≤ r) = 1 − (1/2π) ∫₀^{2π} exp(−r² / (2 b(ψ))) dψ                       (1)

exactly (the distribution of λ₁χ²₁ + λ₂χ²₁). The integrand is smooth and periodic (its width in ψ is
≈ r/√λ₁ ≈ 1 rad at the radii of interest, also as λ₂ → 0), so the trapezoid rule on ``N_PHI``
angles converges geometrically; r comes from Newton's method on (1), with dP/dr = (1/2π) ∫ r/b(ψ)
exp(−r²/(2b(ψ))) dψ, safeguarded by bisection inside the bracket of the isotropic radii √(−2λ ln(1 − p))
of λ₂ and λ₁ (a step that leaves the bracket bisects it instead), started from a table of r/√λ₁
against λ₂/λ₁ per probability (interpolated on 1025 ratios: one or two Newton steps to 1e-12) — a handful of
iterations where bisection alone took 40 (the forecast of every track at every frame needs two radii per horizon).
For λ₁ = λ₂ = λ, (1) is 1 − exp(−r²/2λ).
Hand-written: scipy has no generalised χ² distribution.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from xnlos_core.errors import InputError

N_PHI = 64
MAX_ITER = 60  # safeguarded Newton steps at most (bisection alone would need ≈ 40)
RTOL = 1e-12  # stop once every step is below this fraction of the bracket's upper end
_COS2 = np.cos((np.arange(N_PHI) + 0.5) * (np.pi / N_PHI)) ** 2  # b(ψ) has period π: half the circle
_SIN2 = 1.0 - _COS2


def disc_probability(r, lam1, lam2) -> np.ndarray:
    """P(|X| ≤ r) (…) of Eq. (1) for eigenvalues ``lam1``, ``lam2`` (…) [m²] ≥ 0 and radius r (…) [m]."""
    lam1, lam2, r = (np.asarray(a, dtype=np.float64)[..., None] for a in (lam1, lam2, r))
    return 1.0 - np.mean(np.exp(-0.5 * r * r / (lam1 * _COS2 + lam2 * _SIN2)), axis=-1)


_RATIOS = np.linspace(0.0, 1.0, 1025) ** 2  # λ₂/λ₁ of the starting table (denser near 0, where r bends most)


@lru_cache(maxsize=16)
def _table(prob: float) -> np.ndarray:
    """r/√λ₁ (1025,) at ``_RATIOS`` for one probability: Eq. (1) solved by bisection (the Newton start)."""
    lo, hi = np.zeros(len(_RATIOS)), np.full(len(_RATIOS), np.sqrt(-2 * np.log1p(-prob)) * 1.0001)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        below = disc_probability(mid, 1.0, _RATIOS) < prob
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _start(prob, ratio, shape) -> np.ndarray:
    """Newton's starting radius over √λ₁ (shape) from the table of each distinct probability (≤ 16 of
    them; the bracket's midpoint's start for more, NaN)."""
    prob, ratio = np.broadcast_arrays(np.asarray(prob, dtype=np.float64), np.broadcast_to(ratio, shape))
    out = np.full(shape, np.nan)
    values = np.unique(prob)
    if len(values) > 16:
        return out
    for v in values:
        m = prob == v
        out[m] = np.interp(ratio[m], _RATIOS, _table(float(v)))
    return out


def disc_radius(cov, prob) -> np.ndarray:
    """Radius (…) [m] of the disc around the mean of N(μ, ``cov``) (…, 2, 2) [m²] holding ``prob``
    (a float, or an array broadcast against the leading shape (…) of ``cov``)."""
    cov = np.asarray(cov, dtype=np.float64)
    if cov.shape[-2:] != (2, 2) or not np.all(np.isfinite(cov)):
        raise InputError(f"disc_radius: cov must be a finite (…, 2, 2) array [m²], got shape {cov.shape}")
    prob = np.asarray(prob, dtype=np.float64)
    if not np.all((prob > 0) & (prob < 1)):
        raise InputError(f"disc_radius: prob must be in (0, 1), got {prob}")
    lam = np.linalg.eigvalsh(0.5 * (cov + np.swapaxes(cov, -1, -2)))
    lam_max = np.maximum(lam[..., 1], 1e-300)
    lam_min = np.maximum(lam[..., 0], 0.0)
    k = np.sqrt(-2 * np.log1p(-prob))
    lo, hi = np.broadcast_arrays(k * np.sqrt(lam_min), k * np.sqrt(lam_max))
    a, b = lam_max[..., None], lam_min[..., None]
    bpsi = np.broadcast_to(a * _COS2 + b * _SIN2, lo.shape + (N_PHI,))  # (…, N_PHI)
    r = _start(prob, lam_min / lam_max, lo.shape) * np.sqrt(lam_max)
    r = np.where((r > lo) & (r < hi), r, 0.5 * (lo + hi))
    for _ in range(MAX_ITER):
        e = np.exp(-0.5 * r[..., None] ** 2 / bpsi)
        f = 1.0 - e.mean(axis=-1) - prob
        lo, hi = np.where(f < 0, r, lo), np.where(f < 0, hi, r)
        slope = np.mean(r[..., None] / bpsi * e, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = r - f / slope
        ok = np.isfinite(newton) & (newton >= lo) & (newton <= hi)
        step = np.where(ok, newton, 0.5 * (lo + hi)) - r
        r = r + step
        if np.all(np.abs(step) <= RTOL * hi):
            break
    return r
