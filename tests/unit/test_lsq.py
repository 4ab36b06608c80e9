"""Least-squares walls: exact recovery, clustering, covariance vs Monte Carlo, errors."""
import numpy as np
import pytest

from estimators.lsq import LSQWallEstimator, fit_line
from xnlos_core import LOS, MNLOS, Detections, InsufficientDataError, WallPosterior

pytestmark = pytest.mark.kernels  # numerically sensitive: `make test-kernels` runs it under several BLAS kernels

def detections(points, label=LOS, range_std=0.0, azimuth_std=0.0):
    return Detections.from_points(points, label, 1.0, range_std, azimuth_std)

def on_line(n, b, t):
    """Points on nᵀx + b = 0 at along-line coordinates t (from the foot point −b n)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    u = np.array([-n[1], n[0]])
    return -b * n + np.asarray(t, float)[:, None] * u

def test_exact_line_recovered():
    n = np.array([-1.0, -1.0]) / np.sqrt(2)  # wall x + y = 25, radar side positive
    pts = on_line(n, 25 / np.sqrt(2), np.linspace(-8, 8, 30))
    (w,) = LSQWallEstimator().estimate(detections(pts))
    assert np.allclose(w.normal, n, atol=1e-9)
    assert w.offset == pytest.approx(25 / np.sqrt(2), abs=1e-9)
    assert w.info["residual_rms"] < 1e-9 and w.info["cluster_size"] == 30 and w.n_points == 30
    assert np.allclose(w.cov, 0, atol=1e-18)
    assert np.allclose(np.sort(w.extent[:, 0]), [25 / 2 - 8 / np.sqrt(2), 25 / 2 + 8 / np.sqrt(2)])
    assert w.info["detection_index"] == list(range(30))

def test_two_walls_two_posteriors_largest_first_and_mnlos_ignored():
    a = on_line([-1, 0], 20.0, np.linspace(2, 12, 21))  # x = 20
    b = on_line([0, -1], 8.0, np.linspace(-10, -2, 9))  # y = 8
    pts = np.concatenate([b, a, [[40.0, 40.0]]])
    labels = np.r_[np.full(len(b) + len(a), LOS), MNLOS]
    walls = LSQWallEstimator().estimate(detections(pts, labels))
    assert [w.n_points for w in walls] == [21, 9]
    assert np.allclose(walls[0].normal, [-1, 0]) and walls[0].offset == pytest.approx(20)
    assert np.allclose(walls[1].normal, [0, -1]) and walls[1].offset == pytest.approx(8)
    assert sorted(walls[1].info["detection_index"]) == list(range(9))

def test_covariance_matches_monte_carlo():
    rng = np.random.default_rng(7)
    n_true, b_true, sigma = np.array([-1.0, 0.0]), 20.0, 0.15
    base = on_line(n_true, b_true, np.linspace(-15, -3, 25))  # x = 20, y ∈ [3, 15]: strong φ–b coupling
    draws, covs = [], []
    for _ in range(3000):
        w = fit_line(base + sigma * rng.standard_normal(base.shape))
        draws.append(w.mean)
        covs.append(w.cov)
    draws = np.array(draws)
    draws[:, 0] = np.angle(np.exp(1j * (draws[:, 0] - np.pi)))  # φ near π: unwrap around it
    emp = np.cov(draws.T)
    pred = np.mean(covs, axis=0)
    assert pred[0, 0] == pytest.approx(emp[0, 0], rel=0.2)
    assert pred[1, 1] == pytest.approx(emp[1, 1], rel=0.2)
    assert pred[0, 1] == pytest.approx(emp[0, 1], rel=0.2)
    assert abs(emp[0, 1]) / np.sqrt(emp[0, 0] * emp[1, 1]) > 0.5  # the cross term matters here
    # The estimator path (detections → clusters → fit) gives the same answer as fit_line.
    noisy = base + sigma * rng.standard_normal(base.shape)
    (w,) = LSQWallEstimator().estimate(detections(noisy))
    assert np.allclose(w.cov, fit_line(noisy).cov)

def test_two_points_use_detection_covariance():
    pts = on_line([-1, 0], 20.0, [-5.0, -4.0])
    (w,) = LSQWallEstimator().estimate(detections(pts, range_std=0.1, azimuth_std=0.01))
    assert w.n_points == 2 and w.cov[0, 0] > 0 and w.cov[1, 1] > 0
    assert np.linalg.eigvalsh(w.cov).min() >= 0

def test_fewer_than_two_los_points_raise_with_count():
    det = detections([[10.0, 0.0], [20.0, 5.0], [30.0, 1.0]], [LOS, MNLOS, MNLOS])
    with pytest.raises(InsufficientDataError, match=r"1 LOS detection\(s\) among 3 detections.*at least 2"):
        LSQWallEstimator().estimate(det)
    with pytest.raises(InsufficientDataError, match="0 LOS"):
        LSQWallEstimator().estimate(Detections.empty())

def test_min_points_fallback_and_isolated_points():
    pairs = np.array([[10.0, 0.0], [10.0, 1.0], [30.0, 0.0], [30.0, 1.5], [30.0, 3.0]])
    walls = LSQWallEstimator({"min_points": 4}).estimate(detections(pairs))
    assert len(walls) == 1 and walls[0].n_points == 3  # largest cluster, below min_points
    far = np.array([[10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    with pytest.raises(InsufficientDataError, match="cluster_distance"):
        LSQWallEstimator().estimate(detections(far))
    with pytest.raises(InsufficientDataError, match="coincide"):
        LSQWallEstimator().estimate(detections([[10.0, 0.0], [10.0, 0.0]]))

def test_wall_posterior_flip_negates_cross_covariance():
    cov = np.array([[0.01, 0.02], [0.02, 0.09]])
    w = WallPosterior("line", np.array([0.0, -5.0]), cov)  # b < 0: canonical form flips n
    assert w.offset == 5.0 and np.allclose(w.normal, [-1, 0])
    assert np.allclose(w.cov, [[0.01, -0.02], [-0.02, 0.09]])

def test_a_seen_building_corner_gives_one_wall_per_facade():
    # Far block of a crossroads: facade y = −7 (x ≥ 19) and facade x = 17 (y ≤ −9), joined by a
    # chamfer; 0.25 m apart, they chain into one single-linkage cluster. One TLS line through that L
    # was a wall that is not there (φ ≈ 2.1 rad); the corner split gives the three facades.
    rng = np.random.default_rng(3)
    front = np.c_[np.arange(19.0, 33.0, 0.25), np.full(56, -7.0)]
    chamfer = np.c_[np.linspace(18.8, 17.2, 8), np.linspace(-7.2, -8.8, 8)]
    side = np.c_[np.full(41, 17.0), np.arange(-9.0, -19.25, -0.25)]
    pts = np.concatenate([front, chamfer, side]) + rng.normal(0, 0.05, (105, 2))
    walls = LSQWallEstimator().estimate(detections(pts))
    assert len(walls) == 3
    (a, b, c) = walls
    for w, normal, offset in ((a, [0, 1], 7.0), (b, [-1, 0], 17.0)):  # within 3σ of their own posterior
        sd_phi, sd_b = np.sqrt(np.diag(w.cov))
        assert np.arccos(min(1.0, float(w.normal @ normal))) < 3 * sd_phi and abs(w.offset - offset) < 3 * sd_b
    assert np.allclose(c.normal, np.array([-1, 1]) / np.sqrt(2), atol=0.1)  # x − y = 26
    assert sorted(i for w in walls for i in w.info["detection_index"]) == list(range(105))


def test_split_corners_keeps_straight_walls_arcs_and_outliers_whole():
    from estimators.corners import split_corners

    rng = np.random.default_rng(5)
    wall = on_line([-1, 0], 25.0, np.linspace(-10, 10, 60)) + rng.normal(0, 0.2, (60, 2))
    assert [len(p) for p in split_corners(wall, 1.0)] == [60]
    with_outlier = np.concatenate([wall, [[22.0, 0.05]]])  # 3 m in front of the wall: not a corner
    assert [len(p) for p in split_corners(with_outlier, 1.0)] == [61]
    # a curved facade, radius 20 m over a 25 m chord (sagitta 4.2 m, 77° of turn): the 'arc' model's
    t = np.linspace(-0.65, 0.65, 80)
    arc = np.c_[45.0 - 20.0 * np.cos(t), 20.0 * np.sin(t)] + rng.normal(0, 0.1, (80, 2))
    assert [len(p) for p in split_corners(arc, 1.0)] == [80]
    corner = np.concatenate([np.c_[np.full(40, 25.0), np.linspace(-12, -2, 40)],  # a block's two seen facades
                             np.c_[np.linspace(25.25, 35, 40), np.full(40, -2.0)]]) + rng.normal(0, 0.1, (80, 2))
    assert sorted(len(p) for p in split_corners(corner, 1.0)) == [40, 40]
    # a block corner cut by a 10.5 m chamfer: three facades, bending by 45° twice (one circle through
    # them fits better than two lines; the polyline of three fits better than the circle)
    a = np.c_[np.linspace(31.7, 26.8, 20), np.full(20, -8.8)]
    chamfer = np.c_[np.linspace(26.4, 19.0, 42), np.linspace(-9.0, -16.4, 42)]
    b = np.c_[np.full(44, 18.8), np.linspace(-16.8, -27.4, 44)]
    three = np.concatenate([a, chamfer, b]) + rng.normal(0, 0.2, (106, 2))
    sizes = sorted(len(p) for p in split_corners(three, 1.0, sigma=np.full(106, 0.25)))
    assert len(sizes) == 3 and np.allclose(sizes, [20, 42, 44], atol=2), sizes


@pytest.mark.parametrize("seed", range(5))
def test_a_short_chamfer_beside_a_short_facade_needs_the_smaller_split_tolerance(seed):
    # A facade seen over 3 m and a 3.4 m chamfer at 45° beside it (a crossroads' far corner, dense LOS
    # points of 0.1 m noise, 0.2 m stated σ): the corner lies ≈ 0.9 m off the chord of the cluster's ends,
    # so at split_tolerance 1 m they stay one wall 20° off both; the tracking ablation's 0.5 m splits
    # them, and does not cut a straight facade of the same noise.
    from estimators.corners import split_corners

    rng = np.random.default_rng(seed)
    facade = np.c_[np.full(20, 24.6), np.linspace(9.0, 12.0, 20)]
    chamfer = np.array([24.6, 9.0]) + np.linspace(0, 1, 11)[1:, None] * np.array([2.4, -2.4])
    pts = np.concatenate([facade, chamfer]) + rng.normal(0, 0.1, (30, 2))
    sigma = np.full(30, 0.2)
    assert len(split_corners(pts, 1.0, 15.0, sigma)) == 1
    pieces = split_corners(pts, 0.5, 15.0, sigma)
    assert len(pieces) == 2
    short = min(pieces, key=len)  # the chamfer, with at most the facade's points within 0.6 m of the corner
    assert set(range(20, 30)) - set(short.tolist()) <= {20} and np.sum(short < 20) <= 4, pieces
    straight = np.c_[np.full(40, 24.6), np.linspace(0.0, 8.0, 40)] + rng.normal(0, 0.1, (40, 2))
    assert len(split_corners(straight, 0.5, 15.0, np.full(40, 0.2))) == 1


@pytest.mark.parametrize("seed", range(5))
def test_three_runs_meeting_at_a_corner_are_three_walls(seed):
    # A facade (x = 19.9, y 9.6…13.3), the chamfer below it (45°, 6.2 m) and a road user's side beside
    # the corner (4.4 m to the lower left): three runs of LOS points meeting in a T, not an L. One chain
    # order interleaves two of them and no cut of it is a corner: one line 35° off every run came out.
    # Taking the arm off the spanning tree's longest path first gives each run its wall.
    from estimators.corners import split_corners

    rng = np.random.default_rng(seed)
    facade = np.c_[np.full(60, 19.9), np.linspace(9.6, 13.3, 60)]
    chamfer = np.array([19.9, 9.3]) + np.linspace(0, 1, 70)[:, None] * np.array([4.4, -4.4])
    side = np.array([19.6, 9.3]) + np.linspace(0.05, 1, 40)[:, None] * np.array([-3.6, -2.6])
    pts = np.concatenate([facade, chamfer, side]) + rng.normal(0, 0.15, (170, 2))
    pieces = split_corners(pts, 0.5, 15.0, np.full(170, 0.23))
    assert len(pieces) == 3
    for truth, n in ((range(60), [-1, 0]), (range(60, 130), [-1, -1]), (range(130, 170), [-2.6, 3.6])):
        piece = max(pieces, key=lambda p: len(set(p.tolist()) & set(truth)))
        assert len(set(piece.tolist()) ^ set(truth)) <= 3, (len(piece), len(truth))
        n = np.asarray(n, float) / np.linalg.norm(n)
        assert abs(fit_line(pts[piece]).normal @ n) > np.cos(np.radians(3.0))


def test_noise_and_clutter_hanging_off_a_facade_are_no_arms():
    # A straight facade with every tenth point 1 m off (N(0, 1) across it) and a noisy L corner: the
    # spanning tree's longest path wanders through stray points, and what hangs off it stays on the
    # path's wall — one piece, and two.
    from estimators.corners import split_corners

    for seed in range(20):
        rng = np.random.default_rng(seed)
        wall = np.c_[np.full(200, 25.0), np.linspace(-12, 8, 200)] + rng.normal(0, 0.1, (200, 2))
        ends = np.r_[np.arange(20), np.arange(180, 200)]
        wall[ends[::4], 0] += rng.choice([-1.0, 1.0], 10) * rng.uniform(0.7, 1.2, 10)
        assert len(split_corners(wall, 0.5, 15.0, np.full(200, 0.2))) == 1, seed
        corner = np.concatenate([np.c_[np.full(120, 25.0), np.linspace(-12, -2, 120)],
                                 np.c_[np.linspace(25.2, 35, 120), np.full(120, -2.0)]]) + rng.normal(0, 0.2, (240, 2))
        assert len(split_corners(corner, 0.5, 15.0, np.full(240, 0.25))) == 2, seed


def test_collinear_facades_across_a_street_stay_two_walls_where_the_radar_sees_through():
    # Facade y = 8 of the near block (x ≤ 6) and of the far block (x ≥ 16): one line, with the cross
    # street's mouth between. Sparse pieces of one wall are merged (no LOS point beyond the gap), but
    # here the radar sees a facade of the cross street (x = 20, y ≥ 13) through the gap: one wall across
    # the mouth would claim every ray into the street.
    near = np.c_[np.linspace(2, 6, 17), np.full(17, 8.0)]
    far = np.c_[np.linspace(16, 30, 57), np.full(57, 8.0)]
    merged = LSQWallEstimator().estimate(detections(np.concatenate([near, far])))
    assert [w.n_points for w in merged] == [74]
    seen = np.c_[np.full(20, 20.0), np.linspace(13.0, 17.75, 20)]  # through the gap (rays cross y = 8 at x ≈ 8–12)
    walls = LSQWallEstimator().estimate(detections(np.concatenate([near, far, seen])))
    along_y8 = [w for w in walls if np.allclose(w.normal, [0, -1], atol=1e-6)]
    assert sorted(w.n_points for w in along_y8) == [17, 57]


@pytest.mark.parametrize("shape", ["wall", "corner", "blob", "collinear", "duplicates"])
def test_the_delaunay_spanning_tree_is_the_all_pairs_one(shape):
    """From DELAUNAY_FROM points spanning_tree searches only the Delaunay edges: the same Euclidean
    MST (every edge, not only its length) as the tree of all pairs, and all pairs where Qhull cannot
    triangulate (points on one line, exact duplicates)."""
    from scipy.sparse.csgraph import minimum_spanning_tree
    from scipy.spatial.distance import pdist, squareform

    from estimators.corners import DELAUNAY_FROM, spanning_tree

    rng = np.random.default_rng(11)
    n = DELAUNAY_FROM + 150
    t = rng.uniform(0.0, 20.0, n)
    x = {"wall": np.c_[t, 0.3 * t + rng.normal(0, 0.1, n)],
         "corner": np.where((t < 10)[:, None], np.c_[t, 0 * t], np.c_[10 + 0 * t, t - 10]) + rng.normal(0, 0.05, (n, 2)),
         "blob": rng.normal(0.0, 5.0, (n, 2)),
         "collinear": np.c_[t, 2.0 * t],
         "duplicates": np.r_[rng.normal(0.0, 5.0, (n - 3, 2)), np.zeros((3, 2))]}[shape]
    fast = spanning_tree(x)
    full = minimum_spanning_tree(squareform(pdist(x)) + 1e-12 * (1.0 - np.eye(n)))
    edges = lambda tree: {tuple(sorted(e)) for e in zip(*tree.nonzero())}  # noqa: E731
    assert fast.nnz == n - 1 and edges(fast) == edges(full)
    assert fast.sum() == pytest.approx(full.sum(), rel=1e-12)


def test_walls_meeting_at_a_corner_end_at_its_vertex():
    # A chamfer (y = x − 36.18, from (27.86, −8.32) to (20.32, −15.86)) and the side street's facade
    # (x = 20.32, y ≤ −15.86). The chamfer's piece took two facade points by the corner, so its extent
    # runs 0.5 m on past the vertex, and the facade's starts 0.35 m short of it: the ray to a virtual
    # point 0.2 m past the corner crossed the chamfer's extent and was mirrored through it, while the
    # wave went by way of the facade. Snapped, both walls end at the lines' intersection, and the
    # anchoring takes the facade.
    from dataclasses import replace

    from estimators.corners import snap_corners
    from plugins.mirror.association import anchor_points

    chamfer_pts = np.c_[np.linspace(27.86, 20.32, 30), np.linspace(-8.32, -15.86, 30)]
    facade_pts = np.c_[np.full(40, 20.32), np.linspace(-16.2, -30.0, 40)]
    chamfer = fit_line(np.concatenate([chamfer_pts, [[20.32, -16.1], [20.32, -16.3]]]))
    chamfer = replace(chamfer, mean=np.array([np.arctan2(-1, 1) + np.pi, 36.18 / np.sqrt(2)]))  # its true line
    facade = fit_line(facade_pts)
    vertex = np.array([20.32, -15.86])
    assert np.linalg.norm(chamfer.extent - vertex, axis=1).min() > 0.3  # overshoots
    assert np.linalg.norm(facade.extent - vertex, axis=1).min() > 0.3  # stops short
    virtual = np.array([[21.88, -17.3]])  # its ray meets x = 20.32 at y = −16.04, 0.18 m past the corner
    assert anchor_points(virtual, [chamfer, facade]).wall_index.tolist() == [0]
    snapped = snap_corners([chamfer, facade], 1.0)
    for w in snapped:
        assert np.linalg.norm(w.extent - vertex, axis=1).min() == pytest.approx(0.0, abs=1e-9)
        assert w.info["snapped_ends"] == 1
    assert anchor_points(virtual, snapped).wall_index.tolist() == [1]
    # a corner farther than the distance, or two parallel walls, keep their extents
    assert snap_corners([chamfer, facade], 0.2)[0] is chamfer
    parallel = fit_line(np.c_[np.full(20, 30.0), np.linspace(-16.2, -30.0, 20)])
    assert snap_corners([facade, parallel], 5.0) == [facade, parallel]
