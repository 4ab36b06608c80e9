"""Forecast of a tracked state (p, v) under a linear motion model: predictive mean and disc intervals,
and predictive path draws for the time-to-appearance.

Motion. d(p, v)/dt = A(Ξ)(p, v), A = [[0, I], [0, Ξ]] with Ξ (2, 2) [1/s] (Ξ = 0 is constant velocity,
CV; :mod:`estimators.trackers.sindy_model` for the turn and acceleration terms), driven by white
acceleration noise of PSD q [m²/s³]. Transition over h [s]: Φ(h) = expm(A h) (for CV the closed form
F = [[I, hI], [0, I]]); process noise Q(h) = q [[h³/3 I, h²/2 I], [h²/2 I, h I]], the CV one — for Ξ ≠ 0
the exact ∫Φ(s)GGᵀΦ(s)ᵀds differs from it at order |Ξ|h, within what q expresses anyway.

Model uncertainty is a set of M equally weighted members Ξ_m (CV: M = 1). From the state's mean x̂ and
covariance P, the predictive position at h is the member mixture of N(Φ_m x̂, Φ_m P Φ_mᵀ + Q(h)) (position
block), moment-matched to one Gaussian:

    μ(h) = mean_m μ_m,   Σ(h) = mean_m Σ_m + s² cov_m(μ_m),   cov_m(μ_m) = mean_m μ_m μ_mᵀ − μ μᵀ     (1)

with s = ``spread`` (1: the plain moment match). Σ(h) is the uncertainty of the object's *true* position
(its centre): no measurement noise R is added — the discs are to hold where the object will be, not
where its next cluster centroid will be measured. The 50 % and 90 % radii are exact for that Gaussian
(:func:`estimators.trackers.disc.disc_radius`). q and s are calibrated on synthetic tracks by
``benchmarks/forecast_calibration.py``.

Draws (for the time-to-appearance): D paths on the grid h_k = kδ, k = 0…G−1: x₀ ~ N(x̂, P), member m_d =
d mod M, x_{k+1} = Φ_{m_d}(δ) x_k + w_k with w_k ~ N(0, Q(δ)) — the object's own path, no measurement noise.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from .disc import disc_radius


def cv_process_noise(h, q: float) -> np.ndarray:
    """Q(h) (…, 4, 4) [m², m²/s, m²/s²] of white acceleration noise of PSD q [m²/s³] over h (…) [s]."""
    h = np.asarray(h, dtype=np.float64)[..., None, None]
    blk = np.array([[1.0, 0.0], [0.0, 1.0]])
    top = np.concatenate([h ** 3 / 3 * blk, h ** 2 / 2 * blk], axis=-1)
    bottom = np.concatenate([h ** 2 / 2 * blk, h * blk], axis=-1)
    return q * np.concatenate([top, bottom], axis=-2)


def system_matrix(xi) -> np.ndarray:
    """A(Ξ) (…, 4, 4) for Ξ (…, 2, 2) [1/s]."""
    xi = np.asarray(xi, dtype=np.float64)
    A = np.zeros(xi.shape[:-2] + (4, 4))
    A[..., 0, 2] = A[..., 1, 3] = 1.0
    A[..., 2:, 2:] = xi
    return A


@dataclass
class LinearMotion:
    """A track's motion model: ``xi`` (2, 2) [1/s] the point estimate the filter predicts with, ``members``
    (M, 2, 2) [1/s] the model-uncertainty set, ``label`` ("cv" or the identified terms)."""

    xi: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    members: np.ndarray = field(default_factory=lambda: np.zeros((1, 2, 2)))
    label: str = "cv"
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def is_cv(self) -> bool:
        return not self.members.any() and not self.xi.any()

    def transition(self, h) -> np.ndarray:
        """Φ(h) (…, 4, 4) of the point estimate for h (…) [s], cached per h (the frame interval repeats;
        a copy: the caller may change it)."""
        h = np.asarray(h, dtype=np.float64)
        key = ("point", h.shape, h.tobytes())
        if key not in self._cache:
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = self._phi(self.xi, h)
        return self._cache[key].copy()

    def member_transitions(self, h) -> np.ndarray:
        """Φ_m(h) (M, K, 4, 4) for h (K,) [s], cached per h (horizons and the grid step repeat)."""
        h = np.asarray(h, dtype=np.float64).reshape(-1)
        key = h.tobytes()
        if key not in self._cache:
            self._cache[key] = self._phi(self.members[:, None], h[None, :])
        return self._cache[key]

    def _phi(self, xi, h) -> np.ndarray:
        xi = np.asarray(xi, dtype=np.float64)
        shape = np.broadcast_shapes(xi.shape[:-2], np.shape(h))
        if not xi.any():
            hh = np.broadcast_to(h, shape)[..., None, None]
            out = np.broadcast_to(np.eye(4), shape + (4, 4)).copy()
            out[..., 0, 2] = out[..., 1, 3] = hh[..., 0, 0]
            return out
        A = np.broadcast_to(system_matrix(xi), shape + (4, 4))
        return expm(A * np.broadcast_to(h, shape)[..., None, None])


def forecast(motion: LinearMotion, x, P, horizons, q: float, spread: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Predictive mean (K, 2) [m] and covariance (K, 2, 2) [m²] of the true position, Eq. (1), at
    ``horizons`` (K,) [s] from the state x (4,), P (4, 4); q [m²/s³] the process noise PSD, ``spread``
    the scale s of the members' spread."""
    phi = motion.member_transitions(horizons)[:, :, :2, :]            # (M, K, 2, 4)
    mu = phi @ np.asarray(x, np.float64)                              # (M, K, 2)
    S = phi @ P @ np.swapaxes(phi, -1, -2) + cv_process_noise(horizons, q)[:, :2, :2]
    mean = mu.mean(axis=0)
    d = mu - mean
    cov = S.mean(axis=0) + spread ** 2 * np.einsum("mki,mkj->kij", d, d) / len(mu)
    return mean, cov


def radii(cov) -> tuple[np.ndarray, np.ndarray]:
    """The 50 % and 90 % disc radii (…) [m] of covariances (…, 2, 2) [m²] (one vectorised solve)."""
    cov = np.asarray(cov, dtype=np.float64)
    r = disc_radius(cov[None], np.array([0.5, 0.9]).reshape((2,) + (1,) * (cov.ndim - 2)))
    return r[0], r[1]


def mean_path(motion: LinearMotion, x, step: float, n: int) -> np.ndarray:
    """Mixture-mean positions (n, 2) [m] at h = 0, δ, …, (n−1)δ."""
    phi = motion.member_transitions([step])[:, 0]                     # (M, 4, 4)
    s = np.broadcast_to(np.asarray(x, np.float64), (len(phi), 4)).copy()
    out = np.empty((n, 2))
    for k in range(n):
        out[k] = s[:, :2].mean(axis=0)
        s = np.einsum("mij,mj->mi", phi, s)
    return out


def draw_paths(motion: LinearMotion, x, P, step: float, n: int, q: float, draws: int,
               rng: np.random.Generator) -> np.ndarray:
    """Predictive path draws (D, n, 2) [m] at h = 0, δ, …, (n−1)δ (module docstring)."""
    phi = motion.member_transitions([step])[:, 0]
    member_phi = phi[np.arange(draws) % len(phi)]                     # (D, 4, 4)
    chol_p = np.linalg.cholesky(P + 1e-12 * np.eye(4))
    chol_q = np.linalg.cholesky(cv_process_noise(step, q) + 1e-12 * np.eye(4))
    s = np.asarray(x, np.float64) + rng.standard_normal((draws, 4)) @ chol_p.T
    noise = rng.standard_normal((n, draws, 4)) @ chol_q.T
    out = np.empty((draws, n, 2))
    for k in range(n):
        out[:, k] = s[:, :2]
        s = np.einsum("dij,dj->di", member_phi, s) + noise[k]
    return out
