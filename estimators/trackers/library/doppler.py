"""Doppler rows of the library fit: a track given as (t, z, ĝ, y).

A hidden point's radial velocity y_i = ĝ_iᵀ dp/dτ(τ_i) + noise (ĝ_i the unit mirrored line of sight;
NaN: none) is linear in θ for every entry, through the derivative of its basis
(:func:`estimators.trackers.library.bases.velocity_basis`): the rows λ(ĝ_iᵀ Ḃ(τ_i)θ − y_i) are stacked
under the position rows (at least ``MIN_RADIAL`` of them), and every grid value of every entry is
refitted with them at once. The weight λ = σ_p/σ_r [s] is :mod:`estimators.trackers.sindy_model`'s:
first σ_p of the best position-only fit over σ_r of the radial velocities' successive differences
(robust), then, refitted, the residual RMS of each kind of the best joint fit; σ_r is floored at the
caller's ``radial_floor`` (the tracker's ``doppler_floor``, the least radial SD its filter assumes). A
track's velocity then comes from measured radial velocities where the positions give it only through
differences of a wandering centroid (a braking's deceleration shows in the radial velocities' ramp).
The selection weighs the radial terms by ``radial_share`` (``RADIAL_SHARES``): Eq. (2) of
:mod:`estimators.trackers.library.selection`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from xnlos_core.errors import InputError

from .bases import hyper_grid, readonly, velocity_basis
from .entries import LIBRARY, N_LINEAR, OMEGA_GRID
from .fit import FULL, pick, shared_designs


RADIAL_SHARES = ("ar1", "full")
MIN_RADIAL = 3  # radial velocities a track needs for its Doppler rows (a robust σ_r from their differences)


def radial_rows(i: int, track, n: int, rot: np.ndarray, floor: float):
    """(idx (m,), ĝ (m, 2) in the track's own frame, y (m,) [m/s], σ_r [m/s]) of track ``i``'s Doppler
    samples, or None with fewer than MIN_RADIAL; σ_r the robust SD of successive differences of y
    (:func:`estimators.trackers.sindy_model.radial_sigma`), at least ``floor``."""
    from ..sindy_model import radial_sigma

    g, y = np.asarray(track[2], np.float64), np.asarray(track[3], np.float64)
    if g.shape != (n, 2) or y.shape != (n,):
        raise InputError(f"identify_batch: track {i}: ĝ must be (n, 2) and y (n,) with n = {n}")
    ok = np.flatnonzero(np.isfinite(y))
    norm = np.linalg.norm(g[ok], axis=1)
    if not np.all(np.isfinite(norm)) or np.any(norm == 0):
        raise InputError(f"identify_batch: track {i}: each sample with a radial velocity needs a finite, "
                         "nonzero direction ĝ (2,)")
    if len(ok) < MIN_RADIAL:
        return None
    sigma_r = max(radial_sigma(y), floor)
    return ok.astype(np.int64), (g[ok] / norm[:, None]) @ rot, y[ok], sigma_r, floor


@lru_cache(maxsize=32)
def _radial_basis(tau_key: bytes, idx_key: bytes) -> dict:
    """Per full entry dB/dτ (G, m, 2, P) at the samples ``idx`` of the sample-time pattern τ (keys: their
    bytes), and XᵀX (G, P, P) of its position design: shared by the tracks of that pattern (read-only)."""
    tau = np.frombuffer(tau_key, dtype=np.float64)
    idx = np.frombuffer(idx_key, dtype=np.int64)
    shared = shared_designs(tau_key)
    out = {}
    for full, _ in FULL:
        X = shared[full][0]
        out[full] = (readonly(velocity_basis(full, hyper_grid(full), tau[idx][None, :])),
                     readonly(np.swapaxes(X, -1, -2) @ X))
    return out


def fit_doppler(fits: dict, radial: dict, rows: np.ndarray, tau: np.ndarray, z: np.ndarray, samples: list,
                 k: np.ndarray) -> None:
    """Refit the tracks ``rows`` of a group (local positions z (T', L, 2); their Doppler samples
    ``samples``, all at the same sample indices) with their radial rows λ(ĝᵀ Ḃ(τ) θ − y) stacked under
    the position rows, over every grid value and track at once; their entries in ``fits`` and ``radial``
    (RSS_r, m, λ, the radial residuals) are replaced. λ = σ_p/σ_r [s] (module docstring) as in
    :mod:`estimators.trackers.sindy_model`: first σ_p of the best position-only fit and σ_r of the radial
    velocities' successive differences; then, refitted, the residual RMS of each kind of the best joint
    fit (σ_r at least the floor)."""
    idx = samples[0][0]
    g = np.array([r[1] for r in samples])                              # (T', m, 2)
    y = np.array([r[2] for r in samples])                              # (T', m)
    sigma_r = np.array([r[3] for r in samples])
    floor = samples[0][4]
    Tn, L = z.shape[:2]
    N, n_r = 2 * L, len(idx)
    ar = np.arange(Tn)
    zf = z.reshape(Tn, -1)
    zz, yy = np.sum(zf * zf, axis=1), np.sum(y * y, axis=1)
    rss_pos = np.stack([fits[m][2][rows] for m in LIBRARY], axis=1)   # (T', M+1)
    j = np.argmin(rss_pos, axis=1)
    tiny = 1e-18 * np.maximum(zz, 1e-6) / N
    lam = np.sqrt(np.maximum(rss_pos[ar, j] / np.maximum(N - k[j], 1.0), tiny)) / sigma_r
    shared = shared_designs(np.ascontiguousarray(tau).tobytes())
    basis_r = _radial_basis(np.ascontiguousarray(tau).tobytes(), np.ascontiguousarray(idx, np.int64).tobytes())
    parts = {}
    for full, _ in FULL:
        X, _, valid, flat = shared[full]
        Vb, XtX = basis_r[full]
        G, K, P = X.shape
        D = np.einsum("tmc,gmcp->tgmp", g, Vb, optimize=True)          # (T', G, m, P): ĝᵀ dB/dτ
        parts[full] = (X, valid, XtX, (zf @ flat).reshape(Tn, G, P), D, np.einsum("tgmp,tgmq->tgpq", D, D, optimize=True),
                       np.einsum("tgmp,tm->tgp", D, y, optimize=True))
    for first in (True, False):
        used, out = lam, {}
        l2 = (lam * lam)[:, None, None]
        for full, models in FULL:
            X, valid, XtX, Xz, D, DtD, Dy = parts[full]
            for m in models:
                c = N_LINEAR[m]
                A = XtX[None, :, :c, :c] + l2[..., None] * DtD[..., :c, :c]   # (T', G, c, c)
                bz, by = Xz[..., :c], Dy[..., :c]
                scale = np.sqrt(np.einsum("...ii->...i", A))
                scale = np.where(scale > 0, scale, 1.0)
                An = A / scale[..., :, None] / scale[..., None, :] + 1e-12 * np.eye(c)
                theta = np.linalg.solve(An, ((bz + l2 * by) / scale)[..., None])[..., 0] / scale
                rss_p = zz[:, None] - 2 * np.einsum("tgp,tgp->tg", theta, bz) + np.einsum(
                    "tgp,gpq,tgq->tg", theta, XtX[:, :c, :c], theta, optimize=True)
                rss_r = yy[:, None] - 2 * np.einsum("tgp,tgp->tg", theta, by) + np.einsum(
                    "tgp,tgpq,tgq->tg", theta, DtD[..., :c, :c], theta, optimize=True)
                rss_p = np.where(valid, np.maximum(rss_p, 0.0), zz[:, None])  # an invalid grid value fits nothing
                rss_r = np.where(valid, np.maximum(rss_r, 0.0), yy[:, None])
                order = (np.argsort(np.abs(OMEGA_GRID), kind="stable") if m in ("turn", "turn_accel")
                         else np.arange(len(valid)))
                gi = pick(rss_p + (lam * lam)[:, None] * rss_r, order)
                th = theta[ar, gi]
                rp = zf - np.einsum("tkp,tp->tk", X[gi][:, :, :c], th)
                rr = y - np.einsum("tmp,tp->tm", D[ar, gi][..., :c], th)
                sc = scale[ar, gi]                                     # (BᵀB + λ²DᵀD)⁻¹ at the chosen values only
                inv = np.linalg.inv(An[ar, gi]) / sc[:, :, None] / sc[:, None, :]
                out[m] = (gi, th, np.sum(rp * rp, axis=1), inv, rp, np.sum(rr * rr, axis=1), rr)
        if first:                                                      # λ from the best joint fit's residuals
            obj = np.stack([out[m][2] + lam * lam * out[m][5] for m in LIBRARY], axis=1)
            best = np.argmin(obj, axis=1)
            rp_best = np.stack([out[m][2] for m in LIBRARY], axis=1)[ar, best]
            rr_best = np.stack([out[m][5] for m in LIBRARY], axis=1)[ar, best]
            lam = np.sqrt(np.maximum(rp_best / N, tiny)) / np.maximum(np.sqrt(rr_best / n_r), floor)
    for m in LIBRARY:
        gi, th, rss_p, inv, rp, rss_r, rr = out[m]
        fits[m][0][rows], fits[m][1][rows], fits[m][2][rows], fits[m][3][rows], fits[m][4][rows] = gi, th, rss_p, inv, rp
        radial["rss"][rows, LIBRARY.index(m)] = rss_r
        for r, row in enumerate(rows):
            radial.setdefault("all", {})[(int(row), m)] = rr[r]
    radial["m"][rows], radial["lam"][rows] = n_r, used
    for row in rows:
        radial["resid"][int(row)] = idx
