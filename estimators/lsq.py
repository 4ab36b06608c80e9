"""Least-squares relay walls: total-least-squares (orthogonal) line fits to clusters of LOS points.

1. LOS detections' Cartesian positions x_i [m] are split into clusters by single linkage
   (scipy.cluster.hierarchy, cut at ``cluster_distance``), and each cluster into straight pieces at
   its corners (:func:`split_corners`): one piece per wall. A building corner seen from the radar
   (both facades, or a facade and a chamfer) chains into one single-linkage cluster; one line through
   that L would be a wall that is not there, and every point mirrored through it would land metres off.
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
from scipy.sparse.csgraph import minimum_spanning_tree, shortest_path
from scipy.spatial import Delaunay, QhullError
from scipy.spatial.distance import pdist, squareform

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


def single_linkage(points: np.ndarray, distance: float) -> np.ndarray:
    """Cluster labels (N,) 0…C−1 of single-linkage clustering cut at ``distance`` [m]."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return np.zeros(len(pts), dtype=np.int64)
    # condensed distances, not the points: a 2 × 2 point array can look like a distance matrix to linkage
    return fcluster(linkage(pdist(pts), method="single"), t=distance, criterion="distance").astype(np.int64) - 1


MIN_SIDE = 5  # points on each side of a corner cut (split_corners)


def split_corners(points: np.ndarray, tolerance: float, corner_angle: float = 15.0,
                  sigma: np.ndarray | None = None) -> list[np.ndarray]:
    """Straight pieces of one cluster of LOS points (n, 2) [m]: index arrays into ``points``.

    Split-and-merge line extraction (Pavlidis & Horowitz) on the points in chain order: by their
    distance from one end of the longest path through the cluster's minimum spanning tree, so the
    chain runs along one facade, round the corner and along the next. (Azimuth seen from the radar
    orders a noise-free chain too, but scrambles a facade seen at grazing incidence, where 0.1 m of
    noise moves a point across a hundred of its neighbours' azimuths.) ``sigma`` (n,) [m]: each
    point's position standard deviation (largest axis; None: 0).

    1. Split (iterative end-point fit, as in Douglas–Peucker): a piece whose farthest point from the
       chord between its first and last point lies more than ``tolerance`` [m] and more than 3 σ of
       its own from the chord is cut at that point when it is a corner:

       * the two sides' total-least-squares lines differ in direction by at least ``corner_angle``
         [deg] (a lone outlier leaves two sides along one line), and each side's direction is known
         to within ``corner_angle`` at 3 standard deviations (σ_φ² = σ²/Σt², t the coordinates along
         the line, σ² the larger of the points' mean variance and the side's scatter about its line,
         which clutter or a further corner in the side raise): a few noisy points bend any way.

       Both sides are examined again (a side may hold the next corner); a piece that is not
       straight but has no such corner stays whole, as without the split.
    2. Adjust: in noise the farthest point misses the corner by a sample or two, which tilts both
       lines. Each cut between neighbouring pieces moves to where the two pieces' residuals Σd²
       (smaller eigenvalues of their scatter matrices, from prefix sums) add up least; two sweeps.
    3. Merge: cuts go while the polyline's BIC falls without them (:func:`_merge_pieces`): a short
       piece left at a corner by a cut a few samples off joins its neighbours.
    4. Arc or corners: when one circle explains the whole cluster better than the polyline of its
       pieces (BIC, :func:`_arc_beats_polyline`), the cluster stays whole: a curved facade (the
       'arc' wall model) is not a chain of corners, while a chamfered corner (three facades) is.

    Each side of a cut keeps ≥ :data:`MIN_SIDE` points: with fewer, an outlier and two wall points
    pass every test above (three points nearly always lie along a line). A cluster whose points all
    lie within ``tolerance`` of their total-least-squares line is one wall without further tests. Written out here rather
    than taken from shapely's ``simplify`` (step 1 without the corner test): that needs a new
    dependency and returns coordinates, not member indices.
    """
    x = np.asarray(points, dtype=np.float64)
    if len(x) < 2 * MIN_SIDE or _straight(x, tolerance):
        return [np.arange(len(x))]  # no cut possible, or every point within tolerance of one line
    sd = np.zeros(len(x)) if sigma is None else np.asarray(sigma, dtype=np.float64)
    order = _chain_order(x)
    pieces, todo = [], [order]
    while todo:
        g = todo.pop()
        chord = x[g[-1]] - x[g[0]]
        length = float(np.hypot(*chord))
        dist = np.abs((x[g] - x[g[0]]) @ np.array([-chord[1], chord[0]])) / max(length, 1e-300)
        k = int(np.argmax(dist))  # 0 < k < len(g) − 1 when dist[k] > 0: the ends lie on the chord
        if (length > 0.0 and dist[k] > max(tolerance, 3.0 * sd[g[k]])
                and _is_corner(x[g], sd[g], k, corner_angle)):
            todo += [g[:k], g[k:]]
        else:
            pieces.append(g)
    position = np.empty(len(x), np.int64)
    position[order] = np.arange(len(x))
    pieces.sort(key=lambda g: int(position[g[0]]))
    chain = np.concatenate(pieces)
    cuts = np.cumsum([0] + [len(g) for g in pieces])
    for _ in range(2):
        for i in range(1, len(cuts) - 1):
            lo, hi = cuts[i - 1], cuts[i + 1]
            cuts[i] = lo + MIN_SIDE + int(np.argmin(_tls_residuals(x[chain[lo:hi]])[MIN_SIDE:hi - lo - MIN_SIDE + 1]))
    cuts = _merge_pieces(x[chain], list(cuts))
    pieces = [np.sort(chain[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
    if len(pieces) > 1 and _arc_beats_polyline(x, pieces):
        return [np.arange(len(x))]
    return pieces


def _bic(rss: float, n: int, params: int) -> float:
    """Bayesian information criterion n ln(RSS/n) + params · ln n of a fit to n points; RSS/n [m²]
    gets a floor of 1e-6 m² (noise-free points)."""
    return n * np.log(max(rss / n, 1e-6)) + params * np.log(n)


def _merge_pieces(x: np.ndarray, cuts: list[int]) -> list[int]:
    """The merge step (split_corners, step 3): fewer cuts of the chain x (n, 2) [m] while that lowers
    the polyline's BIC (m lines: 3m − 1 parameters, two per line and one per cut). Each round tries
    removing one cut (its two pieces become one line) and dissolving one inner piece (its two
    neighbours and it become two lines, cut where their residuals add up least, ≥ MIN_SIDE points a
    side), and applies the best."""
    n = len(x)
    while len(cuts) > 2:
        rss = [_tls_residual(x[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
        m, total = len(rss), sum(rss)
        best, best_bic = None, _bic(total, n, 3 * m - 1)
        for i in range(1, m):  # remove cut i
            merged = _tls_residual(x[cuts[i - 1]:cuts[i + 1]])
            b = _bic(total - rss[i - 1] - rss[i] + merged, n, 3 * m - 4)
            if b < best_bic:
                best, best_bic = cuts[:i] + cuts[i + 1:], b
        for j in range(1, m - 1):  # dissolve piece j
            lo, hi = cuts[j - 1], cuts[j + 2]
            r = _tls_residuals(x[lo:hi])[MIN_SIDE:hi - lo - MIN_SIDE + 1]
            b = _bic(total - rss[j - 1] - rss[j] - rss[j + 1] + float(r.min()), n, 3 * m - 4)
            if b < best_bic:
                best, best_bic = cuts[:j] + [lo + MIN_SIDE + int(np.argmin(r))] + cuts[j + 2:], b
        if best is None:
            return cuts
        cuts = best
    return cuts


def _arc_beats_polyline(x: np.ndarray, pieces: list[np.ndarray]) -> bool:
    """Whether one circle explains the cluster x (n, 2) [m] better than the polyline of its m
    ``pieces``, by BIC = n ln(RSS/n) + p ln n with p = 3 for the circle and 3m − 1 for the polyline
    (two per line, one per cut); RSS/n gets a floor of 1e-6 m² (noise-free points)."""
    rss_poly = sum(_tls_residual(x[p]) for p in pieces)
    return bool(_bic(_circle_residual(x), len(x), 3) < _bic(rss_poly, len(x), 3 * len(pieces) - 1))


def _straight(x: np.ndarray, tolerance: float) -> bool:
    """Whether every point of x (n, 2) [m] lies within ``tolerance`` of their total-least-squares line
    (the fast path of split_corners: most clusters are one straight facade)."""
    z = x - x.mean(axis=0)
    normal = np.linalg.eigh(z.T @ z)[1][:, 0]
    return bool(np.abs(z @ normal).max() <= tolerance)


DELAUNAY_FROM = 200  # points from which spanning_tree searches the Delaunay edges instead of all pairs


def spanning_tree(x: np.ndarray):
    """Euclidean minimum spanning tree of x (n, 2) [m] as a sparse (n, n) matrix of edge lengths.

    Below DELAUNAY_FROM points, the tree of all n(n − 1)/2 pairs. From there, the tree of the Delaunay
    triangulation's ≤ 3n edges, which holds every Euclidean MST edge (scipy.spatial.Delaunay, Qhull):
    the same tree at O(n log n) instead of sorting n² pairs (1000 pooled LOS points: 91 → 5 ms). Points
    that Qhull cannot triangulate (all on one line, exact duplicates: the tree would not span them)
    fall back to all pairs. Edge lengths get 1e-12 m added: csgraph reads a 0 as "no edge".
    """
    n = len(x)
    if n >= DELAUNAY_FROM:
        try:
            s = Delaunay(x).simplices
        except QhullError:
            s = None
        if s is not None:
            e = np.unique(np.sort(np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [0, 2]]]), axis=1), axis=0)
            w = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) + 1e-12
            tree = minimum_spanning_tree(coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr())
            if tree.nnz == n - 1:
                return tree
    return minimum_spanning_tree(squareform(pdist(x)) + 1e-12 * (1.0 - np.eye(n)))


def _chain_order(x: np.ndarray) -> np.ndarray:
    """Indices of x (n, 2) [m] by tree distance from one end of the longest path of their Euclidean
    minimum spanning tree (scipy.sparse.csgraph; the far end of a far end is an end of that path)."""
    if len(x) < 3:
        return np.arange(len(x))
    tree = spanning_tree(x)
    end = int(np.argmax(shortest_path(tree, directed=False, indices=0)))
    return np.argsort(shortest_path(tree, directed=False, indices=end), kind="stable")


def _is_corner(x: np.ndarray, sd: np.ndarray, k: int, corner_angle: float) -> bool:
    """Whether the chain x (n, 2) [m] with position errors sd (n,) [m] bends at x[k] (split_corners)."""
    if min(k, len(x) - k) < MIN_SIDE:
        return False
    sides = []
    for side, s in ((x[:k + 1], sd[:k + 1]), (x[k:], sd[k:])):
        w, v = np.linalg.eigh(np.cov(side.T, bias=True))
        noise2 = max(float(np.mean(s ** 2)), float(w[0]))  # the points' σ², or the side's scatter about its line
        sides.append((v[:, 1], noise2 / (len(side) * max(float(w[1]), 1e-300))))  # direction, Var φ = σ²/Σt² [rad²]
    (u0, var0), (u1, var1) = sides
    angle = float(np.arccos(min(1.0, abs(float(u0 @ u1)))))
    return bool(angle >= np.radians(corner_angle) and 3.0 * np.sqrt(max(var0, var1)) <= np.radians(corner_angle))


def _circle_residual(x: np.ndarray) -> float:
    """Σ(|x_i − c| − R)² [m²] of the algebraic (Kåsa) circle fit to x (n, 2) [m]: solve
    x² + y² + D x + E y + F = 0 by linear least squares, c = −(D, E)/2, R² = |c|² − F."""
    z = x - x.mean(axis=0)
    (d, e, f), *_ = np.linalg.lstsq(np.c_[z, np.ones(len(z))], -np.sum(z ** 2, axis=1), rcond=None)
    c = -0.5 * np.array([d, e])
    r = np.sqrt(max(float(c @ c) - f, 0.0))
    return float(np.sum((np.linalg.norm(z - c, axis=1) - r) ** 2))


def _tls_residual(x: np.ndarray) -> float:
    """Total-least-squares Σd² [m²] of one line through x (n, 2) [m]: the scatter matrix's smaller eigenvalue."""
    z = x - x.mean(axis=0)
    return max(float(np.linalg.eigvalsh(z.T @ z)[0]), 0.0)


def _tls_residuals(x: np.ndarray) -> np.ndarray:
    """(n + 1,) total-least-squares Σd² [m²] of x[:k] plus that of x[k:], for every cut k = 0 … n."""
    def sums(v):
        ones = np.ones(len(v))
        c = np.cumsum(np.c_[ones, v, v[:, 0] ** 2, v[:, 0] * v[:, 1], v[:, 1] ** 2], axis=0)
        return np.vstack([np.zeros(6), c])  # rows: the first k points

    def smallest_eigenvalue(s):
        n = np.maximum(s[:, 0], 1.0)
        sxx = s[:, 3] - s[:, 1] ** 2 / n
        sxy = s[:, 4] - s[:, 1] * s[:, 2] / n
        syy = s[:, 5] - s[:, 2] ** 2 / n
        return np.maximum(0.5 * (sxx + syy) - np.sqrt(0.25 * (sxx - syy) ** 2 + sxy ** 2), 0.0)

    centred = x - x.mean(axis=0)  # prefix sums of squares lose digits far from the origin otherwise
    return smallest_eigenvalue(sums(centred)) + smallest_eigenvalue(sums(centred[::-1]))[::-1]


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
        cluster's points from earlier frames). If no cluster reaches min_points, the largest cluster
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
