"""Wall fits on large LOS clouds run in bounded memory: single linkage and the corner splitter's
spanning tree beyond DENSE_MAX points need O(N) memory (for 20,000 points the condensed distances and
linkage took 1.9 GB, the tree's all-pairs fallback needs 6.4 GB), and the probabilistic estimators fit
a seeded subsample of max_fit_points per wall that keeps the wall's two ends."""
import tracemalloc
import warnings

import numpy as np
import pytest
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial.distance import pdist

from estimators.corners import DENSE_MAX, mst_edges, spanning_tree
from estimators.lsq import single_linkage
from xnlos_core.registry import get_registry
from xnlos_core.types import LOS, Detections

MiB = 1 << 20


def peak_bytes(fn, *args):
    tracemalloc.start()
    try:
        out = fn(*args)
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def wall(n, rng, noise=0.05):
    return np.c_[np.full(n, 8.0), np.linspace(-30, 30, n)] + rng.standard_normal((n, 2)) * noise


def same_partition(a, b) -> bool:
    return len(set(zip(a.tolist(), b.tolist()))) == len(set(a.tolist())) == len(set(b.tolist()))


def test_single_linkage_of_20000_points_in_bounded_memory():
    rng = np.random.default_rng(0)
    for pts in (wall(20_000, rng), rng.standard_normal((20_000, 2)) * 40,
                np.c_[np.full(20_000, 8.0), np.linspace(-30, 30, 20_000)]):  # exactly collinear: Qhull fails
        labels, peak = peak_bytes(single_linkage, pts, 4.0)
        assert peak < 64 * MiB, peak / MiB  # the condensed distances alone are 1.5 GiB
        assert labels.shape == (20_000,) and labels.min() == 0


@pytest.mark.parametrize("kind", ["cloud", "duplicates", "collinear", "grid"])
def test_large_single_linkage_gives_linkages_clusters(kind):
    """Beyond DENSE_MAX the clusters are the same as scipy's linkage (numbered by first appearance)."""
    rng = np.random.default_rng(1)
    n = DENSE_MAX + 700
    pts = {"cloud": rng.standard_normal((n, 2)) * 30,
           "duplicates": np.repeat(rng.standard_normal((n // 4 + 1, 2)) * 50, 4, axis=0)[:n],
           "collinear": np.c_[np.linspace(-100, 100, n), np.linspace(-100, 100, n) * 0.5 + 3],
           "grid": np.round(rng.standard_normal((n, 2)) * 20)}[kind]
    for d in (1e-3, 0.7, 4.0):
        ours = single_linkage(pts, d)
        ref = fcluster(linkage(pdist(pts), method="single"), t=d, criterion="distance") - 1
        assert same_partition(ours, ref), (kind, d)
        _, first = np.unique(ours, return_index=True)
        assert np.all(np.diff(first) > 0)  # labels in order of first appearance


def test_up_to_dense_max_single_linkage_is_unchanged():
    pts = np.random.default_rng(2).standard_normal((DENSE_MAX, 2)) * 30
    ref = fcluster(linkage(pdist(pts), method="single"), t=4.0, criterion="distance") - 1
    assert np.array_equal(single_linkage(pts, 4.0), ref)


def test_spanning_tree_of_20000_collinear_points_in_bounded_memory():
    """Qhull cannot triangulate collinear points; the all-pairs fallback took 6.4 GB at 20,000."""
    x = np.c_[np.full(20_000, 8.0), np.linspace(-30, 30, 20_000)]
    tree, peak = peak_bytes(spanning_tree, x)
    assert peak < 64 * MiB, peak / MiB
    assert tree.nnz == len(x) - 1
    assert tree.sum() == pytest.approx(60.0 + (len(x) - 1) * 1e-12, rel=1e-9)  # the chain


@pytest.mark.parametrize("kind", ["cloud", "duplicates", "collinear"])
def test_mst_edges_is_a_minimum_spanning_tree(kind):
    rng = np.random.default_rng(3)
    n = 600
    x = {"cloud": rng.standard_normal((n, 2)), "collinear": np.c_[rng.uniform(-5, 5, n), np.zeros(n)],
         "duplicates": np.repeat(rng.standard_normal((n // 3, 2)), 3, axis=0)}[kind]
    i, j = mst_edges(x)
    assert len(i) == len(x) - 1
    ii, jj = np.triu_indices(len(x), 1)
    ref = minimum_spanning_tree(coo_matrix((pdist(x) + 1e-12, (ii, jj)), shape=(len(x),) * 2).tocsr())
    assert np.hypot(*(x[i] - x[j]).T).sum() == pytest.approx(ref.sum() - (len(x) - 1) * 1e-12, rel=1e-12, abs=1e-12)


def detections(pts):
    n = len(pts)
    return Detections.from_points(pts, label=np.full(n, LOS), range_std=np.full(n, 0.05),
                                  azimuth_std=np.full(n, 0.005))


def test_lsq_fits_a_20000_point_wall_in_bounded_memory():
    est = get_registry().create("wall_estimator", "lsq", {})
    det = detections(wall(20_000, np.random.default_rng(4)))
    (w,), peak = peak_bytes(est.estimate, det)
    assert peak < 128 * MiB, peak / MiB
    assert w.n_points == 20_000 and w.offset == pytest.approx(8.0, abs=0.01)


FAST = {"emcee": {"n_walkers": 8, "n_steps": 40, "burn": 10, "min_ess": 0.0}, "laplace_is": {"fallback": False}}


@pytest.mark.parametrize("name", ["casadi_map", "laplace_is", "emcee"])
def test_probabilistic_estimators_fit_a_seeded_subsample_of_a_large_wall(name):
    """A wall of N > max_fit_points LOS points is fitted to a seeded subsample (the same on every run);
    info names both sizes; a wall within the bound is fitted whole, as before."""
    det = detections(wall(300, np.random.default_rng(5)))

    def fit(m):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # short test chains
            (w,) = get_registry().create("wall_estimator", name, {"max_fit_points": m, **FAST.get(name, {})}).estimate(det)
        return w

    w, again = fit(64), fit(64)
    assert w.n_points == 64 and w.info["fitted_points"] == 64 and w.info["cluster_size"] == 300
    assert len(w.info["detection_index"]) == 300
    assert np.array_equal(w.mean, again.mean) and np.array_equal(w.cov, again.cov)
    assert w.offset == pytest.approx(8.0, abs=0.05)
    assert float(np.ptp(w.extent[:, 1])) == pytest.approx(60.0, abs=0.5)  # the subsample keeps the wall's ends
    whole = fit(300)
    assert whole.n_points == 300 and "fitted_points" not in whole.info
