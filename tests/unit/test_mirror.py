"""Mirror reconstructor (Eq. 7): involution, wall choice, covariance propagation, errors."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plugins.mirror.mirror import MirrorReconstructor
from xnlos_core import LOS, MNLOS, Detections, InsufficientDataError, WallPosterior
from xnlos_core.geometry import mirror_reflect


def detections(points, label=MNLOS, range_std=0.05, azimuth_std=0.01):
    return Detections.from_points(points, label, 1.0, range_std, azimuth_std)


def wall(n, b, extent=None, cov=None):
    return WallPosterior.line(np.asarray(n, float), b, cov=cov, extent=extent)


@settings(max_examples=200, deadline=None)
@given(phi=st.floats(-np.pi, np.pi), b=st.floats(0.5, 200.0), depth=st.floats(0.01, 100.0),
       along=st.floats(-100.0, 100.0))
def test_mirror_then_mirror_back_is_identity(phi, b, depth, along):
    n = np.array([np.cos(phi), np.sin(phi)])
    u = np.array([-n[1], n[0]])
    virtual = -(b + depth) * n + along * u  # behind the wall (nᵀo' + b = −depth < 0)
    hp = MirrorReconstructor({"gate": False}).reconstruct(detections(virtual), [wall(n, b)])  # the mirror alone
    assert len(hp) == 1 and hp.source_index.tolist() == [0] and hp.wall_index.tolist() == [0]
    o = hp.mean[0]
    scale = b + depth + abs(along)
    assert o @ n + b == pytest.approx(depth, abs=1e-9 * scale)  # mirrored onto the radar side
    assert np.allclose(mirror_reflect(o, n, b), virtual, atol=1e-9 * scale)


def two_wall_scene():
    a = wall([-1, 0], 20.0, extent=[[20, 2], [20, 12]])  # x = 20, y ∈ [2, 12]
    b = wall([0, 1], 8.0, extent=[[5, -8], [15, -8]])  # y = −8, x ∈ [5, 15]
    return [a, b]


def test_right_wall_picked_in_two_wall_scene():
    walls = two_wall_scene()
    # (30, −20) lies behind both lines and is nearer to the x = 20 line, but its ray crosses
    # the y = −8 segment (at x = 12): the ray test, not the distance, must decide.
    pts = [[5.0, 1.0], [30.0, 10.0], [10.0, -15.0], [30.0, -20.0]]
    det = detections(pts, [LOS, MNLOS, MNLOS, MNLOS])
    hp = MirrorReconstructor().reconstruct(det, walls)
    assert hp.source_index.tolist() == [1, 2, 3]
    assert hp.wall_index.tolist() == [0, 1, 1]
    assert np.allclose(hp.mean, [[10.0, 10.0], [10.0, -1.0], [30.0, 4.0]])


def test_first_crossing_wins_and_fallbacks():
    near = wall([-1, 0], 20.0, extent=[[20, 0], [20, 20]])
    far = wall([-1, 0], 25.0, extent=[[25, 0], [25, 20]])
    hp = MirrorReconstructor({"one_relay": False}).reconstruct(detections([[30.0, 10.0]]), [far, near])
    assert hp.wall_index.tolist() == [1]
    # behind two seen walls the relay is ambiguous: the gate does not report it (visibility rule 5)
    hp = MirrorReconstructor().reconstruct(detections([[30.0, 10.0]]), [far, near])
    assert len(hp) == 0 and hp.gated.tolist() == [0]
    # (30, −30): its ray passes below both extents (even with the 2 m margin).
    det = detections([[30.0, 10.0], [30.0, -30.0]])
    rec = MirrorReconstructor({"fallback": "drop"})
    hp = rec.reconstruct(det, [near])
    assert hp.source_index.tolist() == [0] and rec.last_unanchored_.tolist() == [1]
    rec = MirrorReconstructor({"fallback": "nearest", "gate": False})
    hp = rec.reconstruct(det, [near])
    assert hp.source_index.tolist() == [0, 1] and rec.last_unanchored_.size == 0
    # ... but its mirror image lies outside the wedge the wall's seen extent subtends: a ghost
    hp = MirrorReconstructor({"fallback": "nearest"}).reconstruct(det, [near])
    assert hp.source_index.tolist() == [0] and hp.gated.tolist() == [1]
    # A point in front of every wall line cannot be anchored even by "nearest".
    hp = rec.reconstruct(detections([[10.0, -30.0]]), [near])
    assert len(hp) == 0 and rec.last_unanchored_.tolist() == [0]


def test_covariance_psd_and_grows_with_wall_uncertainty():
    det = detections([[30.0, 10.0], [28.0, 4.0]])
    sure = MirrorReconstructor().reconstruct(det, [wall([-1, 0], 20.0)])
    unsure = MirrorReconstructor().reconstruct(det, [wall([-1, 0], 20.0, cov=np.diag([1e-3, 0.04]))])
    for hp in (sure, unsure):
        assert np.all(np.linalg.eigvalsh(hp.cov) >= -1e-15)
    assert np.all(np.linalg.eigvalsh(unsure.cov - sure.cov) >= -1e-15)
    assert np.all(np.trace(unsure.cov, axis1=1, axis2=2) > np.trace(sure.cov, axis1=1, axis2=2))
    # With a certain wall the map is an isometry: the detection covariance is only rotated.
    assert np.allclose(np.linalg.eigvalsh(sure.cov), np.linalg.eigvalsh(det.position_cov()))


def test_wall_covariance_propagation_matches_monte_carlo():
    rng = np.random.default_rng(0)
    cov = np.array([[4e-4, 1e-3], [1e-3, 1e-2]])
    w = wall([-1, 0], 20.0, cov=cov)
    det = detections([[30.0, 10.0]], range_std=0.0, azimuth_std=0.0)
    hp = MirrorReconstructor().reconstruct(det, [w])
    s = rng.multivariate_normal(w.mean, cov, size=20000)
    o = np.array([mirror_reflect(det.position[0], [np.cos(p), np.sin(p)], b) for p, b in s])
    assert np.allclose(np.cov(o.T), hp.cov[0], rtol=0.1, atol=1e-4)


def test_no_walls_with_mnlos_raises_with_count():
    with pytest.raises(InsufficientDataError, match="3 mNLOS detection"):
        MirrorReconstructor().reconstruct(detections([[30, 1], [31, 2], [32, 3]]), [])
    hp = MirrorReconstructor().reconstruct(detections([[5.0, 0.0]], LOS), [])
    assert len(hp) == 0
