"""lsq with ``history_frames`` K > 1 (estimators.history): each fit pools the LOS detections of the
last K frames. The pooled (φ, b) covariance matches the spread over independent draws and shrinks
K-fold (Var φ = σ²/Σt_i², closed form); the walls index this frame's rows only; a frame without LOS
gets the wall the held frames saw; the oldest frame is forgotten; the pipeline resets and
checkpoints it; a state that is not one lsq wrote is a typed error naming the key."""
import json

import numpy as np
import pytest

from estimators.lsq import LSQWallEstimator
from xnlos_core import InputError, InsufficientDataError
from xnlos_core.config import parse_pipeline
from xnlos_core.pipeline import Pipeline
from xnlos_core.testing import check_wall_estimator, small_pipeline_table
from xnlos_core.types import LOS, MNLOS, Detections

START, END = np.array([12.0, -6.0]), np.array([14.0, 6.0])  # a facade 12 m long, 12–14 m ahead [m]
SIGMA = 0.1  # position noise of each LOS point, isotropic [m]


def _wall_points(rng, n: int = 15) -> np.ndarray:
    t = np.linspace(0.05, 0.95, n)[:, None]
    return START + t * (END - START) + rng.normal(0.0, SIGMA, (n, 2))


def _frame(points, mnlos=()) -> Detections:
    los = Detections.from_points(points, LOS, confidence=0.9, range_std=0.05, azimuth_std=0.005)
    if not len(mnlos):
        return los
    return Detections.concat(los, Detections.from_points(np.asarray(mnlos), MNLOS, confidence=0.9,
                                                         range_std=0.05, azimuth_std=0.005))


def test_the_conformance_kit_accepts_lsq_with_a_history():
    check_wall_estimator(LSQWallEstimator({"history_frames": 3}))


@pytest.mark.parametrize("k", [1, 4])
def test_the_pooled_covariance_matches_the_spread_and_the_closed_form(k):
    """400 independent runs of k frames of 15 noisy points each: the reported Var φ of the last
    frame's wall matches the empirical variance of φ and σ²/Σt_i² over the k·15 pooled points."""
    rng = np.random.default_rng(7)
    est = LSQWallEstimator({"history_frames": k})
    phis, reported = [], []
    for _ in range(400):
        est.reset()
        for _ in range(k):
            w = est.estimate(_frame(_wall_points(rng)))[0]
        assert w.n_points == 15 * k and w.info["history_points"] == 15 * (k - 1)
        phis.append(w.mean[0])
        reported.append(w.cov[0, 0])
    s = np.tile(np.linspace(0.05, 0.95, 15), k) * np.linalg.norm(END - START)  # along the wall [m]
    closed = SIGMA**2 / np.sum((s - s.mean()) ** 2)  # Var φ = σ²/Σt_i² (estimators.lsq, step 3)
    assert np.mean(reported) == pytest.approx(closed, rel=0.1)
    assert np.var(phis) == pytest.approx(closed, rel=0.25)  # 400 draws: the variance is known to ±14 % (1 σ 7 %)


def test_walls_index_this_frames_rows_and_count_the_held_ones():
    rng = np.random.default_rng(1)
    est = LSQWallEstimator({"history_frames": 2})
    est.estimate(_frame(_wall_points(rng, 10)))
    det = _frame(_wall_points(rng, 3), mnlos=[[30.0, 5.0], [31.0, 6.0]])
    (w,) = est.estimate(det)
    assert w.info["detection_index"] == [0, 1, 2] and w.info["history_points"] == 10 and w.n_points == 13


def test_a_frame_without_los_gets_the_wall_the_held_frames_saw_and_reset_forgets_it():
    rng = np.random.default_rng(2)
    est = LSQWallEstimator({"history_frames": 3})
    (seen,) = est.estimate(_frame(_wall_points(rng)))
    no_los = _frame(np.empty((0, 2)), mnlos=[[30.0, 5.0], [31.0, 6.0]])
    (held,) = est.estimate(no_los)
    np.testing.assert_array_equal(held.mean, seen.mean)
    assert held.info["detection_index"] == [] and held.info["history_points"] == 15
    est.reset()
    with pytest.raises(InsufficientDataError, match="0 LOS detection"):
        est.estimate(no_los)


def test_the_oldest_frame_is_forgotten():
    """history_frames 2: frame C (no LOS) sees frame B's wall, not frame A's (8 m away)."""
    rng = np.random.default_rng(3)
    est = LSQWallEstimator({"history_frames": 2})
    est.estimate(_frame(_wall_points(rng)))
    frame_b = _frame(_wall_points(rng) + [8.0, 0.0])
    assert len(est.estimate(frame_b)) == 2  # A's wall (held) and B's
    (c,) = est.estimate(_frame(np.empty((0, 2)), mnlos=[[30.0, 5.0]]))
    np.testing.assert_array_equal(c.mean, LSQWallEstimator().estimate(frame_b)[0].mean)
    assert c.n_points == 15 and len(est.state()["frames"]) == 1


def test_one_frame_is_the_default_and_carries_no_state():
    rng = np.random.default_rng(4)
    est = LSQWallEstimator()
    det = _frame(_wall_points(rng))
    assert not est.carries_state and est.state() == {"format": 1, "frames": []}
    a, b = est.estimate(det)[0], est.estimate(det)[0]
    np.testing.assert_array_equal(a.cov, b.cov)
    assert a.info["history_points"] == 0


def test_the_pipeline_resets_the_history_and_names_it_stateful():
    t = small_pipeline_table()
    t["wall_estimator"] = {"name": "lsq", "params": {"history_frames": 3}}
    t.pop("tracker", None)
    pipe = Pipeline(parse_pipeline(t, "history.toml"))
    assert list(pipe.stateful()) == ["wall_estimator"]
    est = pipe.stages["wall_estimator"]
    est.estimate(_frame(_wall_points(np.random.default_rng(5))))
    assert est.state()["frames"]
    pipe.reset()
    assert est.state()["frames"] == []
    t["wall_estimator"]["params"] = {}
    assert Pipeline(parse_pipeline(t, "single.toml")).stateful() == {}


def _state() -> dict:
    est = LSQWallEstimator({"history_frames": 3})
    rng = np.random.default_rng(6)
    for _ in range(2):
        est.estimate(_frame(_wall_points(rng, 4)))
    return json.loads(json.dumps(est.state()))


@pytest.mark.parametrize("edit, match", [
    (lambda s: s.update(format=9), "history format 9"),
    (lambda s: s.pop("frames"), "missing key 'frames'"),
    (lambda s: s["frames"].append(s["frames"][0]), "holds 3 frames; history_frames = 3 keeps at most 2"),
    (lambda s: s["frames"][1].update(label=[1, 0, 0, 0]), r"frames\[1\]: label holds \[0, 1\]; expected LOS"),
    (lambda s: s["frames"][0]["range"].pop(), r"frames\[0\]: the fields .* have lengths \[3, 4"),
    (lambda s: s["frames"][0].update(azimuth="up"), r"frames\[0\]: azimuth = up; expected an array"),
    (lambda s: s["frames"][0]["range"].__setitem__(0, float("nan")), "Detections.range: .* NaN"),
])
def test_a_state_lsq_did_not_write_is_a_typed_error_and_leaves_it_empty(edit, match):
    state = _state()
    edit(state)
    est = LSQWallEstimator({"history_frames": 3})
    est.estimate(_frame(_wall_points(np.random.default_rng(8))))
    with pytest.raises(InputError, match=match):
        est.load_state(state)
    assert est.state()["frames"] == []


def test_a_loaded_state_gives_the_uninterrupted_walls():
    rng = np.random.default_rng(9)
    frames = [_frame(_wall_points(rng, 5)) for _ in range(5)]
    a = LSQWallEstimator({"history_frames": 3})
    for f in frames[:3]:
        a.estimate(f)
    b = LSQWallEstimator({"history_frames": 3})
    b.load_state(json.loads(json.dumps(a.state())))
    for f in frames[3:]:
        wa, wb = a.estimate(f)[0], b.estimate(f)[0]
        np.testing.assert_array_equal(wa.mean, wb.mean)
        np.testing.assert_array_equal(wa.cov, wb.cov)


def _with_velocity(det: Detections, v) -> Detections:
    v = np.broadcast_to(np.asarray(v, dtype=np.float64), (len(det),))
    return Detections(det.range, det.azimuth, det.label, det.confidence, det.range_std, det.azimuth_std, v,
                      np.full(len(det), 0.01))


def test_a_road_users_los_echoes_are_not_held():
    """A car in line of sight drives 1 m a frame along y = 5 m (5 m/s radial, 4 echoes a frame): with
    Doppler its echoes are not held, so after 5 frames only the facade pools earlier frames (with
    wall_max_speed None the car's own echoes of this frame give what one frame gives; by default they are
    no wall at all); without Doppler they line up into a 'wall' of 20 points along its path."""
    rng = np.random.default_rng(10)
    frames = []
    for k in range(5):
        car = np.array([[26.0 - k, 5.0]]) + rng.normal(0.0, 0.1, (4, 2))
        facade = _with_velocity(_frame(_wall_points(rng, 6)), 0.0)
        frames.append(Detections.concat(facade, _with_velocity(_frame(car), -5.0)))
    doppler, blind = LSQWallEstimator({"history_frames": 5}), LSQWallEstimator({"history_frames": 5})
    this_frame = LSQWallEstimator({"history_frames": 5, "wall_max_speed": None})
    fields = ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std")
    for f in frames:
        seen, seen_now = doppler.estimate(f), this_frame.estimate(f)
        unseen = blind.estimate(Detections(*(getattr(f, a) for a in fields)))
    assert sorted(w.n_points for w in unseen) == [20, 30], "without Doppler the car's path reads as a wall"
    assert sorted((w.n_points, w.info["history_points"]) for w in seen_now) == [(4, 0), (30, 24)]
    assert [(w.n_points, w.info["history_points"]) for w in seen] == [(30, 24)]
    assert sum(len(d) for d in doppler.history.held) == 4 * 6
