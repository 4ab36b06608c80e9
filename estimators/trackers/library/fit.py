"""The batched least squares: every library entry at every grid value fitted to many tracks at once.

Every library entry is linear in its parameters θ once a few shape parameters are fixed on a grid,
so one batched least-squares solve per entry (numpy einsum + ``numpy.linalg.solve`` over all tracks
and grid values at once) identifies every due track of a frame: tracks sampled at the same relative
times share their designs and normal matrices (:func:`shared_designs`), and one matrix product per
entry fits them all (:func:`fit_group`). Nested entries (``cv`` in ``line``, ``turn`` in
``turn_accel``) are fitted on the first columns of their full entry's design (``FULL``).

Hand-written on numpy rather than with pysindy: pysindy fits one system at a time (an sklearn estimator
per fit, 6–17 ms a track with the ensemble's refits, ``benchmarks/tracking_speed.md``), where the batched
normal equations here fit every track of a frame in one matrix product per entry; with a library this
small every support is a candidate, so no sparse-regression path is needed to propose them.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .bases import basis, hyper_grid
from .entries import MIN_BEFORE, N_LINEAR, OMEGA_GRID


# (full entry, the entries fitted on the first columns of its design)
FULL = (("line", ("cv", "line")), ("turn_accel", ("turn", "turn_accel")), ("lane", ("lane",)), ("ramp", ("ramp",)),
        ("kink", ("kink",)))


@lru_cache(maxsize=32)
def shared_designs(key: bytes):
    """Per sample-time pattern τ (L,) (``key``: its bytes): for each full entry its design X (G, 2L, P) and
    for each nested entry (BᵀB)⁻¹ (G, P', P') of its first P' columns. Tracks sampled at the same
    relative times (every frame seen, the common case) share them, and successive frames repeat them.
    Also per full entry the grid values it may take (G,): a ``ramp`` or ``kink`` needs ``MIN_BEFORE``
    samples before its τ_k (else its extra columns vanish or fit a sample or two)."""
    tau = np.frombuffer(key, dtype=np.float64)
    out = {}
    for full, models in FULL:
        grid = hyper_grid(full)
        valid = np.ones(len(grid), bool)
        if full in ("ramp", "kink"):
            valid = np.sum(tau[None, :] < grid[:, 1, None] - 1e-9, axis=1) >= MIN_BEFORE
        X = basis(full, grid, tau[None, :])                          # (G, L, 2, P)
        X = X.reshape(X.shape[0], 2 * len(tau), -1)
        A = np.swapaxes(X, -1, -2) @ X
        invs = {}
        for m in models:
            c = N_LINEAR[m]
            scale = np.sqrt(np.einsum("...ii->...i", A[:, :c, :c]))
            scale = np.where(scale > 0, scale, 1.0)                  # a vanishing column (an invalid grid value)
            An = A[:, :c, :c] / scale[:, :, None] / scale[:, None, :] + 1e-12 * np.eye(c)
            invs[m] = np.linalg.inv(An) / scale[:, :, None] / scale[:, None, :]
        G, K, P = X.shape
        flat = np.ascontiguousarray(X.transpose(1, 0, 2).reshape(K, G * P))  # (2L, G·P): one BLAS product fits all
        out[full] = (X, invs, valid, flat)
    return out


def pick(rss: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Per track (T,) the grid index of least RSS (T, G), ties within a relative 1e-9 to the earliest in
    ``order`` (the grid values by preference): the choice never follows a last-bit difference."""
    r = rss[:, order]
    best = r.min(axis=1, keepdims=True)
    tied = r <= best + 1e-9 * np.abs(best) + 1e-300
    return order[np.argmax(tied, axis=1)]


def fit_group(tau: np.ndarray, z: np.ndarray) -> dict:
    """Every entry of the library fitted to tracks sampled at the same τ (L,), local positions z (T, L, 2):
    {model: (grid index (T,), θ (T, P), RSS (T,), (BᵀB)⁻¹ (T, P, P), residuals (T, 2L))}."""
    shared = shared_designs(np.ascontiguousarray(tau).tobytes())
    T = len(z)
    zf = z.reshape(T, -1)
    zz = np.sum(zf * zf, axis=1)
    idx = np.arange(T)
    out = {}
    for full, models in FULL:
        X, invs, valid, flat = shared[full]
        G, K, P = X.shape
        b = (zf @ flat).reshape(T, G, P)                                       # one BLAS product: BᵀWz
        for m in models:
            c = N_LINEAR[m]
            bc = np.ascontiguousarray(b[..., :c].transpose(1, 2, 0))          # (G, c, T)
            theta = (invs[m] @ bc).transpose(2, 0, 1)                         # (T, G, c)
            rss = np.maximum(zz[:, None] - np.einsum("tgp,tgp->tg", theta, b[..., :c]), 0.0)
            rss = np.where(valid, rss, zz[:, None])                           # an invalid grid value fits nothing
            order = (np.argsort(np.abs(OMEGA_GRID), kind="stable") if m in ("turn", "turn_accel")
                     else np.arange(rss.shape[1]))
            g = pick(rss, order)
            th = theta[idx, g]
            resid = zf - np.einsum("tkp,tp->tk", X[g][:, :, :c], th)     # (T, 2L) at the chosen grid values
            out[m] = (g, th, rss[idx, g], invs[m][g], resid)
    return out
