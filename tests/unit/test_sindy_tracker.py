"""Tracker ``sindy`` and the Doppler update shared with ``kalman``: closed-form update, faster velocity
convergence with Doppler, one identity through a hidden approach, bad input, forecast quality (slow)."""

import numpy as np
import pytest

from estimators.trackers.kalman import KalmanTracker
from estimators.trackers.sindy import SindyTracker
from xnlos_core import ConfigError, HiddenPoints, InputError
from xnlos_core.motion import ConstantTurn
from xnlos_core.testing import check_component


def hidden(points, sigma=0.1, velocity=None, vvar=None):
    pts = np.asarray(points, float).reshape(-1, 2)
    k = len(pts)
    extra = {}
    if velocity is not None:
        w = np.asarray(velocity, float).reshape(-1, 2)
        g = w / np.linalg.norm(w, axis=1, keepdims=True)
        extra = {"velocity": w, "velocity_cov": vvar * g[:, :, None] * g[:, None, :]}
    return HiddenPoints(pts, np.tile(sigma ** 2 * np.eye(2), (k, 1, 1)), np.arange(k), np.zeros(k), **extra)


def test_conformance_kit():
    check_component("tracker", "sindy")


def test_doppler_update_closed_form_on_birth():
    # A new track's prior v = 0, P_v = σ_v² I, updated by y = ĝᵀv with variance s = var + floor²:
    # v = ĝ y σ_v²/(σ_v² + s), and the position is untouched (no p–v correlation in the prior).
    g, y, var, floor, sv = np.array([0.6, 0.8]), 5.0, 0.3, 0.1, 4.0
    for name in ("kalman", "sindy"):
        cls = KalmanTracker if name == "kalman" else SindyTracker
        tr = cls({"confirm_hits": 1, "initial_speed_sigma": sv, "doppler_floor": floor})
        out = tr.update(hidden([[10.0, 2.0]], velocity=[y * g], vvar=var), 0.0)
        assert np.allclose(out.velocity[0], g * y * sv ** 2 / (sv ** 2 + var + floor ** 2), atol=1e-12)
        assert np.allclose(out.position[0], [10.0, 2.0])
        off = cls({"confirm_hits": 1, "use_doppler": False}).update(hidden([[10.0, 2.0]], velocity=[y * g], vvar=var), 0.0)
        assert np.allclose(off.velocity[0], 0.0)


def test_doppler_speeds_up_velocity_convergence():
    # A car at 10 m/s seen along ĝ = its direction of travel: after 5 frames the velocity error
    # with the radial velocity is well below the one from positions alone (same seeded noise).
    v = np.array([6.0, 8.0])
    err = {}
    for use in (True, False):
        rng = np.random.default_rng(4)
        tr = KalmanTracker({"use_doppler": use, "extent_sigma": 0.0})
        for k in range(5):
            t = 0.1 * k
            z = np.array([20.0, -5.0]) + v * t + 0.4 * rng.standard_normal(2)
            w = (v @ (v / 10) + 0.3 * rng.standard_normal()) * v / 10
            out = tr.update(hidden([z], 0.4, velocity=[w], vvar=0.09), t)
        err[use] = np.linalg.norm(out.velocity[0] - v)
    assert err[True] < 0.5 * err[False]


def test_nan_velocity_is_a_typed_error():
    with pytest.raises(InputError, match="HiddenPoints.velocity"):
        HiddenPoints([[1.0, 2.0]], [np.eye(2)], [0], [0], velocity=[[np.nan, 0.0]], velocity_cov=[np.eye(2)])
    pts = hidden([[1.0, 2.0]], velocity=[[1.0, 0.0]], vvar=0.1)
    object.__setattr__(pts, "velocity", np.array([[np.nan, 0.0]]))  # bypassing the type's own check
    for cls in (KalmanTracker, SindyTracker):
        with pytest.raises(InputError, match="velocity"):
            cls().update(pts, 0.0)


def test_bad_timestamps_and_empty_frames():
    tr = SindyTracker({"confirm_hits": 1})
    tr.update(hidden([[0.0, 0.0]]), 1.0)
    with pytest.raises(InputError, match="increase strictly"):
        tr.update(hidden([[0.0, 0.0]]), 1.0)                 # Δt = 0: documented typed error
    with pytest.raises(InputError, match="must not decrease"):
        tr.update(hidden([[0.0, 0.0]]), 0.5)
    out = tr.update(HiddenPoints.empty(), 1.1)                # no detections: the track coasts
    assert out.track_id.tolist() == [0] and out.forecast.shape == (1, 6, 2) and out.model == ("cv",)
    tr.reset()
    out = tr.update(HiddenPoints.empty(), 0.0)               # nothing yet: the documented empty result
    assert len(out) == 0 and out.forecast.shape == (0, 6, 2) and out.model == ()
    with pytest.raises(ConfigError, match="min_samples"):
        SindyTracker({"min_samples": 3})


def test_short_tracks_stay_constant_velocity():
    tr = SindyTracker({"confirm_hits": 1})
    out = tr.update(hidden([[5.0, 5.0]]), 0.0)                # a one-point track: no model, CV forecast
    assert out.model == ("cv",) and np.allclose(out.forecast[0], [5.0, 5.0])


def test_one_identity_through_a_hidden_approach():
    # Acceptance: a car at 10 m/s comes through the hidden street for 5 s (10 Hz), hidden points with
    # 0.4 m noise (plus ±0.5 m spread over the body; the points' covariance says 0.5 m), two or three
    # points a frame, a few frames missed; one track id from confirmation on, for kalman and sindy.
    rng = np.random.default_rng(7)
    t = np.arange(50) * 0.1
    truth = ConstantTurn(speed=10.0, yaw_rate=0.1).state(t, (25.0, -45.0), np.pi / 2).position
    frames = []
    for k in range(50):
        n = 0 if k in (12, 13, 27, 40) else rng.integers(2, 4)
        frames.append(truth[k] + rng.uniform(-0.5, 0.5, (n, 2)) + 0.4 * rng.standard_normal((n, 2)))
    for tr in (KalmanTracker(), SindyTracker()):
        ids = set()
        for k in range(50):
            out = tr.update(hidden(frames[k], 0.5), t[k])
            ids.update(out.track_id.tolist())
        assert ids == {0}
        assert np.linalg.norm(out.position[0] - truth[-1]) < 1.0


def test_sindy_90_percent_discs_cover_a_handful_of_synthetic_cars(benchmark_module):
    # The calibrated forecast (benchmarks/forecast_calibration.py) on 4 seeded straight, turning and
    # braking cars each (forecast_quality's cars: 0.5 m noise, 4 s at 10 Hz, 2 s ahead): the 90 % discs
    # around sindy's forecast hold the true centre in 80–100 % of the cases (12 cars: a loose band).
    res = benchmark_module("forecast_quality").compare({"sindy": SindyTracker()}, tracks=4, noise=0.5, seed=3)
    err = np.concatenate([r["sindy"][0] for r in res.values()])
    r90 = np.concatenate([r["sindy"][1] for r in res.values()])
    assert np.all(np.isfinite(err))                               # no car lost
    assert 0.8 <= np.mean(err <= r90) <= 1.0


@pytest.mark.slow
def test_forecast_beats_cv_on_turns_and_braking_not_worse_on_straight(benchmark_module):
    # targets at 0.5 m noise, 2 s ahead: ≥ 30 % below CV (kalman) on turning and braking
    # cars, ≤ 5 % above it on straight ones (8 seeded cars per kind, xnlos_core.motion truth).
    res = benchmark_module("forecast_quality").compare({"kalman": KalmanTracker(), "sindy": SindyTracker()}, tracks=8, noise=0.5)
    ratio = {k: np.nanmean(r["sindy"][0]) / np.nanmean(r["kalman"][0]) for k, r in res.items()}
    assert ratio["cv"] <= 1.05
    assert ratio["turn"] <= 0.7 and ratio["brake"] <= 0.7


@pytest.mark.parametrize("params, counts, least", [
    ({"identification": "ensemble", "min_evidence": 30.0}, lambda m: m != "cv", 5),
    ({}, lambda m: m == "brake", 4),  # the manoeuvre library: Doppler rows ĝᵀ dp/dτ, forecast from the filter
])
def test_radial_velocities_let_sindy_see_braking_behind_a_wandering_centroid(params, counts, least):
    # Braking cars (9 m/s, −2 m/s²) seen as one hidden point with 1 m of noise and a radial velocity with
    # 0.1 m/s along the line of sight from a mirrored radar: fitting the radial velocities identifies
    # the braking on more tracks and cuts the 2 s forecast error against the positions alone, by
    # ensemble SINDy and by the manoeuvre library (library_origin "doppler")
    from xnlos_core.motion import ConstantAcceleration

    rng = np.random.default_rng(4)
    n, dt = 35, 0.1
    t = np.arange(n) * dt
    err = {True: [], False: []}
    models = {True: 0, False: 0}
    for car in range(6):
        heading = rng.uniform(0, 2 * np.pi)
        st = ConstantAcceleration(speed=9.0, acceleration=-2.0).state(np.r_[t, t[-1] + 2.0], (25.0, 10.0), heading)
        z = st.position[:n] + rng.standard_normal((n, 2))
        g = st.position[:n] - [60.0, 40.0]
        g /= np.linalg.norm(g, axis=1, keepdims=True)
        y = np.sum(g * st.velocity[:n], axis=1) + 0.1 * rng.standard_normal(n)
        for fit_radial in (False, True):
            tr = SindyTracker({**params, "identify_doppler": fit_radial, "seed": car})
            for k in range(n):
                out = tr.update(HiddenPoints(z[k][None], np.eye(2)[None], [0], [0], velocity=(y[k] * g[k])[None],
                                             velocity_cov=(0.01 * np.outer(g[k], g[k]))[None]), t[k])
            assert len(out) == 1
            j = int(np.argmin(np.abs(out.horizons - 2.0)))
            err[fit_radial].append(np.linalg.norm(out.forecast[0, j] - st.position[-1]))
            models[fit_radial] += bool(counts(out.model[0]))
    assert models[True] >= least and models[True] > models[False], models
    assert np.mean(err[True]) < 0.8 * np.mean(err[False]), err


def test_defaults_follow_braking_cars_early():
    # (ensemble SINDy, which fits the radial velocities) The defaults identify from a track's 8th sample and refit every 2 frames (chosen on the sequence
    # val split, configs/ablations/tracking.toml): of 12 braking cars (9 m/s, −2 m/s², 1 m position
    # noise, 0.1 m/s radial noise), 8 follow a model by their 14th frame (1.3 s); with the earlier
    # 12 samples / every 5 frames, 4 did. Until it is identified, a braking car is forecast as CV.
    from xnlos_core.motion import ConstantAcceleration

    rng = np.random.default_rng(4)
    n, dt = 35, 0.1
    t = np.arange(n) * dt
    early = 0
    for car in range(12):
        heading = rng.uniform(0, 2 * np.pi)
        st = ConstantAcceleration(speed=9.0, acceleration=-2.0).state(t, (25.0, 10.0), heading)
        z = st.position + rng.standard_normal((n, 2))
        g = st.position - [60.0, 40.0]
        g /= np.linalg.norm(g, axis=1, keepdims=True)
        y = np.sum(g * st.velocity, axis=1) + 0.1 * rng.standard_normal(n)
        tr = SindyTracker({"identification": "ensemble", "min_evidence": 30.0, "seed": car})
        for k in range(14):
            out = tr.update(HiddenPoints(z[k][None], np.eye(2)[None], [0], [0], velocity=(y[k] * g[k])[None],
                                         velocity_cov=(0.01 * np.outer(g[k], g[k]))[None]), t[k])
            if out.model and out.model[0] != "cv":
                early += 1
                break
    assert early >= 6, early


def test_matched_alpha_covers_the_identified_distance_in_2s():
    # The linear form e^{αh} of a constant tangential acceleration β: the 2 s position of a straight
    # path matches s·2 + β·2²/2 (or the stop at s²/(2|β|)); β/s would overshoot a speed-up, undershoot
    # a braking.
    from estimators.trackers.forecast import LinearMotion
    from estimators.trackers.sindy import MATCH_HORIZON, matched_alpha

    assert MATCH_HORIZON == 2.0
    for beta, speed, dist in ((2.0, 4.0, 12.0), (-1.5, 6.0, 9.0), (-2.5, 4.0, 3.2), (0.0, 5.0, 10.0)):
        alpha = float(matched_alpha(beta, speed))
        x = LinearMotion(alpha * np.eye(2)).transition(2.0) @ np.r_[0.0, 0.0, speed, 0.0]
        assert x[0] == pytest.approx(dist, rel=1e-8) and x[1] == 0.0, (beta, speed, alpha, x)
        if beta:
            assert alpha < beta / speed      # below the instantaneous β/s: less speed-up, more braking
    assert matched_alpha(np.array([[2.0, 0.0], [-1.5, 2.0]]), 4.0).shape == (2, 2)


def test_models_beyond_the_road_users_envelope_stay_constant_velocity():
    # A model is followed only within β ≤ max_speedup and |ω|·|v| ≤ max_lateral: a 5 m/s² speed-up or a
    # 6 m/s² lateral acceleration (1 rad/s at 6 m/s) is an artefact of the track, not a road user's motion;
    # a 3 m/s² braking and a 0.3 rad/s turn at 6 m/s (1.8 m/s²) are followed.
    from estimators.trackers.sindy import SindyParams, motion_from, within_envelope
    from estimators.trackers.sindy_model import MotionModel

    p = SindyParams(min_evidence=10.0)
    for (beta, omega), inside in (((5.0, 0.0), False), ((0.0, 1.0), False), ((-3.0, 0.0), True),
                                  ((0.0, 0.3), True), ((3.0, -0.6), True), ((3.01, 0.0), False)):
        assert within_envelope((beta, omega), 6.0, p) is inside, (beta, omega)
        xi = (beta / 6.0) * np.eye(2) + omega * np.array([[0.0, -1.0], [1.0, 0.0]])
        mask = np.array([beta != 0, omega != 0])
        theta = np.r_[0.0, 0.0, 6.0, 0.0, [r for r, m in zip((beta, omega), mask) if m]]
        model = MotionModel(xi, xi[None], ((mask, theta, np.zeros((len(theta), len(theta)))),), 0.0, 0.5, 50.0,
                            np.array([beta, omega]))
        assert motion_from(model, [6.0, 0.0], 0, p).is_cv is not inside, (beta, omega)
        wide = SindyParams(min_evidence=10.0, max_speedup=10.0, max_lateral=10.0)
        assert not motion_from(model, [6.0, 0.0], 0, wide).is_cv



def test_braking_alone_may_have_its_own_evidence_bar():
    # braking_evidence sets the bar of a model of braking alone (β < 0, ω = 0); a turn, a speed-up and
    # a braking turn keep min_evidence, and None (the default) is min_evidence for all.
    from estimators.trackers.sindy import SindyParams, evidence_bar, motion_from
    from estimators.trackers.sindy_model import MotionModel

    low = SindyParams(min_evidence=30.0, braking_evidence=5.0)
    same = SindyParams(min_evidence=30.0)
    for (beta, omega), bar in (((-2.0, 0.0), 5.0), ((2.0, 0.0), 30.0), ((0.0, 0.2), 30.0), ((-2.0, 0.2), 30.0)):
        assert evidence_bar((beta, omega), low) == bar and evidence_bar((beta, omega), same) == 30.0
        xi = (beta / 6.0) * np.eye(2) + omega * np.array([[0.0, -1.0], [1.0, 0.0]])
        mask = np.array([beta != 0, omega != 0])
        theta = np.r_[0.0, 0.0, 6.0, 0.0, [r for r, m in zip((beta, omega), mask) if m]]
        model = MotionModel(xi, xi[None], ((mask, theta, np.zeros((len(theta), len(theta)))),), 0.0, 0.5, 10.0,
                            np.array([beta, omega]))  # evidence 10: between the two bars
        assert motion_from(model, [6.0, 0.0], 0, low).is_cv is (bar == 30.0), (beta, omega)
        assert motion_from(model, [6.0, 0.0], 0, same).is_cv
    with pytest.raises(ValueError):
        SindyParams(braking_evidence=-1.0)


def test_a_revived_track_keeps_its_history_and_is_not_identified_while_lost():
    # A car at 5 m/s missed for 5 frames (lost after max_misses = 3): no identification while lost, and the
    # revived track goes on with the samples from before the gap (the history's window is 3 s).
    tr = SindyTracker({"max_misses": 3, "lost_frames": 5})
    fitted = []
    for k in range(30):
        t = 0.1 * k
        pts = np.empty((0, 2)) if 12 <= k < 17 else [[20.0 + 5.0 * t, 3.0]]
        out = tr.update(hidden(pts), t)
        track = tr._tracks[0]
        fitted.append(track.fitted_frame)
        assert out.track_id.tolist() == ([] if 14 <= k <= 17 else [0] if k >= 1 else [])  # 17: revived, tentative
    assert len(set(fitted[14:17])) == 1                   # lost frames 14–16: no new identification
    assert [h[0] for h in track.history][:3] == pytest.approx([0.0, 0.1, 0.2])
    assert len(track.history) == 25


def test_a_library_cv_track_anchored_to_the_filter_forecasts_as_kalman():
    # library_origin "filter": a straight track identified as CV forecasts the filter's p + v·h, the
    # Kalman tracker's mean exactly (the covariance stays the fit's)
    rng = np.random.default_rng(7)
    t = np.arange(30) * 0.1
    z = np.c_[3.0 + 8.0 * t, 1.0 + 4.0 * t] + 0.05 * rng.standard_normal((30, 2))
    sindy, kalman = SindyTracker({"library_origin": "filter"}), KalmanTracker({})
    for k in range(30):
        a, b = sindy.update(hidden(z[k]), t[k]), kalman.update(hidden(z[k]), t[k])
    assert a.model[0] == "cv" and sindy._tracks[0].library is not None
    assert a.forecast == pytest.approx(b.forecast, abs=1e-9)
