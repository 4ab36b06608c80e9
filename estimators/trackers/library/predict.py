"""Forecast of a library fit (:func:`predict`, :func:`predict_many` for many tracks at once).

The selected entry's B(τ)θ with covariance B Σ_θ Bᵀ, Σ_θ = σ² (BᵀB)⁻¹ / f (σ² = RSS/(N − k)), plus the
model-selection uncertainty Σ_j w_j (μ_j − μ)(μ_j − μ)ᵀ over the entries with BIC weights
w_j ∝ exp(−BIC_j/2) (Schwarz weights; Burnham & Anderson 2002, §6.4; entries below ``MIN_WEIGHT`` leave
the mixture). A braking entry's τ is cut at its stop; a reversal's goes on at its present speed
(:func:`estimators.trackers.library.bases.forecast_basis`).

Anchored (``predict_many``'s ``anchor``: a filter's position p and velocity v at the forecast's origin
τ₀): each entry's path keeps its shape about its own tangent at τ₀ and starts from (p, v), Eq. (3) of
:func:`predict_many` — the CV entry then forecasts exactly p + v h. A tracker whose filter measures the
velocity directly (Doppler) starts the forecast from its state, where the window fit's level and slope
carry the wander of a reconstructed car's points; and so does a fit whose window's own present velocity
is biased (:attr:`~estimators.trackers.library.entries.LibraryFit.local_origin`): a lane change —
anchored, its forecast is the filter's line bent by the rest of the fitted offset,
A n_φ (σ(τ₀ + h) − σ(τ₀) − σ′(τ₀) h): the filter's lateral velocity dies out as the lane change's does,
where a CV forecast would carry it on for the whole horizon — and a CV selection with a manoeuvre clearly
better by BIC (CV weight < ``CV_BENT``), whose window velocity averages a bend.
"""
from __future__ import annotations

import numpy as np

from .bases import basis, forecast_basis, forecast_velocity_basis, velocity_basis
from .entries import MIN_WEIGHT, LibraryFit


def predict(fit: LibraryFit, tau) -> tuple[np.ndarray, np.ndarray]:
    """Mean (K, 2) [m] and covariance (K, 2, 2) [m²] of the position at tau (K,) ≥ 0 [s] after
    ``fit.t_ref``: the selected entry's, plus the entries' BIC-weighted spread about it (module
    docstring, forecast). No process noise here: the caller adds its own. :func:`predict_many` of one fit."""
    mean, cov = predict_many([fit], np.asarray(tau, dtype=np.float64).reshape(1, -1))
    return mean[0], cov[0]


def _spread_weight(w: float) -> float:
    """An entry's weight in the mixture spread: 0 below MIN_WEIGHT (module docstring)."""
    return w if w >= MIN_WEIGHT else 0.0


def predict_many(fits, tau, anchor=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`predict` of many fits at once: means (T, K, 2) [m], covariances (T, K, 2, 2) [m²] at tau (T, K)
    ≥ 0 [s] after each fit's ``t_ref`` — one basis evaluation per library entry over all tracks.

    ``anchor`` (p (T, 2) [m], v (T, 2) [m/s], τ₀ (T,) [s]): each track's filtered position and velocity
    at τ₀ after ``t_ref`` (the forecast's origin, tau[:, k] = τ₀ + h_k). Each entry's path S(τ) then
    keeps its shape about its own tangent at τ₀ and takes the filter's position and velocity there
    (module docstring, anchored):

        μ(τ₀ + h) = p + v h + S(τ₀ + h) − S(τ₀) − S′(τ₀) h                                       (3)

    — the CV entry forecasts exactly p + v h. An entry that brakes to a standstill (``line`` with a stop,
    β along û; ``turn_accel`` whose a₀ has a part β < 0 along v₀) reaches it when the filter's speed runs
    out, and stays there (Eq. 3 would carry on at the difference of the two velocities past the fit's
    stop, and a braking turn's basis would reverse):

        μ(τ₀ + h) = μ₃(τ₀ + h_e),  h_e = min(h, t*),  t* = max(−ûᵀv/β, 0) (line), |v|/|β| (turn)    (4)

    with μ₃ Eq. (3) on the entry's basis without its own stop (for ``line``: p + v h_e + û β h_e²/2). A
    track whose p is not finite keeps its fit's own path. The covariance stays the fit's."""
    tau = np.asarray(tau, dtype=np.float64)
    T, K = tau.shape
    mean, cov = np.zeros((T, K, 2)), np.zeros((T, K, 2, 2))
    if T == 0:
        return mean, cov
    buckets = {}
    for i, f in enumerate(fits):
        for j, e in enumerate(f.entries):
            buckets.setdefault(e.model, []).append((i, j, e))
    others = []                                                        # (track, weight, mean (K, 2))
    for m, sel in buckets.items():
        idx = np.array([i for i, _, _ in sel])
        hyper = np.array([e.hyper for *_, e in sel])
        stop = np.array([e.stop for *_, e in sel])
        coast = np.array([e.coast for *_, e in sel])
        B = forecast_basis(m, hyper, tau[idx], stop[:, None], coast[:, None])  # (E, K, 2, P)
        theta = np.array([e.theta for *_, e in sel])
        mu = np.einsum("ekcp,ep->ekc", B, theta)
        if anchor is not None:                                         # Eq. (3)
            p, v, t0 = (np.asarray(a, np.float64)[idx] for a in anchor)
            h = tau[idx] - t0[:, None]                                 # (E, K)
            B0 = forecast_basis(m, hyper, t0[:, None], stop[:, None], coast[:, None])[:, 0]  # (E, 2, P)
            D0 = forecast_velocity_basis(m, hyper, t0[:, None], stop[:, None], coast[:, None])[:, 0]
            s0, v0 = np.einsum("ecp,ep->ec", B0, theta), np.einsum("ecp,ep->ec", D0, theta)
            shift = (p - s0)[:, None, :] + (v - v0)[:, None, :] * h[..., None]
            mu = mu + np.where(np.isfinite(shift), shift, 0.0)
            if m in ("line", "turn_accel"):                            # braking: Eq. (4), its stop from v
                with np.errstate(divide="ignore", invalid="ignore"):
                    if m == "line":
                        u, beta = hyper[:, 3:5], theta[:, 4]
                        brakes = np.isfinite(stop)
                        t_star = np.maximum(-np.sum(u * v, axis=1) / beta, 0.0)
                    else:                                              # the tangential part of a₀ along v₀
                        beta = np.sum(theta[:, 4:6] * theta[:, 2:4], axis=1) / np.linalg.norm(theta[:, 2:4], axis=1)
                        brakes = beta < 0
                        t_star = np.linalg.norm(v, axis=1) / -beta
                brakes &= np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(v), axis=1)
                if brakes.any():
                    he = np.minimum(h, np.where(brakes, t_star, 0.0)[:, None])
                    Bu = basis(m, hyper, t0[:, None] + he)             # (E, K, 2, P), without the fit's own stop
                    B0u, D0u = basis(m, hyper, t0[:, None])[:, 0], velocity_basis(m, hyper, t0[:, None])[:, 0]
                    bend = (np.einsum("ekcp,ep->ekc", Bu, theta) - np.einsum("ecp,ep->ec", B0u, theta)[:, None]
                            - np.einsum("ecp,ep->ec", D0u, theta)[:, None] * he[..., None])
                    own = p[:, None, :] + v[:, None, :] * he[..., None] + bend
                    mu = np.where(brakes[:, None, None], own, mu)
        first = np.array([j == 0 for _, j, _ in sel])
        if first.any():
            covs = np.array([e.cov for (_, j, e) in sel if j == 0])
            Bf = B[first]
            cov[idx[first]] = np.einsum("ekip,epq,ekjq->ekij", Bf, covs, Bf)
            mean[idx[first]] = mu[first]
        others += [(i, _spread_weight(e.weight), mu[r]) for r, (i, j, e) in enumerate(sel) if j > 0]
    if others:                                                         # the selected entries' spread, Σ w d dᵀ
        i = np.array([o[0] for o in others])
        d = np.array([o[2] for o in others]) - mean[i]                 # (O, K, 2)
        w = np.array([o[1] for o in others])
        np.add.at(cov, i, w[:, None, None, None] * d[..., :, None] * d[..., None, :])
    return mean, cov
