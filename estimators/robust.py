"""Shared machinery of the probabilistic wall estimators (casadi_map, emcee).

Per frame: the LOS detections are split into walls exactly as ``lsq`` does
(:func:`estimators.lsq.los_clusters`: single linkage, collinear pieces merged). Per wall:

1. warm start: the TLS line of ``lsq`` and, with ≥ 3 points, the best line through a pair of
   points under the robust likelihood (all pairs up to 1000, else a seeded random subset) —
   a TLS fit dragged by outliers can sit in the wrong basin of the mixture likelihood;
2. robust MAP of each wall model (line, arc) with casadi/IPOPT and its Laplace Gaussian
   (:mod:`estimators.map_solver`); the arc starts from the line's MAP at κ = 0, anchored at the
   cluster centroid; each model is then restarted once from the other's optimum (the mixture
   posterior can have several modes — e.g. outliers explained by a larger noise scale — and
   the models must be compared at their best modes);
3. model selection (:mod:`estimators.selection`).

Parameters and measurement model: :mod:`estimators.likelihood`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from xnlos_core.errors import InsufficientDataError
from xnlos_core.types import Detections, WallPosterior
from xnlos_core.wall import MODEL_PARAMS, canonical, nearest_points

from .likelihood import LikelihoodConfig, WallLikelihood, param_names
from .lsq import ClusterParams, fit_line, los_clusters
from .map_solver import MapFit, solve_map
from .selection import select_model

MAX_PAIRS = 1000
# LOS points of one wall fitted at most (RobustWallParams.max_fit_points): casadi builds its problem per
# padded size (symbolic rows) and the samplers evaluate every point for every draw — a 20,000-point wall
# took 4.7 GB (casadi_map, emcee) and over 8 GB (laplace_is) and minutes; 1024 points take ≈ 0.3–0.5 GB.
MAX_FIT_POINTS = 1024


class RobustWallParams(ClusterParams):
    """Parameters shared by the probabilistic wall estimators (clustering as lsq, plus the model)."""

    models: tuple[Literal["line", "arc"], ...] = Field(("line", "arc"), description="wall models to "
                                                       "consider, chosen per wall by `selection`")
    selection: Literal["evidence", "bic"] = Field("evidence", description="model-order criterion: Laplace "
                                                  "log evidence or −BIC/2")
    selection_margin: float = Field(2.0, ge=0, le=100, description="nats a more complex model must gain "
                                    "to be chosen")
    outlier_fraction: float = Field(0.1, ge=0, lt=0.5, description="prior fraction ε of LOS points not on "
                                    "the wall (0: plain Gaussian likelihood)")
    outlier_width: float = Field(4.0, gt=0, le=1e4, description="width W [m] of the band over which "
                                 "outliers are uniform (depth in front of the wall for clutter); about "
                                 "cluster_distance, the reach within which a point joins the wall's cluster")
    clutter_share: float = Field(0.8, ge=0, le=1, description="share c of the outliers that is clutter in "
                                 "front of the wall (the rest: uniform on both sides)")
    wall_roughness: float = Field(0.02, ge=0, le=100, description="rms departure ρ [m] of the real wall "
                                  "from the model, added to each point's normal variance")
    estimate_noise_scale: bool = Field(True, description="infer a factor s on the detections' stated "
                                       "errors (log s ~ N(0, noise_scale_prior_std²))")
    noise_scale_prior_std: float = Field(0.5, gt=0, le=10, description="prior std of log s")
    curvature_prior_std: float = Field(0.03, gt=0, le=100, description="prior std σ_κ of the arc "
                                       "curvature [1/m]")
    max_iter: int = Field(100, ge=5, le=10_000, description="IPOPT iteration limit per MAP")
    tol: float = Field(1e-8, gt=0, le=1e-2, description="IPOPT convergence tolerance")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="seed of every random draw (pair subsets, "
                      "sampler, subsamples of large walls)")
    max_fit_points: int = Field(MAX_FIT_POINTS, ge=16, le=65_536, description="a wall with more LOS points is "
                                "fitted to this many of them, drawn without replacement from seed and the wall's "
                                "rank (estimate_walls: bounded memory); its posterior is then that of the subsample")

    @field_validator("models")
    @classmethod
    def _models(cls, v):
        if not v or len(set(v)) != len(v):
            raise ValueError("models must name each of 'line', 'arc' at most once and at least one model")
        return tuple(sorted(v, key=("line", "arc").index))

    def likelihood_config(self) -> LikelihoodConfig:
        return LikelihoodConfig(self.outlier_fraction, self.outlier_width, self.wall_roughness,
                                self.estimate_noise_scale, self.noise_scale_prior_std,
                                self.curvature_prior_std, self.clutter_share)


@dataclass
class ClusterFit:
    """MAP fits of one wall (one LOS cluster): fits {model: MapFit}, the chosen model, the
    selection report, the likelihoods {model: WallLikelihood} and the start line."""

    points: np.ndarray
    point_cov: np.ndarray
    fits: dict[str, MapFit]
    chosen: str
    selection: dict
    likelihoods: dict[str, WallLikelihood]
    anchor: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def best(self) -> MapFit:
        return self.fits[self.chosen]


def _line_scales(points, point_cov, cfg: LikelihoodConfig, phi: float) -> tuple[np.ndarray, float, float]:
    """(expected posterior widths of (φ, b) — lsq's formula with the stated noise —, the typical
    normal error σ_n [m], the seen length [m]) of a line with normal angle φ; used to scale the
    optimisation variables."""
    n = np.array([np.cos(phi), np.sin(phi)])
    u = np.array([-n[1], n[0]])
    var = np.einsum("i,kij,j->k", n, point_cov, n) + cfg.wall_roughness**2
    sd = float(np.sqrt(max(np.median(var), 1e-24)))
    t = points @ u
    stt = max(float(np.sum((t - t.mean()) ** 2)), 1e-24 + 1e-12 * float(np.sum(points**2)))
    widths = np.array([sd / np.sqrt(stt), sd * np.sqrt(1.0 / len(points) + t.mean() ** 2 / stt)])
    return widths, sd, max(float(np.ptp(t)), 1e-6)


def _pair_start(lik: WallLikelihood, phi0: float, rng: np.random.Generator) -> np.ndarray | None:
    """(φ, b) of the line through two points that maximises the robust likelihood, or None."""
    x = lik.points
    n = len(x)
    if n < 3:
        return None
    i, j = np.triu_indices(n, 1)
    if len(i) > MAX_PAIRS:
        pick = rng.choice(len(i), MAX_PAIRS, replace=False)
        i, j = i[pick], j[pick]
    d = x[j] - x[i]
    length = np.hypot(d[:, 0], d[:, 1])
    ok = length > 0
    if not ok.any():
        return None
    i, j, d, length = i[ok], j[ok], d[ok], length[ok]
    nrm = np.stack([-d[:, 1], d[:, 0]], -1) / length[:, None]
    flip = (nrm @ [np.cos(phi0), np.sin(phi0)]) < 0  # same half-turn as the TLS normal
    nrm[flip] *= -1
    phi = np.arctan2(nrm[:, 1], nrm[:, 0])
    b = -np.sum(nrm * x[i], axis=1)
    theta = np.zeros((len(phi), lik.n_params))
    theta[:, 0], theta[:, 1] = phi, b
    lp = lik.log_prob(theta)
    if not np.isfinite(lp).any():
        return None
    k = int(np.argmax(lp))
    return np.array([phi[k], b[k]])


def _best(fits: list[MapFit]) -> MapFit:
    return min(fits, key=lambda f: (not f.success, f.neg_log_post))


def fit_cluster(points, point_cov, params: RobustWallParams, rng: np.random.Generator) -> ClusterFit:
    """MAP fits of every configured wall model to one LOS cluster, and the model choice.

    points (N, 2) [m], point_cov (N, 2, 2) [m²]. Raises InsufficientDataError when the points
    coincide (no wall direction) or fewer than 2 are given; InputError for unusable covariances.
    """
    t0 = time.perf_counter()
    x = np.asarray(points, dtype=np.float64)
    cov = np.asarray(point_cov, dtype=np.float64)
    start = fit_line(x, cov)  # TLS warm start; raises for coincident points
    phi0, b0 = float(start.mean[0]), float(start.mean[1])
    anchor = x.mean(axis=0)
    cfg = params.likelihood_config()
    liks = {m: WallLikelihood(m, x, cov, cfg, anchor=anchor, phi_ref=phi0) for m in ("line", "arc")}
    sc_line, sd_n, length = _line_scales(x, cov, cfg, phi0)
    ls = [0.0] if cfg.estimate_noise_scale else []
    sc_ls = [0.3] if cfg.estimate_noise_scale else []
    line_starts = [np.array([phi0, b0])]
    pair = _pair_start(liks["line"], phi0, rng) if cfg.mixture else None
    if pair is not None:
        lp = liks["line"].log_prob(np.array([np.concatenate([st, ls]) for st in (line_starts[0], pair)]))
        if lp[1] > lp[0]:  # the TLS line (dragged by outliers) explains the data worse: start there too
            line_starts.append(pair)

    def solve_line(s):
        return solve_map(liks["line"], np.concatenate([s[:2], s[2:] if len(s) > 2 else ls]),
                         np.concatenate([sc_line, sc_ls]), params.max_iter, params.tol)

    line_fit = _best([solve_line(s) for s in line_starts])
    fits: dict[str, MapFit] = {"line": line_fit}
    n_solves = len(line_starts)
    if "arc" in params.models:
        # κ is seen through the sagitta κL²/8 against the normal error σ_n
        k_scale = float(np.clip(8.0 * sd_n / length**2, 1e-9, cfg.curvature_prior_std))
        sc_arc = np.concatenate([sc_line, [k_scale], sc_ls])
        th = line_fit.theta
        arc_fit = solve_map(liks["arc"], np.concatenate([th[:2], [0.0], th[2:]]), sc_arc,
                            params.max_iter, params.tol)
        n_solves += 1
        # Cross-seed: if the arc's mode with κ dropped is a better line than the line's MAP, the
        # line restarts there (and the arc again from the new line), so both models are compared
        # at their best modes.
        from_arc = np.concatenate([arc_fit.theta[:2], arc_fit.theta[3:]])
        line_again = None
        if -liks["line"].log_prob(from_arc[None])[0] < line_fit.neg_log_post - 1e-6:
            line_again = solve_line(from_arc)
            n_solves += 1
        if line_again is not None and (line_again.success, -line_again.neg_log_post) > \
                (line_fit.success, -line_fit.neg_log_post):
            line_fit = line_again
            th = line_fit.theta
            arc_fit = _best([arc_fit, solve_map(liks["arc"], np.concatenate([th[:2], [0.0], th[2:]]), sc_arc,
                                                params.max_iter, params.tol)])
            n_solves += 1
        fits = {"line": line_fit, "arc": arc_fit}
    fits = {m: fits[m] for m in params.models}
    chosen, report = select_model(fits, len(x), params.selection, params.selection_margin)
    info = {"map_solves": n_solves, "map_time_s": time.perf_counter() - t0}
    return ClusterFit(x, cov, fits, chosen, report, liks, anchor, info)


def extent_of(model: str, theta_wall: np.ndarray, points: np.ndarray, anchor,
              inlier: np.ndarray) -> np.ndarray:
    """(2, 2) ends [m] of the wall's supported part: the wall points nearest the two extreme
    inliers along the wall (all points when fewer than 2 inliers)."""
    use = points[inlier] if inlier.sum() >= 2 else points
    near = nearest_points(model, theta_wall[None], use, anchor)[0]
    u = np.array([-np.sin(theta_wall[0]), np.cos(theta_wall[0])])
    t = near @ u
    return near[[int(np.argmin(t)), int(np.argmax(t))]]


def posterior_from_fit(fit: ClusterFit, estimator: str, mean=None, cov=None, samples=None,
                       extra_info: dict | None = None) -> WallPosterior:
    """WallPosterior of the chosen model: the MAP/Laplace by default, or the given moments and
    samples over the full parameter vector (wall parameters first, log s last, which is
    marginalised out here)."""
    model = fit.chosen
    mf = fit.best
    p = len(MODEL_PARAMS[model])
    mean = mf.theta if mean is None else np.asarray(mean, float)
    cov = mf.cov if cov is None else np.asarray(cov, float)
    lik = fit.likelihoods[model]
    inl = lik.inlier_probability(mf.theta)
    w_mean, w_cov = mean[:p], 0.5 * (cov[:p, :p] + cov[:p, :p].T)
    w_samples = None if samples is None else np.asarray(samples, float)[:, :p]
    extent = extent_of(model, w_mean, fit.points, fit.anchor, inl >= 0.5)
    w_mean, w_cov, w_samples = canonical(w_mean, w_cov, w_samples)
    names = param_names(model, lik.cfg)
    info = {
        "estimator": estimator, "model": model, "model_selection": fit.selection,
        "solver_status": mf.status, "solver_success": mf.success, "ipopt_iterations": mf.iterations,
        "laplace_regularised": mf.regularised,
        "outlier_fraction": float(1.0 - inl.mean()), "n_outliers": int(np.sum(inl < 0.5)),
        "inlier_probability": inl.tolist(), "map": dict(zip(names, map(float, mf.theta))),
        "cluster_size": len(fit.points), **fit.info,
    }
    if lik.cfg.estimate_noise_scale:
        info["noise_scale"] = float(np.exp(mean[-1]))
    info.update(extra_info or {})
    return WallPosterior(model, w_mean, w_cov, MODEL_PARAMS[model], n_points=len(fit.points),
                         extent=extent, samples=w_samples, info=info,
                         anchor=fit.anchor if model == "arc" else None)


def warm_up(params: RobustWallParams, max_points: int = 64) -> int:
    """Build the casadi Functions for clusters of up to ``max_points`` LOS points ahead of the
    first frame (:func:`estimators.map_solver.warm_up`); returns how many were built."""
    from .map_solver import warm_up as build

    return build(("line", "arc"), max_points, params.outlier_fraction > 0, params.estimate_noise_scale,
                 params.max_iter, params.tol)


def _subsample(pts: np.ndarray, members: np.ndarray, m: int, seq: np.random.SeedSequence) -> np.ndarray:
    """m of the cluster ``members`` (indices into pts (K, 2) [m]), sorted: the two extreme points along
    the cluster's principal axis (so the wall's extent keeps its ends) and m − 2 others drawn without
    replacement by a child of the wall's seed ``seq`` (the wall's own stream is left unchanged)."""
    x = pts[members]
    c = x - x.mean(axis=0)
    along = c @ np.linalg.eigh(c.T @ c)[1][:, 1]
    ends = np.unique([int(np.argmin(along)), int(np.argmax(along))])
    rest = np.setdiff1d(np.arange(len(members)), ends)
    pick = np.random.default_rng(seq.spawn(1)[0]).choice(rest, m - len(ends), replace=False)
    return members[np.sort(np.concatenate([ends, pick]))]


def estimate_walls(detections: Detections, params: RobustWallParams, who: str, per_wall) -> list[WallPosterior]:
    """Cluster the LOS detections and call ``per_wall(points, cov, rng) -> WallPosterior`` on each
    cluster (largest first); clusters whose points coincide are skipped and reported. Each
    wall's rng is spawned from ``params.seed`` by cluster rank, so results do not depend on
    what else is in the frame beyond the clustering.

    A cluster of N > ``max_fit_points`` (m) LOS points is fitted to m of them (:func:`_subsample`: its
    two ends along the wall and m − 2 drawn without replacement from the wall's seed, the same points
    on every run), so that memory and time stay bounded whatever the cloud (MAX_FIT_POINTS). The
    posterior is then the subsample's: honest for what was fitted, at most √(N/m) wider than all
    points would give (m = 1024 already pins a wall to σ/32); the extent still reaches the cluster's
    ends. info then says ``fitted_points`` m and ``cluster_size`` N; ``detection_index`` lists the
    whole cluster. Clusters of ≤ m points are fitted as before."""
    idx, pts, cov, chosen = los_clusters(detections, params, who)
    seeds = np.random.SeedSequence(params.seed).spawn(len(chosen))
    walls, skipped = [], []
    for members, seq in zip(chosen, seeds):
        t0 = time.perf_counter()
        fitted = members
        if len(members) > params.max_fit_points:
            fitted = _subsample(pts, members, params.max_fit_points, seq)
        try:
            w = per_wall(pts[fitted], cov[fitted], np.random.default_rng(seq))
        except InsufficientDataError as exc:
            skipped.append(str(exc))
            continue
        w.info["detection_index"] = idx[members].tolist()
        if len(fitted) < len(members):
            w.info.update(fitted_points=len(fitted), cluster_size=len(members))
        w.info["time_s"] = time.perf_counter() - t0
        walls.append(w)
    if not walls:
        raise InsufficientDataError(f"{who}: no cluster gave a wall: " + "; ".join(skipped))
    return walls
