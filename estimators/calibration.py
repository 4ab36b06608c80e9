"""Calibration of wall posteriors on simulated scenes with known truth.

Scenes (:func:`simulate_wall_scene`) follow the documented measurement model
(:mod:`estimators.likelihood`): a relay wall (line, or arc with |κ| drawn from ``curvature`` —
not from the κ prior) seen over a stretch of length L at 12–35 m; LOS detections at wall points
displaced along the local normal by the wall roughness ρ, then observed with range/azimuth
errors N(0, (s·σ_r)²), N(0, (s·σ_θ)²), where σ_r, σ_θ are the stated ``range_std`` /
``azimuth_std`` and s the factor by which a detector's stated errors are off, log s ~
N(0, ``noise_scale_std``²) per scene (0: the stated errors are exact); a fraction of the LOS
detections are outliers drawn from the likelihood's outlier model — a share ``clutter_share``
is clutter uniform over a depth ``outlier_width`` in front of the wall, the rest uniform over a
band of that width on both sides — and observed alike (``clutter_depth`` overrides the clutter's
depth range, e.g. (0.5, 3) m for clutter hugging the wall, a misspecified case); virtual points
o' 2–12 m behind the wall along rays that cross it, detected with the same errors, and their
true hidden points o = R_θ(o') (:func:`xnlos_core.wall.mirror`).

Coverage: the Mahalanobis distance m² = (o − μ)ᵀ Σ⁻¹ (o − μ) of each true hidden point from its
reconstruction is χ²(2)-distributed under a calibrated Gaussian posterior, so the fraction with
m² ≤ χ²₂(p) = −2 ln(1 − p) should be p. Two versions:

* total: the reconstructed points from the detected o' (detection + wall uncertainty);
* wall-only: the true o' mirrored through the wall posterior alone (isolates the wall's
  calibration when the detection covariance dominates).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.geometry import cartesian_to_polar
from xnlos_core.metrics import chamfer_distance
from xnlos_core.types import LOS, MNLOS, Detections, WallPosterior
from xnlos_core.wall import mirror, nearest_points
from xnlos_core.wall_propagation import propagate

LEVELS = (0.5, 0.9)


def chi2_2_quantile(p: float) -> float:
    """Quantile of χ²(2): −2 ln(1 − p)."""
    return float(-2.0 * np.log1p(-p))


@dataclass(frozen=True)
class SyntheticWallScene:
    """One simulated frame: detections (LOS then mNLOS rows), the true wall (zero covariance),
    virtual points o' (M, 2) [m], hidden points o (M, 2) [m], LOS outlier mask (K_los,)."""

    detections: Detections
    wall: WallPosterior
    virtual: np.ndarray
    hidden: np.ndarray
    outlier: np.ndarray


def wall_point(theta, anchor, s):
    """Points (…, 2) [m] at arc length s (…,) [m] from the tangent point p₀ of the wall θ (line or
    arc, anchored at ``anchor`` (2,)), and their unit normals (…, 2):
    p(s) = p₀ + u·sin(κs)/κ − n·(1 − cos κs)/κ (via sinc, so κ = 0 is the line)."""
    phi, b = theta[0], theta[1]
    kappa = theta[2] if len(theta) > 2 else 0.0
    n = np.array([np.cos(phi), np.sin(phi)])
    u = np.array([-n[1], n[0]])
    p0 = anchor - (n @ anchor + b) * n
    s = np.asarray(s, dtype=np.float64)
    along = s * np.sinc(kappa * s / np.pi)
    across = 0.5 * kappa * s * s * np.sinc(kappa * s / (2 * np.pi)) ** 2
    pts = p0 + along[..., None] * u - across[..., None] * n
    ang = kappa * s
    normals = np.cos(ang)[..., None] * n + np.sin(ang)[..., None] * u
    return pts, normals


def _observe(points, rng, range_std, azimuth_std, label, scale=1.0) -> Detections:
    """Detections of points with errors scale·(range_std, azimuth_std), stating (range_std, azimuth_std)."""
    r, a = cartesian_to_polar(points)
    r = np.abs(r + scale * range_std * rng.standard_normal(len(r)))
    a = np.angle(np.exp(1j * (a + scale * azimuth_std * rng.standard_normal(len(a)))))
    k = len(r)
    return Detections(r, a, np.full(k, label, np.int8), np.ones(k), np.full(k, range_std),
                      np.full(k, azimuth_std))


def simulate_wall_scene(rng: np.random.Generator, model: str = "line", n_los: int = 16, n_hidden: int = 6,
                        outlier_fraction: float = 0.1, range_std: float = 0.07, azimuth_std: float = 0.02,
                        roughness: float = 0.02, distance=(12.0, 35.0), length=(8.0, 16.0),
                        curvature=(0.02, 0.06), outlier_width: float = 4.0, clutter_share: float = 0.8,
                        clutter_depth=None, noise_scale_std: float = 0.0) -> SyntheticWallScene:
    """A random scene of the module doc. distance [m]: range of the wall's tangent point;
    length [m]: seen wall length; curvature [1/m]: |κ| range for model 'arc' (random sign);
    outlier_width [m], clutter_share: the outlier model; noise_scale_std: spread of log s
    (module doc)."""
    if model not in ("line", "arc"):
        raise InputError(f"simulate_wall_scene: model must be 'line' or 'arc', got {model!r}")
    if n_los < 2 or n_hidden < 0:
        raise InputError(f"simulate_wall_scene: need n_los ≥ 2 and n_hidden ≥ 0, got {n_los}, {n_hidden}")
    alpha = rng.uniform(-0.6, 0.6)  # azimuth of the tangent point [rad]
    r0 = rng.uniform(*distance)
    p0 = r0 * np.array([np.cos(alpha), np.sin(alpha)])
    beta = rng.uniform(-0.9, 0.9)  # incidence: angle between n and the direction to the radar
    to_radar = -p0 / r0
    c, s = np.cos(beta), np.sin(beta)
    n = np.array([c * to_radar[0] - s * to_radar[1], s * to_radar[0] + c * to_radar[1]])
    u = np.array([-n[1], n[0]])
    b, anchor = float(-n @ p0), p0
    theta = [float(np.arctan2(n[1], n[0])), b]
    if model == "arc":
        theta.append(float(rng.choice([-1.0, 1.0]) * rng.uniform(*curvature)))
    theta = np.array(theta)
    half = 0.5 * rng.uniform(*length)
    n_out = int(rng.binomial(n_los, outlier_fraction)) if outlier_fraction > 0 else 0
    n_in = max(n_los - n_out, 2)
    s_in = rng.uniform(-half, half, n_in)
    pts, nrm = wall_point(theta, anchor, s_in)
    pts = pts + roughness * rng.standard_normal(n_in)[:, None] * nrm
    s_out = rng.uniform(-half, half, n_out)
    q_out, n_q = wall_point(theta, anchor, s_out)
    front = rng.random(n_out) < clutter_share
    lo, hi = (0.0, outlier_width) if clutter_depth is None else clutter_depth
    depth = np.where(front, rng.uniform(lo, hi, n_out), rng.uniform(-outlier_width / 2, outlier_width / 2, n_out))
    clutter = q_out + depth[:, None] * n_q
    los_pts = np.concatenate([pts, clutter])
    scale = float(np.exp(noise_scale_std * rng.standard_normal())) if noise_scale_std > 0 else 1.0
    los = _observe(los_pts, rng, range_std, azimuth_std, LOS, scale)
    s_h = rng.uniform(-0.8 * half, 0.8 * half, n_hidden)
    q, _ = wall_point(theta, anchor, s_h)
    ray = q / np.linalg.norm(q, axis=1, keepdims=True)
    virtual = q + rng.uniform(2.0, 12.0, n_hidden)[:, None] * ray
    hidden = mirror(model, theta, virtual, anchor)[0].reshape(-1, 2)
    mn = _observe(virtual, rng, range_std, azimuth_std, MNLOS, scale)
    ends, _ = wall_point(theta, anchor, np.array([-half, half]))
    names = ("phi", "b", "kappa")[:len(theta)]
    wall = WallPosterior(model, theta, np.zeros((len(theta), len(theta))), names, n_points=n_in,
                         extent=ends, anchor=anchor)
    outlier = np.concatenate([np.zeros(n_in, bool), np.ones(n_out, bool)])
    return SyntheticWallScene(Detections.concat(los, mn), wall, virtual, hidden, outlier)


def mahalanobis2(truth, mean, cov) -> np.ndarray:
    """m² (M,) of truth (M, 2) from N(mean (M, 2), cov (M, 2, 2)); a singular cov is floored at
    10⁻¹²·its largest eigenvalue (+10⁻²⁴ m²), so a degenerate ellipse counts as a miss, not NaN."""
    d = np.asarray(truth, float) - np.asarray(mean, float)
    c = np.asarray(cov, float)
    vals, vecs = np.linalg.eigh(0.5 * (c + np.swapaxes(c, -1, -2)))
    vals = np.maximum(vals, 1e-12 * vals.max(axis=-1, keepdims=True) + 1e-24)
    z = np.einsum("mji,mj->mi", vecs, d)
    return np.sum(z * z / vals, axis=-1)


def coverage(m2, levels=LEVELS) -> dict[float, float]:
    """Fraction of m² inside each credible level's χ²(2) quantile ({level: fraction}, NaN if empty)."""
    m2 = np.asarray(m2, float)
    return {p: float(np.mean(m2 <= chi2_2_quantile(p))) if len(m2) else float("nan") for p in levels}


def wall_errors(estimate: WallPosterior, truth: WallPosterior) -> tuple[float, float]:
    """(angle error [deg], offset error [m]) of the estimate's local line against the true wall's.

    Both are compared at the data: the estimate's local line is its tangent line at the middle of
    its extent (the tangent point when it has no extent); the true wall's is its tangent line at
    the true wall point nearest that middle (for a true line, the line itself). Offsets are the
    b of those lines (nᵀx + b = 0, n oriented alike).
    """
    if estimate.extent is not None:
        mid = nearest_points(estimate.model, estimate.mean, estimate.extent.mean(axis=0)[None],
                             estimate.anchor).reshape(2)
    else:
        mid = estimate.tangent_point
    n_est = _normal_at(estimate, mid)
    b_est = -float(n_est @ mid)
    q = nearest_points(truth.model, truth.mean, mid[None], truth.anchor).reshape(2)
    n_true = _normal_at(truth, q)
    b_true = -float(n_true @ q)
    if n_est @ n_true < 0:
        n_est, b_est = -n_est, -b_est
    ang = float(np.degrees(np.arccos(np.clip(n_est @ n_true, -1.0, 1.0))))
    return ang, abs(b_est - b_true)


def _normal_at(wall: WallPosterior, q: np.ndarray) -> np.ndarray:
    """Unit normal of a 'line'/'arc' wall at its point q (2,): n + κ(q − p₀), normalised."""
    g = wall.normal + wall.curvature * (q - wall.tangent_point)
    return g / np.linalg.norm(g)


@dataclass
class FrameEval:
    """Per-frame scores: wall angle/offset errors of the wall that anchors most hidden points,
    hidden-point Chamfer distance [m²], m² total and wall-only (one per reconstructed point),
    the estimator's time [s] and the chosen model."""

    angle_deg: float
    offset_m: float
    cd: float
    m2_total: np.ndarray
    m2_wall: np.ndarray
    time_s: float
    model: str


def evaluate(estimator, reconstructor, scene: SyntheticWallScene) -> FrameEval:
    """Run ``estimator`` and ``reconstructor`` on one scene and score them (module doc)."""
    import time

    t0 = time.perf_counter()
    walls = estimator.estimate(scene.detections)
    dt = time.perf_counter() - t0
    hidden = reconstructor.reconstruct(scene.detections, walls)
    mn_rows = scene.detections.of_class(MNLOS)
    row = {int(i): k for k, i in enumerate(mn_rows)}
    k = np.array([row[int(i)] for i in hidden.source_index], dtype=np.int64)
    m2_total = mahalanobis2(scene.hidden[k], hidden.mean, hidden.cov) if len(k) else np.empty(0)
    m2_wall = []
    for j in np.unique(hidden.wall_index):
        sel = k[hidden.wall_index == j]
        mean, cov = propagate(scene.virtual[sel], np.zeros((len(sel), 2, 2)), walls[j])
        m2_wall.append(mahalanobis2(scene.hidden[sel], mean, cov))
    main = walls[int(np.bincount(hidden.wall_index).argmax())] if len(hidden) else walls[0]
    ang, off = wall_errors(main, scene.wall)
    cd = chamfer_distance(hidden.mean, scene.hidden)
    return FrameEval(ang, off, cd, m2_total, np.concatenate(m2_wall) if m2_wall else np.empty(0), dt,
                     main.model)
