"""Constant-velocity Kalman tracker: closed-form filter steps, gating, M-of-N birth, K-miss death."""
import numpy as np
import pytest

from estimators.trackers.kalman import KalmanTracker, cluster_measurements, cv_transition
from xnlos_core import ConfigError, HiddenPoints, InputError
from xnlos_core.testing import check_component


def hidden(points, sigma=0.1):
    pts = np.asarray(points, float).reshape(-1, 2)
    k = len(pts)
    return HiddenPoints(pts, np.tile(sigma ** 2 * np.eye(2), (k, 1, 1)), np.arange(k), np.zeros(k))


def test_conformance_kit():
    check_component("tracker", "kalman")


def test_transition_matches_white_noise_acceleration_closed_form():
    F, Q = cv_transition(0.5, 2.0)
    assert np.allclose(F @ [1.0, 2.0, 3.0, -4.0], [2.5, 0.0, 3.0, -4.0])
    assert Q[0, 0] == pytest.approx(2.0 * 0.5 ** 3 / 3) and Q[0, 2] == pytest.approx(2.0 * 0.5 ** 2 / 2)
    assert Q[2, 2] == pytest.approx(1.0) and Q[0, 1] == 0.0


def test_cluster_covariance_is_mean_of_independent_points():
    pts = HiddenPoints(np.array([[0.0, 0.0], [1.0, 0.0], [50.0, 0.0]]),
                       np.array([np.eye(2) * 0.04, np.eye(2) * 0.16, np.eye(2) * 0.09]), [0, 1, 2], [0, 0, 0])
    z, R = cluster_measurements(pts, 2.0, floor=0.1)
    order = np.argsort(z[:, 0])
    assert np.allclose(z[order], [[0.5, 0.0], [50.0, 0.0]])
    assert np.allclose(R[order][:, 0, 0], [(0.04 + 0.16) / 4 + 0.01, 0.09 + 0.01])


def test_noisy_constant_velocity_converges_with_one_id():
    rng = np.random.default_rng(1)
    v = np.array([3.0, -2.0])
    tracker = KalmanTracker({"accel_psd": 0.1})
    for k in range(50):
        t = 0.1 * k
        tracks = tracker.update(hidden(np.array([20.0, 5.0]) + v * t + 0.1 * rng.standard_normal(2)), t)
        if k >= 1:
            assert tracks.track_id.tolist() == [0]
    assert np.linalg.norm(tracks.velocity[0] - v) < 0.3
    assert np.linalg.norm(tracks.position[0] - (np.array([20.0, 5.0]) + v * 4.9)) < 0.15
    assert np.allclose(tracks.predicted[0], tracks.position[0] + 0.1 * tracks.velocity[0])


def test_m_of_n_birth_and_k_miss_death():
    tracker = KalmanTracker({"confirm_hits": 2, "confirm_window": 3, "max_misses": 2})
    assert len(tracker.update(hidden([[0.0, 0.0]]), 0.0)) == 0          # tentative: not reported
    assert len(tracker.update(hidden(np.empty((0, 2))), 0.1)) == 0     # 1 hit in 2 frames: still tentative
    assert tracker.update(hidden([[0.0, 0.0]]), 0.2).track_id.tolist() == [0]  # 2 of 3: confirmed
    assert tracker.update(hidden(np.empty((0, 2))), 0.3).track_id.tolist() == [0]  # one miss: coasts
    assert len(tracker.update(hidden(np.empty((0, 2))), 0.4)) == 0     # second miss: deleted
    tracker.reset()
    tracker.update(hidden([[0.0, 0.0]]), 0.0)
    tracker.update(hidden(np.empty((0, 2))), 0.1)
    tracker.update(hidden(np.empty((0, 2))), 0.2)                     # 1 of 3: the tentative track dies
    assert tracker.update(hidden([[0.0, 0.0]]), 0.3).track_id.tolist() == []
    assert tracker.update(hidden([[0.0, 0.0]]), 0.4).track_id.tolist() == [1]


def _gap_run(lost_frames: int, gap: range, n: int = 30) -> list[list[int]]:
    """Reported ids, frame by frame, of a car at 5 m/s missed in the frames ``gap``."""
    tracker = KalmanTracker({"accel_psd": 0.5, "max_misses": 3, "lost_frames": lost_frames})
    out = []
    for k in range(n):
        t = 0.1 * k
        pts = np.empty((0, 2)) if k in gap else [[20.0 + 5.0 * t, 3.0]]
        out.append(tracker.update(hidden(pts, 0.1), t).track_id.tolist())
    return out


def test_a_lost_track_is_hidden_then_revived_with_its_id():
    # missed in frames 10–15: 2 misses coast (reported), from the 3rd (= max_misses) the track is lost
    ids = _gap_run(lost_frames=8, gap=range(10, 16))
    assert ids[9] == ids[10] == ids[11] == [0]
    assert all(i == [] for i in ids[12:16])        # lost: not reported, no new track
    assert ids[16] == []                             # the next hit revives it, tentative (1 of M = 2 hits)
    assert ids[17] == [0] and ids[-1] == [0]        # confirmed anew: the same id
    ids = _gap_run(lost_frames=0, gap=range(10, 16))
    assert ids[16] == [] and ids[-1] == [1]         # without the buffer: deleted, a new (tentative) track
    ids = _gap_run(lost_frames=2, gap=range(10, 16))  # the gap (6 frames) outlasts K + L = 5 misses
    assert ids[-1] == [1]


def test_a_lost_track_survives_a_checkpoint():
    params = {"accel_psd": 0.5, "max_misses": 3, "lost_frames": 8}
    tracker = KalmanTracker(params)
    for k in range(14):                                    # seen in frames 0–9, lost from frame 12 on
        tracker.update(hidden(np.empty((0, 2)) if k >= 10 else [[20.0 + 0.5 * k, 3.0]]), 0.1 * k)
    resumed = KalmanTracker(params)
    resumed.load_state(tracker.state())
    for tr in (tracker, resumed):
        assert tr.update(hidden([[27.0, 3.0]]), 1.4).track_id.tolist() == []       # revived, tentative
        assert tr.update(hidden([[27.5, 3.0]]), 1.5).track_id.tolist() == [0]


def test_a_lost_track_takes_only_what_the_held_tracks_leave():
    # A lost track, coasted far, has a wide gate; it must not take a held track's measurement.
    tracker = KalmanTracker({"confirm_hits": 1, "max_misses": 1, "lost_frames": 50, "accel_psd": 0.5})
    tracker.update(hidden([[0.0, 0.0], [30.0, 0.0]]), 0.0)               # tracks 0 (at 0) and 1 (at 30)
    for k in range(1, 20):                                                # track 0 lost, track 1 held
        tracker.update(hidden([[30.0, 0.0]]), 0.1 * k)
    # 3 m off track 1 (d² ≈ 8, within its gate), nearer in Mahalanobis terms to lost track 0 (σ ≈ 19 m)
    assert tracker.update(hidden([[33.0, 0.0]]), 2.0).track_id.tolist() == [1]
    assert [tr["misses"] for tr in tracker.state()["tracks"]] == [20, 0]
    # its measurement left over, the lost track takes it back (confirmed at once: M = 1)
    assert sorted(tracker.update(hidden([[30.0, 0.0], [0.5, 0.0]]), 2.1).track_id.tolist()) == [0, 1]


def test_a_false_alarm_does_not_bring_a_lost_track_back():
    # one hit near a lost track's prediction makes it tentative; without a second hit in N frames it is deleted
    tracker = KalmanTracker({"accel_psd": 0.5, "max_misses": 3, "lost_frames": 10})
    for k in range(10):
        tracker.update(hidden([[20.0, 3.0]]), 0.1 * k)
    for k in range(10, 14):
        tracker.update(hidden(np.empty((0, 2))), 0.1 * k)       # lost from frame 12
    assert tracker.update(hidden([[20.2, 3.0]]), 1.4).track_id.tolist() == []
    for k in range(15, 17):
        assert tracker.update(hidden(np.empty((0, 2))), 0.1 * k).track_id.tolist() == []
    assert tracker.state()["tracks"] == []


def test_mahalanobis_gate_uses_measurement_covariance():
    # The same 2 m jump is inside the gate for a 1 m measurement σ and outside it for 0.05 m.
    for sigma, same in ((1.0, True), (0.05, False)):
        tracker = KalmanTracker({"confirm_hits": 1, "initial_speed_sigma": 0.1, "extent_sigma": 0.0})
        tracker.update(hidden([[0.0, 0.0]], sigma), 0.0)
        ids = tracker.update(hidden([[2.0, 0.0]], sigma), 0.1).track_id.tolist()
        assert (ids == [0]) is same


def test_crossing_targets_keep_their_ids():
    tracker = KalmanTracker({"accel_psd": 0.5, "cluster_distance": 0.5})
    for k in range(30):
        t = 0.1 * k
        a, b = np.array([10.0 + 5 * t, 0.0 + 5 * t]), np.array([10.0 + 5 * t, 15.0 - 5 * t])
        tracks = tracker.update(hidden([a, b], 0.05), t)
    ids = dict(zip(tracks.track_id.tolist(), tracks.position[:, 1]))
    assert ids[0] > ids[1]  # track 0 was born at y = 0 and moves up; it crossed track 1


def test_errors():
    tracker = KalmanTracker()
    tracker.update(hidden([[0.0, 0.0]]), 1.0)
    with pytest.raises(InputError, match="must not decrease"):
        tracker.update(hidden([[0.0, 0.0]]), 0.5)
    with pytest.raises(InputError, match="expected HiddenPoints"):
        tracker.update(np.zeros((1, 2)), 2.0)
    with pytest.raises(ConfigError, match="confirm_window"):
        KalmanTracker({"confirm_hits": 4, "confirm_window": 3})


def test_a_seen_side_moves_to_the_objects_centre_along_the_view():
    from estimators.trackers.measurements import cluster

    # a car (4.5 m × 1.8 m, centre (10, −20)) seen broadside along +y (its bounce point south of it):
    # the seen face y = −20.9 spans 4.5 m, its centroid is 0.9 m in front of the centre
    face = np.c_[np.linspace(7.75, 12.25, 10), np.full(10, -20.9)]
    view = np.tile([0.0, 1.0], (10, 1))
    pts = HiddenPoints(face, np.tile(0.01 * np.eye(2), (10, 1, 1)), np.arange(10), np.zeros(10), view=view)
    z = cluster(pts, 5.0, 0.1, depth_ratio=0.2).z
    assert np.allclose(z, [[10.0, -20.9 + 0.2 * 4.5]])  # W/(2L) = 0.2: the centre exactly
    assert np.allclose(cluster(pts, 5.0, 0.1).z, [[10.0, -20.9]])  # depth_ratio 0: the centroid
    plain = HiddenPoints(face, pts.cov, pts.source_index, pts.wall_index)  # no view: the centroid
    assert np.allclose(cluster(plain, 5.0, 0.1, depth_ratio=0.2).z, [[10.0, -20.9]])


def test_one_doppler_row_per_relay_wall_sees_the_full_velocity():
    # A car at v = (4, −3) m/s seen through two relay walls along perpendicular mirrored lines of sight
    # ±x̂ and ±ŷ (points of wall 0 and wall 1): per wall one row with y = ĝᵀv exactly, and a new
    # track's update from the prior v = 0, P_v = σ_v² I recovers v·σ_v²/(σ_v² + s) exactly. One row per
    # cluster mixes them: ĝ_c on the bisector, y_c the mean of the two projections — not ĝ_cᵀv.
    from estimators.trackers.measurements import cluster

    v, var, floor, sv = np.array([4.0, -3.0]), 0.04, 0.1, 10.0
    g = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]])
    w = (g @ v)[:, None] * g                                   # each point's observed component y_i ĝ_i
    pts = HiddenPoints(np.array([[20.0, 5.0], [20.5, 5.2], [20.2, 4.8], [19.8, 5.1]]), np.tile(0.01 * np.eye(2), (4, 1, 1)),
                       np.arange(4), np.array([0, 0, 1, 1]), velocity=w, velocity_cov=var * g[:, :, None] * g[:, None, :])
    walls = cluster(pts, 5.0, 0.1, floor, doppler_rows="wall")
    s = (var + floor ** 2) / 2                                   # two points per wall
    assert walls.rows_g.shape == (1, 2, 2) and np.allclose(walls.rows_s, s)
    assert np.allclose(walls.rows_g[0] @ v, walls.rows_y[0])  # each row is exact: y = ĝᵀv
    assert np.allclose(np.abs(walls.rows_g[0]), np.eye(2)[::1 if abs(walls.rows_g[0, 0, 0]) > 0.5 else -1])
    one = cluster(pts, 5.0, 0.1, floor)
    assert one.rows_g.shape == (1, 1, 2) and not np.isclose(one.g[0] @ v, one.y[0])
    tr = KalmanTracker({"confirm_hits": 1, "initial_speed_sigma": sv, "doppler_floor": floor, "doppler_rows": "wall",
                        "depth_ratio": 0.0})
    out = tr.update(pts, 0.0)
    assert np.allclose(out.velocity[0], v * sv ** 2 / (sv ** 2 + s), atol=1e-9)
    with pytest.raises(ConfigError):
        KalmanTracker({"doppler_rows": "point"})


def test_a_gated_doppler_row_with_an_outlier_is_left_out():
    # A track at v = (5, 0) m/s with consistent radial velocities for 5 frames; in frame 6 its radial
    # velocity is off by 5 m/s at 0.1 m/s: with doppler_gate 0.999 (χ²₁ 10.83) that row is left out — the
    # update is the one of the same frame without Doppler — and without the gate it pulls the velocity.
    from estimators.trackers.kalman import chi2_1_ppf

    assert chi2_1_ppf(0.999) == pytest.approx(10.8276, abs=1e-4)
    g = np.array([1.0, 0.0])

    def frame(k, y):
        p = np.array([[10.0 + 0.5 * k, 3.0]])
        if y is None:
            return HiddenPoints(p, 0.01 * np.eye(2)[None], np.arange(1), np.zeros(1))
        return HiddenPoints(p, 0.01 * np.eye(2)[None], np.arange(1), np.zeros(1), velocity=(y * g)[None],
                            velocity_cov=(0.01 * np.outer(g, g))[None])

    out = {}
    for name, gate, last in (("gated", 0.999, 10.0), ("no row", 0.999, None), ("ungated", None, 10.0)):
        tr = KalmanTracker({"doppler_gate": gate} if gate else {})
        for k in range(5):
            tr.update(frame(k, 5.0), 0.1 * k)
        out[name] = tr.update(frame(5, last), 0.5).velocity[0]
    assert np.allclose(out["gated"], out["no row"], atol=1e-12)
    assert out["ungated"][0] > out["gated"][0] + 1.0
