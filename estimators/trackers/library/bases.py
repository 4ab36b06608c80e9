"""The library entries' bases: positions p(τ) = B(τ) θ, their velocities and forecast paths.

Times τ = t − t_ref [s] (τ ≤ 0 in the window, t_ref its last sample), positions p(τ) = B(τ) θ with
B (2, P):

* ``cv``: p₀ + v₀τ (P = 4).
* ``line``: p₀ + v₀τ + û βτ²/2 (P = 5): a constant acceleration β [m/s²] along the path's line û (the
  principal axis of the window's positions). It is **braking** when the speed along û falls to zero in
  the future (t* = −(ûᵀv₀)/β > 0: the forecast stops there, the car then stays), **reversing** when it
  went through zero inside the window (t* between the first sample and now: the speed changed sign)
  and the car has since run back farther than twice the residual SD (else it is braking that stopped
  at t*: it stays), **accelerating** otherwise. A reversal is forecast at its present (backward) speed
  (``Entry.coast`` = 0: a reversing car settles at a low reverse speed; the quadratic would have it
  speed up backwards for ever).
* ``turn``: p₀ + R(ω, τ) v₀ (P = 4 + ω): constant speed and turn rate ω [rad/s],
  R = (sin ωτ/ω) I + ((1 − cos ωτ)/ω) J (J the +90° rotation).
* ``turn_accel``: ``turn`` + M(ω, τ) a₀ (P = 6 + ω): an acceleration a₀ [m/s²] that turns with the
  heading, M = ((1 − cos ωτ)/ω²) I + ((ωτ − sin ωτ)/ω²) J — a speed change in a turn.
* ``lane``: p₀ + w û_φ τ + n_φ A σ((τ − τ_c)/s) (P = 4 + τ_c, φ): a **lane change**, driving at w [m/s]
  along the lane û_φ (the principal axis turned by φ) with a lateral offset A [m] across it
  (n_φ = Jû_φ) completed along a logistic σ of centre τ_c [s] and width s = 0.5 s (10–90 % of the offset
  in 2.2 s: the middle of a 4–5 s lane change, chosen on the calibration split): the lateral velocity is
  bounded and dies out, where a turn's heading keeps rotating.
* ``ramp``: p₀ + v₀τ + û β min(τ − τ_k, 0)²/2 (P = 5 + τ_k): a speed change along the line that **ended**
  at τ_k < 0 (a braking, speeding up or reversal that has settled): the forecast goes on at v₀.
* ``kink``: p₀ + v₀τ + d min(τ − τ_k, 0) (P = 6 + τ_k): a velocity that changed by −d [m/s] at τ_k < 0
  (the end of a turn or lane change, as a step): the forecast goes on at v₀, fitted on the window's
  recent part only, where CV over the whole window would follow the old heading.
  ``ramp`` and ``kink`` are reported as ``settled``; τ_k needs ``MIN_BEFORE`` samples before it.

ω, τ_c, φ and τ_k are grid parameters: ``OMEGA_GRID`` (step 0.01 rad/s), ``LANE_CENTRES`` ×
``LANE_ANGLES``, ``KINK_TIMES`` (:func:`hyper_grid`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .entries import KINK_TIMES, LANE_ANGLES, LANE_CENTRES, LANE_SCALES, N_LINEAR, OMEGA_GRID


def _kernels(omega, tau):
    """a = sin(ωτ)/ω, b = (1 − cos ωτ)/ω, c = (1 − cos ωτ)/ω², d = (ωτ − sin ωτ)/ω² (broadcast), with
    their limits at ω → 0 (τ, 0, τ²/2, 0)."""
    x = omega * tau
    a = tau * np.sinc(x / np.pi)
    c = tau * tau / 2 * np.sinc(x / (2 * np.pi)) ** 2
    b = omega * c
    small = np.abs(x) < 1e-2
    with np.errstate(divide="ignore", invalid="ignore"):
        d_direct = (x - np.sin(x)) / (omega * omega)
    d = np.where(small, tau * tau * (x / 6 - x ** 3 / 120), d_direct)
    return a, b, c, d


def _design(model: str, hyper, tau):
    """(ω, τ_c, s, û_x, û_y (…, 1), τ broadcast (…, L), zeros (…, L, 2, P)) of :func:`basis` and
    :func:`velocity_basis` for hyper (…, 5) and tau (…, L) [s]."""
    hyper = np.asarray(hyper, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    om, tc, s, ux, uy = (hyper[..., i, None] for i in range(5))
    shape = np.broadcast_shapes(om.shape, tau.shape)
    return om, tc, s, ux, uy, np.broadcast_to(tau, shape), np.zeros(shape + (2, N_LINEAR[model]))


def basis(model: str, hyper, tau) -> np.ndarray:
    """B (…, L, 2, P) of entry ``model`` at times tau (…, L) [s] for hyper (…, 5) (module docstring)."""
    om, tc, s, ux, uy, t, out = _design(model, hyper, tau)
    out[..., 0, 0] = out[..., 1, 1] = 1.0
    if model in ("cv", "line"):
        out[..., 0, 2] = out[..., 1, 3] = t
    if model == "line":
        out[..., 0, 4], out[..., 1, 4] = ux * t * t / 2, uy * t * t / 2
    if model in ("turn", "turn_accel"):
        a, b, c, d = _kernels(om, t)
        out[..., 0, 2], out[..., 1, 2], out[..., 0, 3], out[..., 1, 3] = a, b, -b, a
        if model == "turn_accel":
            out[..., 0, 4], out[..., 1, 4], out[..., 0, 5], out[..., 1, 5] = c, d, -d, c
    if model == "ramp":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 2] = out[..., 1, 3] = t
        out[..., 0, 4], out[..., 1, 4] = ux * m * m / 2, uy * m * m / 2
    if model == "kink":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 2] = out[..., 1, 3] = t
        out[..., 0, 4] = out[..., 1, 5] = m
    if model == "lane":
        g = 0.5 * (1.0 + np.tanh((t - tc) / (2 * s)))  # the logistic σ((τ − τ_c)/s)
        out[..., 0, 2], out[..., 1, 2] = ux * t, uy * t
        out[..., 0, 3], out[..., 1, 3] = -uy * g, ux * g
    return out


def velocity_basis(model: str, hyper, tau) -> np.ndarray:
    """dB/dτ (…, L, 2, P) [1/s on the p₀ columns: 0] of entry ``model`` at tau (…, L) [s]: the velocity
    dp/dτ = (dB/dτ) θ, the rows of a radial velocity y = ĝᵀ dp/dτ (:mod:`estimators.trackers.library.doppler`). Closed
    forms of the derivatives of :func:`basis` (a′ = cos ωτ, b′ = sin ωτ, c′ = a, d′ = b; the logistic's
    σ(1 − σ)/s; min(τ − τ_k, 0)′ = [τ < τ_k])."""
    om, tc, s, ux, uy, t, out = _design(model, hyper, tau)
    if model in ("cv", "line", "ramp", "kink"):
        out[..., 0, 2] = out[..., 1, 3] = 1.0
    if model == "line":
        out[..., 0, 4], out[..., 1, 4] = ux * t, uy * t
    if model in ("turn", "turn_accel"):
        a, b, _, _ = _kernels(om, t)
        co, si = np.cos(om * t), np.sin(om * t)
        out[..., 0, 2], out[..., 1, 2], out[..., 0, 3], out[..., 1, 3] = co, si, -si, co
        if model == "turn_accel":
            out[..., 0, 4], out[..., 1, 4], out[..., 0, 5], out[..., 1, 5] = a, b, -b, a
    if model == "ramp":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 4], out[..., 1, 4] = ux * m, uy * m
    if model == "kink":
        out[..., 0, 4] = out[..., 1, 5] = (t < tc).astype(np.float64)
    if model == "lane":
        g = 0.5 * (1.0 + np.tanh((t - tc) / (2 * s)))
        dg = g * (1.0 - g) / s
        out[..., 0, 2], out[..., 1, 2] = ux * np.ones_like(t), uy * np.ones_like(t)
        out[..., 0, 3], out[..., 1, 3] = -uy * dg, ux * dg
    return out


def forecast_basis(model: str, hyper, tau, stop, coast) -> np.ndarray:
    """B (…, K, 2, P) of a forecast at tau (…, K) [s]: the entry's basis at min(τ, stop) (a braking entry
    stays at its stop), continued beyond ``coast`` c (a ``line`` entry only) at the speed it has there,
    B(c) + (τ − c) dB/dτ(c) — a reversal is forecast at its present (backward) speed, not accelerating on."""
    tau = np.minimum(np.asarray(tau, dtype=np.float64), stop)
    c = np.minimum(tau, coast)
    B = basis(model, hyper, c)
    extra = tau - c
    if model == "line" and np.any(extra > 0):
        h = np.asarray(hyper, dtype=np.float64)
        B[..., 0, 2] += extra
        B[..., 1, 3] += extra
        B[..., 0, 4] += h[..., 3, None] * c * extra
        B[..., 1, 4] += h[..., 4, None] * c * extra
    return B


def forecast_velocity_basis(model: str, hyper, tau, stop, coast) -> np.ndarray:
    """dB/dτ (…, K, 2, P) of the forecast path of :func:`forecast_basis` at tau (…, K) [s]: 0 past a
    braking entry's stop, the velocity at ``coast`` beyond it."""
    tau = np.asarray(tau, dtype=np.float64)
    D = velocity_basis(model, hyper, np.minimum(np.minimum(tau, stop), coast))
    return D * (tau < stop)[..., None, None]


@lru_cache(maxsize=8)
def hyper_grid(model: str) -> np.ndarray:
    """hyper (G, 5) of entry ``model`` in a track's own frame (û = +x) (read-only: shared)."""
    if model in ("turn", "turn_accel"):
        h = np.zeros((len(OMEGA_GRID), 5))
        h[:, 0] = OMEGA_GRID
    elif model == "lane":
        tc, s, phi = np.meshgrid(LANE_CENTRES, LANE_SCALES, LANE_ANGLES, indexing="ij")
        h = np.zeros((tc.size, 5))
        h[:, 1], h[:, 2], h[:, 3], h[:, 4] = tc.ravel(), s.ravel(), np.cos(phi.ravel()), np.sin(phi.ravel())
        return readonly(h)
    elif model in ("kink", "ramp"):
        h = np.zeros((len(KINK_TIMES), 5))
        h[:, 1] = KINK_TIMES
    else:
        h = np.zeros((1, 5))
    h[:, 3] = 1.0
    return readonly(h)


def readonly(a: np.ndarray) -> np.ndarray:
    """``a`` itself, made read-only: an array cached and shared between calls (:func:`hyper_grid`,
    the Doppler rows' bases) must not be written by a caller."""
    a.flags.writeable = False
    return a
