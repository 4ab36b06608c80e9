"""Least-squares relay walls: total-least-squares (orthogonal) line fits to clusters of LOS points.

1. LOS detections' Cartesian positions x_i [m] are split into clusters by single linkage
   (scipy.cluster.hierarchy, cut at ``cluster_distance``), and each cluster into straight pieces at
   its corners (:func:`estimators.corners.split_corners`): one piece per wall.
2. Per cluster (n points, centroid c): the line normal n = (cos φ, sin φ) is the eigenvector of
   the smallest eigenvalue of the scatter matrix Σ (x_i − c)(x_i − c)ᵀ, b = −nᵀc, made canonical
   (b ≥ 0, the radar side positive). Residuals d_i = nᵀx_i + b.
3. Covariance of (φ, b), first order (Gauss–Newton on d_i(φ, b), noise σ² along the normal):
   with u = ∂n/∂φ = (−sin φ, cos φ) the along-line direction, s_i = uᵀx_i, s̄ = uᵀc and
   t_i = s_i − s̄ (coordinate along the line relative to the centroid), J_i = [s_i, 1] and
   Cov = σ²(JᵀJ)⁻¹, i.e.

       Var φ = σ²/Σt_i²,   Cov(φ, b) = −σ² s̄/Σt_i²,   Var b = σ²(1/n + s̄²/Σt_i²),

   (b is correlated with φ through the centroid: rotating the line about c moves b by −s̄ dφ).
   σ² = Σ d_i²/(n − 2) (TLS residual variance); with n = 2 the residuals are 0 by construction
   and σ² is the mean variance of the two detections' positions along n (Detections.position_cov).
"""
from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.distance import pdist

from estimators.corners import DENSE_MAX, mst_edges, snap_corners, split_corners
from estimators.history import LOSHistory
from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.geometry import canonical_line
from xnlos_core.interfaces import WallEstimator
from xnlos_core.types import LOS, Detections, WallPosterior


# Largest |x|, |y| [m] of a LOS point, and largest position standard deviation [m], the wall
# estimators accept: a thousand times any radar's reach (RadarConfig.max_range ≤ the unambiguous
# range, ~100 m), yet far from where squared distances and variances (linkage, scatter matrices,
# likelihood Hessians) overflow — a point at 1e300 m made scipy raise, stated errors of 1e150 m
# made the casadi Hessian non-finite.
MAX_COORDINATE = 1e6


class ClusterParams(BaseModel):
    """How LOS points are split into walls; shared by every wall estimator."""

    model_config = ConfigDict(extra="forbid")
    cluster_distance: float = Field(4.0, gt=0, le=1e3, description="single-linkage cut: LOS points closer "
                                                                   "than this [m] chain into one wall")
    min_points: int = Field(3, ge=2, le=100_000, description="LOS points a cluster needs to become a wall")
    merge_tolerance: float = Field(0.75, ge=0, le=100, description="clusters (or single points) lying within "
                                   "this distance [m] of a larger cluster's line join it (one wall seen in pieces)")
    split_tolerance: float = Field(1.0, gt=0, le=100, description="a cluster is split at its corner when a point "
                                   "lies farther than this [m] from the chord of its chain's ends "
                                   "(split_corners); larger than the LOS points' scatter about their wall")
    corner_angle: float = Field(15.0, ge=0, le=90, description="least change of direction [deg] between the two "
                                "sides of a split (split_corners); smaller bends stay one wall")
    wall_max_speed: float | None = Field(0.5, gt=0, le=100, description="LOS detections with |radial velocity| "
                                         "above this [m/s] are left out of the walls: a wall stands still, a road "
                                         "user in line of sight moves (detections without Doppler are all kept); "
                                         "None keeps every LOS detection")


class LSQParams(ClusterParams):
    """Parameters of lsq: the clustering and the frames pooled."""

    history_frames: int = Field(1, ge=1, le=100, description="frames whose LOS detections each fit pools: 1 fits "
                                "each frame alone; K > 1 adds the LOS detections of the K − 1 frames before "
                                "(estimators.history), for a radar that stands still (positions are in its frame)")
    history_max_speed: float = Field(0.5, gt=0, le=100, description="only LOS detections with |radial velocity| ≤ "
                                     "this [m/s] are held for later frames: walls stand still, and a road user's LOS "
                                     "echoes of K frames line up along its path into a wall that is not there "
                                     "(detections without Doppler are all held)")
    corner_snap: float | None = Field(1.0, gt=0, le=100, description="two walls meeting at a corner end at their "
                                      "lines' intersection when an end of each lies within this distance [m] of it "
                                      "(estimators.corners.snap_corners); None keeps the extents of the points")


def single_linkage(points: np.ndarray, distance: float) -> np.ndarray:
    """Cluster labels (N,) 0…C−1 of single-linkage clustering cut at ``distance`` [m].

    Up to DENSE_MAX (2048) points: scipy's linkage of all N(N − 1)/2 distances, as always. Beyond,
    in O(N) memory (the condensed distances and linkage's copies of 20,000 points took 1.9 GB): the
    same clusters as the connected components of a Euclidean minimum spanning tree's edges no longer
    than ``distance`` (:func:`estimators.corners.mst_edges`; two points share a single-linkage cluster
    exactly when the tree path between them has no longer edge), numbered in order of first
    appearance instead of linkage's order."""
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    if n < 2:
        return np.zeros(n, dtype=np.int64)
    if n <= DENSE_MAX:
        # condensed distances, not the points: a 2 × 2 point array can look like a distance matrix to linkage
        return fcluster(linkage(pdist(pts), method="single"), t=distance, criterion="distance").astype(np.int64) - 1
    i, j = mst_edges(pts)
    keep = np.hypot(*(pts[i] - pts[j]).T) <= distance
    graph = coo_matrix((np.ones(int(keep.sum())), (i[keep], j[keep])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def fit_line(points: np.ndarray, point_cov: np.ndarray | None = None) -> WallPosterior:
    """TLS line through ``points`` (n ≥ 2, (n, 2) [m]) with its (φ, b) covariance (module doc).

    point_cov (n, 2, 2) [m²]: position covariances, used for σ² when n = 2.
    Raises InsufficientDataError when the points coincide (no direction) or when the covariance
    overflows (errors so large against the points' spread that they say nothing about the line).
    """
    x = np.asarray(points, dtype=np.float64)
    n_pts = len(x)
    if n_pts < 2:
        raise InsufficientDataError(f"fit_line: {n_pts} point(s) given; a line needs at least 2")
    c = x.mean(axis=0)
    dx = x - c
    evals, evecs = np.linalg.eigh(dx.T @ dx)
    if evals[1] <= 1e-18 * max(1.0, float(np.abs(x).max()) ** 2):
        raise InsufficientDataError(f"fit_line: the {n_pts} points coincide at {c.tolist()}; no line direction")
    nrm, b = canonical_line(evecs[:, 0], -float(evecs[:, 0] @ c))
    phi = float(np.arctan2(nrm[1], nrm[0]))
    u = np.array([-np.sin(phi), np.cos(phi)])
    d = x @ nrm + b
    t = dx @ u
    stt = float(t @ t)
    sbar = float(u @ c)
    if n_pts > 2:
        sigma2 = float(d @ d) / (n_pts - 2)
    elif point_cov is not None:
        sigma2 = float(np.mean(np.einsum("i,kij,j->k", nrm, np.asarray(point_cov, float), nrm)))
    else:
        sigma2 = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        cov = sigma2 * np.array([[1.0 / stt, -sbar / stt], [-sbar / stt, 1.0 / n_pts + sbar**2 / stt]])
    if not np.all(np.isfinite(cov)):
        raise InsufficientDataError(
            f"fit_line: the {n_pts} points spread {np.sqrt(stt):.3g} m along the line but their normal "
            f"variance is σ² = {sigma2:.3g} m²; the (φ, b) covariance overflows, so they do not determine a line")
    extent = c + np.array([t.min(), t.max()])[:, None] * u
    info = {"residual_rms": float(np.sqrt(np.mean(d**2))), "cluster_size": n_pts, "sigma2": sigma2}
    return WallPosterior("line", np.array([phi, b]), cov, n_points=n_pts, extent=extent, info=info)


class LSQWallEstimator(WallEstimator):
    """Total-least-squares line per single-linkage cluster of LOS points, with (φ, b) covariance;
    with ``history_frames`` K > 1, of this frame's LOS points and those of the K − 1 frames before."""

    Params = LSQParams

    def __init__(self, params=None):
        super().__init__(params)
        self.history = LOSHistory(self.params.history_frames, self.params.history_max_speed)

    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """One 'line' WallPosterior per cluster with ≥ min_points LOS points, largest cluster first.

        info: residual_rms [m], cluster_size (LOS points of the pooled frames), sigma2 [m²],
        detection_index (indices into ``detections``, this frame's rows only), history_points (the
        cluster's points from earlier frames); with ``corner_snap``, walls meeting at a corner end at its
        vertex (:func:`estimators.corners.snap_corners`, info snapped_ends). If no cluster reaches min_points, the largest cluster
        is fitted if it has ≥ 2 points. Raises InsufficientDataError with < 2 LOS points (pooled
        over the frames held) or no usable cluster; this frame's LOS points are held all the same.
        """
        pooled = self.history.pool(detections, "LSQWallEstimator")  # InputError for anything but Detections
        n = len(detections)
        idx, pts, cov, chosen = los_clusters(pooled, self.params, "LSQWallEstimator")
        walls, skipped = [], []
        for members in chosen:
            try:
                w = fit_line(pts[members], cov[members])
            except InsufficientDataError as exc:
                skipped.append(str(exc))
                continue
            w.info["detection_index"] = idx[members][idx[members] < n].tolist()
            w.info["history_points"] = int(np.sum(idx[members] >= n))
            walls.append(w)
        if not walls:
            raise InsufficientDataError("LSQWallEstimator: no cluster gave a line: " + "; ".join(skipped))
        if self.params.corner_snap is not None:
            walls = snap_corners(walls, self.params.corner_snap, self.params.corner_angle)
        return walls

    @property
    def carries_state(self) -> bool:
        """True with ``history_frames`` > 1: a fit then uses earlier frames' LOS detections."""
        return self.params.history_frames > 1

    def reset(self) -> None:
        """Forget the LOS detections of earlier frames (the start of a run or a sequence)."""
        self.history.reset()

    def state(self) -> dict:
        """The LOS detections held from earlier frames, JSON-able (:meth:`LOSHistory.state`)."""
        return self.history.state()

    def load_state(self, state: dict) -> None:
        """Restore :meth:`state`; InputError naming the key for anything else (the history is then empty)."""
        self.history.load_state(state, type(self).__name__)


def los_clusters(detections: Detections, params, who: str) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                     list[np.ndarray]]:
    """Split the LOS detections into walls (steps 1 and merging; shared by every wall estimator).

    params: a :class:`ClusterParams` (its ``wall_max_speed`` leaves moving LOS detections out first); ``who``
    names the caller in errors. Returns (idx (K,): indices of the LOS rows in ``detections``,
    points (K, 2) [m], their covariances (K, 2, 2) [m²], clusters: index arrays into points,
    largest first, each with ≥ min_points members — or the largest cluster alone if none reaches
    min_points but it has ≥ 2). Raises InputError for non-Detections, for LOS points beyond
    ±MAX_COORDINATE [m] or with position errors above MAX_COORDINATE, InsufficientDataError with
    < 2 LOS points or no usable cluster.
    """
    if not isinstance(detections, Detections):
        raise InputError(f"{who}.estimate: expected Detections, got {type(detections).__name__}")
    idx = detections.of_class(LOS)
    moving = ""
    if params.wall_max_speed is not None and detections.velocity is not None:
        still = np.abs(detections.velocity[idx]) <= params.wall_max_speed
        moving = (f" ({int(np.sum(~still))} LOS detection(s) faster than wall_max_speed = "
                  f"{params.wall_max_speed:g} m/s left out)")
        idx = idx[still]
    if len(idx) < 2:
        raise InsufficientDataError(
            f"{who}: {len(idx)} LOS detection(s) among {len(detections)} detections{moving}; "
            "a wall line needs at least 2 LOS points")
    pts = detections.position[idx]
    far = np.flatnonzero(np.abs(pts).max(axis=1) > MAX_COORDINATE)
    if len(far):
        i = int(idx[far[0]])
        raise InputError(
            f"{who}: LOS detection {i} lies at {detections.position[i].tolist()} m (range "
            f"{detections.range[i]:.6g} m); {len(far)} LOS point(s) exceed |x|, |y| ≤ {MAX_COORDINATE:g} m, "
            "the largest coordinate the wall estimators accept")
    with np.errstate(over="ignore", invalid="ignore"):
        cov = detections.position_cov()[idx]
        sd = np.sqrt(np.trace(cov, axis1=1, axis2=2))  # overall position error [m]; inf/NaN on overflow
    bad = np.flatnonzero(~(sd <= MAX_COORDINATE))
    if len(bad):
        i = int(idx[bad[0]])
        raise InputError(
            f"{who}: the position error of LOS detection {i} is {sd[bad[0]]:.6g} m (range_std "
            f"{detections.range_std[i]:.6g} m, azimuth_std {detections.azimuth_std[i]:.6g} rad at range "
            f"{detections.range[i]:.6g} m); {len(bad)} LOS point(s) exceed {MAX_COORDINATE:g} m, the largest "
            "position standard deviation the wall estimators accept (such a point says nothing about a wall)")
    labels = single_linkage(pts, params.cluster_distance)
    sigma = np.sqrt(np.linalg.eigvalsh(cov)[:, 1])  # each point's largest position error [m]
    for k in np.unique(labels):
        members = np.flatnonzero(labels == k)
        for piece in split_corners(pts[members], params.split_tolerance, params.corner_angle, sigma[members])[1:]:
            labels[members[piece]] = labels.max() + 1
    groups = _merge_collinear(pts, labels, params.merge_tolerance)
    chosen = [g for g in groups if len(g) >= params.min_points]
    if not chosen:
        if len(groups[0]) < 2:
            raise InsufficientDataError(
                f"{who}: {len(idx)} LOS points but no two lie within cluster_distance="
                f"{params.cluster_distance} m of each other; no wall can be fitted")
        chosen = [groups[0]]
    return idx, pts, cov, chosen


def _merge_collinear(pts: np.ndarray, labels: np.ndarray, tol: float) -> list[np.ndarray]:
    """Clusters as index arrays, largest first, after merging pieces of one wall.

    Sparse detections split a long wall into several single-linkage clusters; a cluster (or a
    lone point) whose points all lie within ``tol`` [m] of a larger cluster's TLS line joins it —
    unless the radar sees through the gap between them (:func:`_seen_through`): two collinear
    facades across a street are two walls, and one wall spanning the street's mouth would claim every
    ray into that street (plugins.mirror.association anchors an mNLOS point to the wall its ray crosses).
    """
    groups = sorted((np.flatnonzero(labels == k) for k in np.unique(labels)), key=len, reverse=True)
    out = []
    while groups:
        g = groups.pop(0)
        changed = len(g) >= 2
        while changed:
            changed = False
            try:
                line = fit_line(pts[g])
            except InsufficientDataError:
                break
            for h in list(groups):
                if np.abs(pts[h] @ line.normal + line.offset).max() <= tol and not _seen_through(pts, g, h, line, tol):
                    g = np.concatenate([g, h])
                    groups = [x for x in groups if x is not h]
                    changed = True
        out.append(np.sort(g))
    return sorted(out, key=len, reverse=True)


def _seen_through(pts: np.ndarray, g: np.ndarray, h: np.ndarray, line: WallPosterior, tol: float) -> bool:
    """Whether an LOS point lies more than ``tol`` [m] behind ``line`` (g's TLS line) on a ray from the
    radar (origin) that crosses the line in the gap between the spans of ``g`` and ``h`` along it: the
    radar sees through that gap, so no wall closes it."""
    n, b = line.normal, line.offset
    u = np.array([-n[1], n[0]])
    (g0, g1), (h0, h1) = ((v.min(), v.max()) for v in (pts[g] @ u, pts[h] @ u))
    lo, hi = (g1, h0) if g1 < h0 else (h1, g0)
    if lo >= hi:
        return False  # the spans overlap: no gap
    delta = pts @ n + b
    behind = delta < -tol
    if not behind.any():
        return False
    q = pts[behind] * (b / (b - delta[behind]))[:, None]  # where each ray crosses the line (t = b / (b − δ))
    return bool(np.any(((q @ u) > lo) & ((q @ u) < hi)))
