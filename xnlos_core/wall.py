"""Relay-wall geometry seen from above — models of increasing order, signed distance, ray hits,
Eq. 7 across them, the canonical sign — shared by the wall estimators and the reconstructors.

Every model shares the tangent line nᵀx + b = 0, n = (cos φ, sin φ), u = (−sin φ, cos φ), and a
tangent point p₀ = a − (nᵀa + b)·n, the projection onto that line of a fixed anchor point a (2,)
[m] (chosen before a fit: the centroid of the cluster, so the parameters describe the wall where
it was seen, and p₀ stays next to the data whatever φ). With v = x − p₀, d_n = nᵀv = nᵀx + b and
d_t = uᵀv = uᵀ(x − a):

* ``line`` (φ, b): signed distance δ = d_n (positive on the radar side).
* ``arc`` (φ, b, κ): circle of signed curvature κ [1/m] through p₀, centre p₀ − n/κ (κ > 0 bulges
  towards the radar). Karimäki's form of the signed distance is smooth through κ = 0:

      A = 2 d_n + κ(d_n² + d_t²),   g = n + κ v,   |g|² = 1 + κA,   δ = A / (1 + |g|),

  and g/|g| is the unit normal at the point of the circle nearest x (for a line, n).

The functions take an ``ops`` namespace (:data:`NP` for numpy, vectorised over a leading batch
of parameter vectors; :func:`estimators.likelihood.casadi_ops` for symbolic casadi expressions) so
the likelihood used by the MAP (casadi) and by the sampler (numpy) is one definition.

Canonical sign: n and −n describe the same wall; flipping n maps φ → φ + π, b → −b, κ → −κ
(p₀ and the anchor stay). Walls are kept with b ≥ 0, the radar on the positive side
(:func:`canonical`, :class:`xnlos_core.types.WallPosterior`).

Mirror across an arc (:func:`mirror`): the ray radar → o' meets the arc at q (a root t > 0 of the
quadratic A(t·o') = 0; of two, the hit nearer p₀ — the wall is only modelled where it was seen);
o' is reflected across the tangent at q,
o = o' − 2 n_qᵀ(o' − q) n_q (Eq. 7 with the local wall n_q, b_q = −n_qᵀq). For a line this is
exactly Eq. 7. A ray that misses the circle falls back to the tangent line (φ, b) at p₀.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from scipy import special

from .errors import InputError

MODEL_PARAMS = {"line": ("phi", "b"), "arc": ("phi", "b", "kappa")}
MODEL_ORDER = ("line", "arc")  # increasing complexity


def _np_sum(x):
    return np.sum(x, axis=-1)


NP = SimpleNamespace(cos=np.cos, sin=np.sin, sqrt=np.sqrt, log=np.log, exp=np.exp,
                     logaddexp=np.logaddexp, sum=_np_sum, ndtr=special.ndtr)


def check_model(model: str) -> tuple[str, ...]:
    """Parameter names of ``model``; InputError for an unknown model."""
    if model not in MODEL_PARAMS:
        raise InputError(f"wall model: expected one of {sorted(MODEL_PARAMS)}, got {model!r}")
    return MODEL_PARAMS[model]


@dataclass(frozen=True)
class LocalGeometry:
    """Per-point geometry of a wall model: signed distance δ [m] and unit normal (gx, gy)."""

    delta: object
    gx: object
    gy: object


def anchor_xy(anchor) -> np.ndarray:
    """The anchor point a (2,) [m]; the radar (origin) for None."""
    return np.zeros(2) if anchor is None else np.asarray(anchor, dtype=np.float64).reshape(2)


def local_geometry(model: str, phi, b, kappa, x, y, anchor, ops=NP) -> LocalGeometry:
    """δ(x) and the unit normal at the nearest wall point (module doc), element-wise.

    numpy: phi, b, kappa broadcastable (e.g. (W, 1)), x, y (N,) [m] → (W, N) arrays.
    casadi: scalars phi, b, kappa and column vectors x, y (N, 1). anchor: a pair (a_x, a_y) [m]
    (numbers or casadi scalars). ``kappa`` and ``anchor`` are ignored for a line.
    """
    c, s = ops.cos(phi), ops.sin(phi)
    dn = c * x + s * y + b
    if model == "line":
        return LocalGeometry(dn, c + 0 * dn, s + 0 * dn)
    dt = -s * (x - anchor[0]) + c * (y - anchor[1])
    a = 2 * dn + kappa * (dn * dn + dt * dt)
    gn, gt = 1 + kappa * dn, kappa * dt  # g = n + κv in the (n, u) basis
    g = ops.sqrt(gn * gn + gt * gt)
    delta = a / (1 + g)
    return LocalGeometry(delta, (gn * c - gt * s) / g, (gn * s + gt * c) / g)


def split_theta(model: str, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(φ, b, κ) columns (…, 1) of a parameter batch (…, P); κ = 0 for a line."""
    t = np.asarray(theta, dtype=np.float64)
    kappa = t[..., 2:3] if model == "arc" else np.zeros_like(t[..., :1])
    return t[..., 0:1], t[..., 1:2], kappa


def signed_distance(model: str, theta, points, anchor=None) -> np.ndarray:
    """δ (…, N) [m] of points (N, 2) to walls θ (…, P) (positive on the radar side)."""
    phi, b, kappa = split_theta(model, theta)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return local_geometry(model, phi, b, kappa, p[:, 0], p[:, 1], anchor_xy(anchor)).delta


def nearest_points(model: str, theta, points, anchor=None) -> np.ndarray:
    """Points (…, N, 2) of the wall θ (…, P) nearest to points (N, 2): x − δ·n(x)."""
    phi, b, kappa = split_theta(model, theta)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    g = local_geometry(model, phi, b, kappa, p[:, 0], p[:, 1], anchor_xy(anchor))
    return p - np.stack([g.delta * g.gx, g.delta * g.gy], axis=-1)


def ray_hits(model: str, theta, points, anchor=None) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays radar → points meet the wall θ.

    theta (…, P) (batch broadcast against the points), points (N, 2) [m]. Returns (t (…, N), the
    ray parameter: hit at q = t·point, so 0 < t < 1 means the wall lies between the radar and the
    point; n_q (…, N, 2), the unit wall normal at q). NaN where the ray misses the wall (parallel
    to a line, outside a circle, or only behind the radar). Of two hits on a circle the one
    nearest the tangent point p₀ is returned.
    """
    phi, b, kappa = split_theta(model, theta)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    a = anchor_xy(anchor)
    c, s = np.cos(phi), np.sin(phi)
    s0 = -s * a[0] + c * a[1]  # p₀ = −b·n + s₀·u
    a1 = c * p[:, 0] + s * p[:, 1]  # nᵀo'
    a2 = -s * p[:, 0] + c * p[:, 1]  # uᵀo'
    # A(t) = α t² + β t + γ with the ray x = t·o' (t = 1 at o').
    alpha = kappa * (a1 * a1 + a2 * a2)
    beta = 2 * a1 + 2 * kappa * (a1 * b - a2 * s0)
    gamma = 2 * b + kappa * (b * b + s0 * s0)
    gamma = gamma + 0 * beta
    disc = beta * beta - 4 * alpha * gamma
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        qq = -0.5 * (beta + np.where(beta >= 0, 1.0, -1.0) * root)  # stable roots: qq/α and γ/qq
        roots = np.stack([gamma / qq, qq / alpha])
    roots = np.where((disc >= 0) & np.isfinite(roots) & (roots > 0), roots, np.nan)
    # A circle can meet the ray twice: keep the hit nearest the tangent point p₀ (the wall is
    # only modelled where it was seen).
    p0 = -b[..., None] * np.stack([c, s], -1) + s0[..., None] * np.stack([-s, c], -1)  # (…, 1, 2)
    dist = np.linalg.norm(roots[..., None] * p - p0, axis=-1)
    pick = np.argmin(np.where(np.isnan(dist), np.inf, dist), axis=0)
    t = np.take_along_axis(roots, pick[None], axis=0)[0]
    q = t[..., None] * p
    v = q + b[..., None] * np.stack([c, s], -1) - s0[..., None] * np.stack([-s, c], -1)  # q − p₀
    gx = c + kappa * v[..., 0]
    gy = s + kappa * v[..., 1]
    norm = np.hypot(gx, gy)
    with np.errstate(invalid="ignore", divide="ignore"):
        nq = np.stack([gx / norm, gy / norm], axis=-1)
    return t, nq


def mirror(model: str, theta, points, anchor=None) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 7 across the wall θ (…, P) for points o' (N, 2) [m] (module doc).

    Returns (o (…, N, 2) [m], hit (…, N) bool: False where the ray missed an arc and the tangent
    line at p₀ was used instead). For a line this is o' − 2(nᵀo' + b)n exactly.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    phi, b, _ = split_theta(model, theta)
    n_line = np.stack([np.cos(phi), np.sin(phi)], -1)  # (…, 1, 2)
    if model == "line":
        d = np.sum(p * n_line, -1) + b
        return p - 2 * d[..., None] * n_line, np.ones(d.shape, dtype=bool)
    t, nq = ray_hits(model, theta, p, anchor)
    hit = np.isfinite(t) & np.all(np.isfinite(nq), axis=-1)
    q = np.where(hit[..., None], t[..., None] * p, 0.0)
    nq = np.where(hit[..., None], nq, n_line)
    bq = np.where(hit, -np.sum(nq * q, -1), np.broadcast_to(b, t.shape))
    d = np.sum(p * nq, -1) + bq
    return p - 2 * d[..., None] * nq, hit


def flip_normal(theta, cov=None, samples=None):
    """The same wall written with the opposite normal: φ → φ + π, b → −b, κ → −κ.

    theta (P,) = (φ, b[, κ]); cov (P, P) or None (rows and columns of b, κ change sign, so the
    variances stay); samples (S, P) or None, flipped alike. Returns (theta, cov, samples), new arrays.
    """
    theta = np.asarray(theta, dtype=np.float64)
    sign = np.ones(theta.shape[-1])
    sign[1:] = -1.0
    theta = theta * sign
    theta[0] += np.pi
    if cov is not None:
        cov = cov * np.outer(sign, sign)
    if samples is not None:
        samples = samples * sign
        samples[:, 0] += np.pi
    return theta, cov, samples


def canonical(theta, cov=None, samples=None):
    """(θ, cov, samples) with b ≥ 0 (:func:`flip_normal` when b < 0), φ wrapped into (−π, π] and the
    samples' φ unwrapped next to the mean's. theta (P,), cov (P, P) or None, samples (S, P) or None."""
    theta = np.array(theta, dtype=np.float64)
    if theta[1] < 0:
        theta, cov, samples = flip_normal(theta, cov, samples)
    wrapped = float(np.angle(np.exp(1j * theta[0])))
    if samples is not None:
        samples = samples.copy()
        samples[:, 0] = wrapped + np.angle(np.exp(1j * (samples[:, 0] - theta[0])))
    theta[0] = wrapped
    return theta, cov, samples
