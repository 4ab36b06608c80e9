"""Straight pieces of one cluster of LOS points: split-and-merge line extraction at a cluster's
corners (:func:`split_corners`, step 1 of :mod:`estimators.lsq`), for every wall estimator.

A building corner seen from the radar (both facades, or a facade and a chamfer) chains into one
single-linkage cluster; one line through that L would be a wall that is not there, and every point
mirrored through it would land metres off.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree, shortest_path
from scipy.spatial import Delaunay, QhullError, cKDTree
from scipy.spatial.distance import pdist, squareform

from xnlos_core.numerics import SQRT_EPS, data_scale, first_best, simplest_within, variance_floor

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

    0. Arms (:func:`_chains`): where three runs of points meet (a facade, a chamfer and a road user's
       side beside the corner: a T, not an L), one chain order interleaves two of them, and no cut of
       the chain is a corner. Each arm off the longest path is taken out as a chain of its own first;
       steps 1–3 run on every chain.

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
    pieces = [p for chain in _chains(x, sd, tolerance, corner_angle) for p in _split_chain(x, sd, chain, tolerance, corner_angle)]
    if len(pieces) > 1 and _arc_beats_polyline(x, pieces):
        return [np.arange(len(x))]
    return pieces


def _split_chain(x: np.ndarray, sd: np.ndarray, order: np.ndarray, tolerance: float,
                 corner_angle: float) -> list[np.ndarray]:
    """Steps 1–3 of :func:`split_corners` on one chain: ``order`` indexes x (n, 2) [m] in chain order;
    returns its straight pieces as sorted index arrays into x."""
    pieces, todo = [], [order]
    scale = data_scale(x)  # [m]: rounding of coordinates, distances and residual sums is relative to it
    while todo:
        g = todo.pop()
        chord = x[g[-1]] - x[g[0]]
        length = float(np.hypot(*chord))
        dist = np.abs((x[g] - x[g[0]]) @ np.array([-chord[1], chord[0]])) / max(length, 1e-300)
        # the farthest point, the first of those equally far up to rounding; 0 < k < len(g) − 1 when
        # dist[k] > 0: the ends lie on the chord
        k = first_best(dist, SQRT_EPS * scale, larger_is_better=True)
        if (length > 0.0 and dist[k] > max(tolerance, 3.0 * sd[g[k]])
                and _is_corner(x[g], sd[g], k, corner_angle)):
            todo += [g[:k], g[k:]]
        else:
            pieces.append(g)
    position = np.full(len(x), -1, np.int64)
    position[order] = np.arange(len(order))
    pieces.sort(key=lambda g: int(position[g[0]]))
    chain = np.concatenate(pieces)
    cuts = np.cumsum([0] + [len(g) for g in pieces])
    for _ in range(2):
        for i in range(1, len(cuts) - 1):
            lo, hi = cuts[i - 1], cuts[i + 1]
            r = _tls_residuals(x[chain[lo:hi]])[MIN_SIDE:hi - lo - MIN_SIDE + 1]
            # the first cut of least residual up to rounding: a point on both lines (a corner's vertex)
            # fits either side exactly, and rounding must not choose its side
            cuts[i] = lo + MIN_SIDE + first_best(r, variance_floor(scale, hi - lo))
    cuts = _merge_pieces(x[chain], list(cuts))
    return [np.sort(chain[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]


def _bic(rss: float, n: int, params: int) -> float:
    """Bayesian information criterion n ln(RSS/n) + params · ln n of a fit to n points; RSS/n [m²]
    gets a floor of 1e-6 m² (noise-free points; a millimetre, far above the float rounding of
    coordinates within the project's ±10 km bound, so rounding never enters the criterion)."""
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
        options = [(cuts, _bic(total, n, 3 * m - 1), 3 * m - 1)]  # the current polyline first
        for i in range(1, m):  # remove cut i
            merged = _tls_residual(x[cuts[i - 1]:cuts[i + 1]])
            options.append((cuts[:i] + cuts[i + 1:], _bic(total - rss[i - 1] - rss[i] + merged, n, 3 * m - 4),
                            3 * m - 4))
        for j in range(1, m - 1):  # dissolve piece j
            lo, hi = cuts[j - 1], cuts[j + 2]
            r = _tls_residuals(x[lo:hi])[MIN_SIDE:hi - lo - MIN_SIDE + 1]
            options.append((cuts[:j] + [lo + MIN_SIDE + first_best(r, variance_floor(data_scale(x), hi - lo))]
                            + cuts[j + 2:],
                            _bic(total - rss[j - 1] - rss[j] - rss[j + 1] + float(r.min()), n, 3 * m - 4),
                            3 * m - 4))
        # ties within the criterion tolerance go to fewer pieces, then the first option (xnlos_core.numerics)
        pick = simplest_within([o[1] for o in options], [o[2] for o in options])
        if pick == 0:
            return cuts
        cuts = options[pick][0]
    return cuts


def _arc_beats_polyline(x: np.ndarray, pieces: list[np.ndarray]) -> bool:
    """Whether one circle explains the cluster x (n, 2) [m] better than the polyline of its m
    ``pieces``, by BIC = n ln(RSS/n) + p ln n with p = 3 for the circle and 3m − 1 for the polyline
    (two per line, one per cut); RSS/n gets a floor of 1e-6 m² (noise-free points)."""
    rss_poly = sum(_tls_residual(x[p]) for p in pieces)
    values = [_bic(rss_poly, len(x), 3 * len(pieces) - 1), _bic(_circle_residual(x), len(x), 3)]
    return simplest_within(values, [3 * len(pieces) - 1, 3]) == 1  # ties: the fewer parameters


def _straight(x: np.ndarray, tolerance: float) -> bool:
    """Whether every point of x (n, 2) [m] lies within ``tolerance`` of their total-least-squares line
    (the fast path of split_corners: most clusters are one straight facade)."""
    z = x - x.mean(axis=0)
    normal = np.linalg.eigh(z.T @ z)[1][:, 0]
    return bool(np.abs(z @ normal).max() <= tolerance)


DELAUNAY_FROM = 200  # points from which spanning_tree searches the Delaunay edges instead of all pairs
DENSE_MAX = 2048  # points up to which the all-pairs fallback runs (its (n, n) matrices: 32 MiB each)


def spanning_tree(x: np.ndarray):
    """Euclidean minimum spanning tree of x (n, 2) [m] as a sparse (n, n) matrix of edge lengths.

    Below DELAUNAY_FROM points, the tree of all n(n − 1)/2 pairs. From there, the tree of the Delaunay
    triangulation's ≤ 3n edges, which holds every Euclidean MST edge (scipy.spatial.Delaunay, Qhull):
    the same tree at O(n log n) instead of sorting n² pairs (1000 pooled LOS points: 91 → 5 ms). Points
    that Qhull cannot triangulate (all on one line, exact duplicates: the tree would not span them)
    fall back to all pairs up to DENSE_MAX points, and beyond to :func:`mst_edges` (O(n) memory: the
    two (n, n) float64 matrices of 20,000 points need 6.4 GB). Edge lengths get 1e-12 m added: csgraph
    reads a 0 as "no edge".
    """
    n = len(x)
    if n >= DELAUNAY_FROM:
        tree = _delaunay_tree(x)
        if tree is not None:
            return tree
    if n <= DENSE_MAX:
        return minimum_spanning_tree(squareform(pdist(x)) + 1e-12 * (1.0 - np.eye(n)))
    i, j = mst_edges(x)
    w = np.hypot(*(x[i] - x[j]).T) + 1e-12
    return coo_matrix((w, (i, j)), shape=(n, n)).tocsr()


def _delaunay_tree(x: np.ndarray):
    """The MST of the Delaunay edges of x (n, 2) as a sparse (n, n) matrix (lengths + 1e-12 m), or
    None when Qhull fails or leaves points out (duplicates, collinear or nearly coincident points)."""
    n = len(x)
    try:
        s = Delaunay(x).simplices
    except (QhullError, ValueError):
        return None
    e = np.unique(np.sort(np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [0, 2]]]), axis=1), axis=0)
    w = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) + 1e-12
    tree = minimum_spanning_tree(coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr())
    return tree if tree.nnz == n - 1 else None


def mst_edges(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Endpoints (i, j), each (n − 1,), of a Euclidean minimum spanning tree of x (n ≥ 1, 2) [m], in
    O(n) memory whatever the points' layout.

    Exact duplicates are tied to their first occurrence (edges of length 0); the distinct points take
    the tree of their Delaunay edges (:func:`_delaunay_tree`), or, where Qhull cannot triangulate them,
    the chain of their order along the line when they are collinear (then every MST edge joins two
    neighbours on it), else Prim's algorithm over all pairs (O(n²) time, one distance row at a time).
    """
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    uniq, first, inverse = np.unique(x, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    dup = np.flatnonzero(first[inverse] != np.arange(n))
    i, j = [first[inverse[dup]]], [dup]  # each duplicate to its first occurrence
    m = len(uniq)
    if m >= 2:
        tree = _delaunay_tree(uniq) if m >= 3 else None
        if tree is not None:
            a, b = tree.nonzero()
        else:
            a, b = _chain_or_prim(uniq)
        i.append(first[a])
        j.append(first[b])
    return np.concatenate(i).astype(np.int64), np.concatenate(j).astype(np.int64)


def _chain_or_prim(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MST edges of distinct points u (m ≥ 2, 2) [m] that Qhull could not triangulate (see :func:`mst_edges`)."""
    c = u - u.mean(axis=0)
    scale = float(np.abs(c).max())
    if scale > 0:
        lam, vec = np.linalg.eigh((c / scale).T @ (c / scale))
        if lam[0] <= 1e-24 * max(lam[1], 1e-300):  # collinear to rounding: sort along the line
            order = np.argsort(c @ vec[:, 1], kind="stable")
            return order[:-1], order[1:]
    m = len(u)
    inside = np.zeros(m, dtype=bool)
    inside[0] = True
    best = np.hypot(u[:, 0] - u[0, 0], u[:, 1] - u[0, 1])
    parent = np.zeros(m, dtype=np.int64)
    a, b = np.empty(m - 1, np.int64), np.empty(m - 1, np.int64)
    for k in range(m - 1):
        q = int(np.argmin(np.where(inside, np.inf, best)))
        a[k], b[k] = parent[q], q
        inside[q] = True
        d = np.hypot(u[:, 0] - u[q, 0], u[:, 1] - u[q, 1])
        closer = d < best
        best = np.where(closer, d, best)
        parent = np.where(closer, q, parent)
    return a, b


def _chains(x: np.ndarray, sd: np.ndarray, tolerance: float, corner_angle: float) -> list[np.ndarray]:
    """Chains of x (n, 2) [m] (step 0 of :func:`split_corners`), each as indices in chain order.

    The first: the longest path of the points' Euclidean minimum spanning tree (scipy.sparse.csgraph;
    the far end of a far end is an end of that path) with the points hanging off it, ordered by tree
    distance from one end. The others: the arms, subtrees off that path of ≥ 2·MIN_SIDE points (a
    piece each side of a cut could be cut again) whose direction is known to within ``corner_angle``
    [deg] at 3 σ (as each side of a corner cut: a few noisy points bend any way) and that run away
    from the path (:func:`_leaves_path`).
    Each arm is taken apart the same way (recursively).
    """
    n = len(x)
    if n < 3:
        return [np.arange(n)]
    tree = spanning_tree(x)
    end = int(np.argmax(shortest_path(tree, directed=False, indices=0)))
    dist, pred = shortest_path(tree, directed=False, indices=end, return_predecessors=True)
    path = [int(np.argmax(dist))]
    while path[-1] != end:
        path.append(int(pred[path[-1]]))
    off = np.setdiff1d(np.arange(n), path)
    main = np.ones(n, dtype=bool)
    arms: list[np.ndarray] = []
    if len(off) >= 2 * MIN_SIDE:
        _, label = connected_components(tree[off][:, off], directed=False)
        along = cKDTree(x[path])  # built once: every candidate arm asks it
        for k in range(int(label.max()) + 1):
            idx = off[label == k]
            if (len(idx) >= 2 * MIN_SIDE and 3.0 * np.sqrt(_direction(x[idx], sd[idx])[1]) <= np.radians(corner_angle)
                    and _leaves_path(along, np.delete(x, idx, axis=0), x[idx], np.maximum(tolerance, 3.0 * sd[idx]))):
                main[idx] = False
                arms += [idx[c] for c in _chains(x[idx], sd[idx], tolerance, corner_angle)]
    kept = np.flatnonzero(main)
    return [kept[np.argsort(dist[kept], kind="stable")]] + arms


def _leaves_path(path: cKDTree, rest: np.ndarray, arm: np.ndarray, reach: np.ndarray) -> bool:
    """Whether the points ``arm`` (m, 2) [m] hanging off a chain's longest path run away from it, as a
    second wall does: ``path`` a cKDTree of the path's points (p, 2) [m], ``rest`` (r, 2) [m] every point of the
    chain but the arm's, ``reach`` (m,) [m] the larger of the split tolerance and 3 σ per arm point.

    * Some arm point lies beyond twice its reach from every path point (noise about one facade hangs
      off its path within the points' scatter), and
    * the arm and the chain's points near it (within the arm's span of the path point closest to
      it) each lie mostly beyond reach of the other's total-least-squares line: the far end of a
      facade hanging off a path that ends on a stray point lies along the rest of that facade (one
      such test alone is fooled when a stray point or two tilt the line of a short run).
    """
    if not np.any(path.query(arm)[0] > 2.0 * reach):
        return False
    root = path.data[int(np.argmin(cKDTree(arm).query(path.data)[0]))]
    near = rest[np.linalg.norm(rest - root, axis=1) <= np.linalg.norm(arm - root, axis=1).max()]
    if len(near) < 2:
        return True
    apart = np.median(reach)
    return bool(np.median(_line_distances(arm, near)) > apart and np.median(_line_distances(near, arm)) > apart)


def _line_distances(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(m,) distances [m] of ``others`` (m, 2) [m] from the total-least-squares line of ``points`` (k, 2)."""
    c = points.mean(axis=0)
    normal = np.linalg.eigh((points - c).T @ (points - c))[1][:, 0]
    return np.abs((others - c) @ normal)


def _is_corner(x: np.ndarray, sd: np.ndarray, k: int, corner_angle: float) -> bool:
    """Whether the chain x (n, 2) [m] with position errors sd (n,) [m] bends at x[k] (split_corners)."""
    if min(k, len(x) - k) < MIN_SIDE:
        return False
    (u0, var0), (u1, var1) = _direction(x[:k + 1], sd[:k + 1]), _direction(x[k:], sd[k:])
    angle = float(np.arccos(min(1.0, abs(float(u0 @ u1)))))
    return bool(angle >= np.radians(corner_angle) and 3.0 * np.sqrt(max(var0, var1)) <= np.radians(corner_angle))


def _direction(x: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, float]:
    """Total-least-squares direction (unit (2,)) of the points x (n, 2) [m] with position errors sd (n,)
    [m], and its variance Var φ = σ²/Σt² [rad²]: t the coordinates along the line, σ² the larger of
    the points' mean variance and their scatter about the line (which clutter or a corner raise)."""
    w, v = np.linalg.eigh(np.cov(x.T, bias=True))
    noise2 = max(float(np.mean(sd ** 2)), float(w[0]))
    return v[:, 1], noise2 / (len(x) * max(float(w[1]), 1e-300))


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


def snap_corners(walls: list, distance: float, corner_angle: float = 15.0) -> list:
    """Walls (``WallPosterior`` 'line's) meeting at a corner end at its vertex.

    An extent is the span of its points' projections, and the cut between two pieces of a corner
    falls a sample or two off the vertex: one wall's extent then runs on past the corner (its line
    crossed beyond the building) and the other's stops short of it. The mirror anchors a ray that
    passes near the corner to the extent it crosses (plugins.mirror.association), so a ray into the
    side street 0.2 m past a chamfer's end was mirrored through the chamfer, and its velocity came out
    reversed. For two lines whose directions differ by at least ``corner_angle`` [deg] and whose
    intersection c lies within ``distance`` [m] of an end of each extent, those two ends move to c;
    pairs are taken closest first, each end at most once. Returns the walls (new objects where an end
    moved, ``info["snapped_ends"]`` counting the moved ends); other models and walls without extent
    pass unchanged."""
    ends = {i: np.array(w.extent, dtype=np.float64) for i, w in enumerate(walls)
            if w.model == "line" and w.extent is not None}
    pairs = []
    keys = sorted(ends)
    for a, i in enumerate(keys):
        for j in keys[a + 1:]:
            ni, nj = walls[i].normal, walls[j].normal
            sin = abs(float(ni[0] * nj[1] - ni[1] * nj[0]))
            if sin < np.sin(np.radians(corner_angle)):
                continue
            c = np.linalg.solve(np.array([ni, nj]), -np.array([walls[i].offset, walls[j].offset]))
            di, dj = (np.linalg.norm(ends[k] - c, axis=1) for k in (i, j))
            ei, ej = int(np.argmin(di)), int(np.argmin(dj))
            if max(di[ei], dj[ej]) <= distance:
                pairs.append((max(di[ei], dj[ej]), i, ei, j, ej, c))
    used, moved = set(), {}
    for _, i, ei, j, ej, c in sorted(pairs, key=lambda p: p[0]):
        if (i, ei) in used or (j, ej) in used:
            continue
        used |= {(i, ei), (j, ej)}
        for k, e in ((i, ei), (j, ej)):
            ends[k][e] = c
            moved[k] = moved.get(k, 0) + 1
    return [replace(w, extent=ends[k], info={**w.info, "snapped_ends": moved[k]}) if k in moved else w
            for k, w in enumerate(walls)]
