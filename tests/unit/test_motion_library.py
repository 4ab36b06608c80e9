"""The batched manoeuvre library (estimators/trackers/library/, through motion_library): lane changes and reversals are
identified as such, straight noisy tracks stay constant velocity, and the batched fit equals a
per-track least-squares fit."""
import numpy as np
import pytest

from estimators.trackers import motion_library as ml
from xnlos_core import InputError

T = np.arange(30) * 0.1  # the tracker's 3 s window at 10 Hz


def lane_change(t, speed=12.0, width=3.5, start=-1.0, duration=4.0):
    """A hand-made lane change along +x: lateral offset width·(s − sin(2πs)/2π), s = (t − start)/duration
    clipped to [0, 1] (lateral velocity 0 at both ends, zero lateral acceleration at the ends)."""
    s = np.clip((t - start) / duration, 0.0, 1.0)
    return np.c_[speed * t, width * (s - np.sin(2 * np.pi * s) / (2 * np.pi))]


def test_a_lane_change_is_identified_as_a_lane_change_not_a_turn():
    # 3.5 m in 4 s at 12 m/s, the window ending 0.8 of the way through (the lateral velocity dying out,
    # its heading turning back: no constant turn fits); 0.05 m noise
    rng = np.random.default_rng(0)
    t = T + 0.2
    z = lane_change(t, start=-0.2) + 0.05 * rng.standard_normal((len(t), 2))
    fit = ml.identify_batch([(t, z)])[0]
    assert fit.label == "lane_change" and fit.entries[0].model == "lane"
    mean, _ = ml.predict(fit, [2.0])
    truth = lane_change(np.array([t[-1] + 2.0]), start=-0.2)[0]
    line = np.polyfit(t[-11:] - t[-1], z[-11:], 1)           # the CV line over the last 1 s: ≈ 2.1 m off
    assert np.linalg.norm(mean[0] - truth) < 0.35 * np.linalg.norm(line[1] + 2.0 * line[0] - truth)


def test_a_reversing_car_gets_a_model_through_zero_speed():
    # 3 m/s forward, −2 m/s² through zero at t = 1.5 s, observed over [0, 2.9] s (0.1 m noise): the
    # reversal, not a braking to a stop; its forecast keeps going backwards past the turning point, at
    # its present speed (a reversing car does not speed up backwards for ever)
    rng = np.random.default_rng(1)
    heading = np.array([np.cos(0.7), np.sin(0.7)])
    s = 3.0 * T - T ** 2
    z = s[:, None] * heading + 0.1 * rng.standard_normal((len(T), 2))
    fit = ml.identify_batch([(T, z)])[0]
    assert fit.label == "reverse"
    e = fit.entries[0]
    assert np.isinf(e.stop)                                # not clamped at a stop
    now, speed = 3.0 * T[-1] - T[-1] ** 2, 3.0 - 2.0 * T[-1]            # s(2.9 s) = 0.29 m, v = −2.8 m/s
    mean, _ = ml.predict(fit, [1.0, 2.0])
    assert mean[:, :] @ heading == pytest.approx([now + speed, now + 2 * speed], abs=0.3)
    # the velocity along the path changes sign between the window's start and the forecast
    v = [(ml.predict(fit, [tt + 0.01])[0][0] - ml.predict(fit, [tt])[0][0]) @ heading / 0.01 for tt in (-T[-1], 1.0)]
    assert v[0] > 2.0 and v[1] == pytest.approx(speed, abs=0.3)


def test_straight_noisy_tracks_stay_constant_velocity():
    # 200 straight tracks (5–15 m/s, 0.3–0.5 m white noise): a manoeuvre model for ≈ level α = 1 % at most
    rng = np.random.default_rng(2)
    tracks = []
    for _ in range(200):
        v = rng.uniform(5, 15) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        tracks.append((T, T[:, None] * v + rng.uniform(0.3, 0.5) * rng.standard_normal((len(T), 2))))
    fits = ml.identify_batch(tracks)
    labels = [f.label for f in fits]
    assert labels.count("cv") >= 194                       # ≤ 3 %: binomial(200, 0.01) exceeds 6 with p < 0.5 %
    # and their windows read as straight: the forecast starts from the window fit, not a filter's state
    assert sum(f.local_origin for f in fits) <= 10


def test_a_lane_change_forecast_from_a_filter_state_ends_the_lateral_motion():
    # the closed-form lane change (3.5 m in 4 s at 12 m/s, sin² heading), the window ending 0.8 of the
    # way through (3.4 m across), 0.05 m noise: a lane change, forecast from a filter's (here: the true)
    # position and lateral velocity (0.48 m/s, which a CV forecast carries 0.96 m on over 2 s): the
    # forecast's lateral velocity dies out with the lane change (0 after its end, 0.7 s on) and it lands
    # in the new lane
    rng = np.random.default_rng(0)
    t = T + 0.2
    z = lane_change(t, start=-0.2) + 0.05 * rng.standard_normal((len(t), 2))
    fit = ml.identify_batch([(t, z)])[0]
    assert fit.label == "lane_change" and fit.local_origin
    dt = 1e-4
    p = lane_change(np.array([t[-1]]), start=-0.2)[0]
    v = (lane_change(np.array([t[-1] + dt]), start=-0.2)[0] - lane_change(np.array([t[-1] - dt]), start=-0.2)[0]) / (2 * dt)
    assert v[1] > 0.45                                              # the lateral velocity at the origin
    h = np.array([[1.5, 2.0, 2.0 + dt]])
    mean, _ = ml.predict_many([fit], h, (p[None], v[None], np.zeros(1)))
    lateral_speed = (mean[0, 2, 1] - mean[0, 1, 1]) / dt
    assert abs(lateral_speed) < 0.1 * v[1]                          # the drift has ended
    assert mean[0, 1, 1] == pytest.approx(3.5, abs=0.25)            # in the new lane
    assert abs(p[1] + 2.0 * v[1] - 3.5) > 0.8                       # the CV forecast: 0.84 m beyond it


def test_batched_fit_equals_the_per_track_least_squares_fit():
    # tracks with different sample times (a missed frame) and headings, fitted together and alone, and
    # each selected entry's θ equal to numpy.linalg.lstsq on its own design
    rng = np.random.default_rng(3)
    t_gap = np.delete(T, 12)
    tracks = [(T, lane_change(T) @ np.array([[0.6, 0.8], [-0.8, 0.6]]) + 0.1 * rng.standard_normal((30, 2))),
              (t_gap, np.c_[10 * t_gap - 1.5 * t_gap ** 2, 0 * t_gap] + 0.3 * rng.standard_normal((29, 2))),
              (T, np.c_[8 * np.sin(0.3 * T) / 0.3, 8 * (1 - np.cos(0.3 * T)) / 0.3] + 0.2 * rng.standard_normal((30, 2)))]
    together = ml.identify_batch(tracks)
    for (t, z), fit in zip(tracks, together):
        alone = ml.identify_batch([(t, z)])[0]
        assert alone.label == fit.label
        for a, b in zip(alone.entries, fit.entries):
            assert a.model == b.model and np.allclose(a.theta, b.theta, rtol=1e-8, atol=1e-8)
            B = ml.basis(b.model, b.hyper, t - t[-1]).reshape(-1, len(b.theta))
            ref = np.linalg.lstsq(B, z.ravel(), rcond=None)[0]
            assert np.allclose(b.theta, ref, rtol=1e-6, atol=1e-6)


def test_bad_tracks_are_typed_errors():
    with pytest.raises(InputError, match="samples"):
        ml.identify_batch([(T[:5], np.zeros((5, 2)))])
    with pytest.raises(InputError, match="strictly increasing"):
        ml.identify_batch([(T[::-1], np.zeros((30, 2)))])
    with pytest.raises(InputError, match="level"):
        ml.identify_batch([(T, np.zeros((30, 2)))], level=1.5)


def test_batched_forecasts_equal_one_at_a_time():
    rng = np.random.default_rng(4)
    tracks = [(T, lane_change(T) + 0.1 * rng.standard_normal((30, 2))),
              (T, np.c_[10 * T - 1.5 * T ** 2, 0 * T] + 0.3 * rng.standard_normal((30, 2))),
              (T, np.c_[8 * T, 0 * T] + 0.4 * rng.standard_normal((30, 2)))]
    fits = ml.identify_batch(tracks)
    tau = np.array([[0.5, 2.0, 3.0], [0.1, 2.1, 3.1], [0.0, 1.0, 9.0]])
    mean, cov = ml.predict_many(fits, tau)
    for i, f in enumerate(fits):
        m1, c1 = ml.predict(f, tau[i])
        assert np.allclose(mean[i], m1) and np.allclose(cov[i], c1)


def test_a_track_that_settled_after_a_velocity_step_forecasts_its_present_velocity():
    # 10 m/s heading 30° off, then at τ = −1.5 s a step to 12 m/s along +x (0.05 m noise): the window's CV
    # line follows the old heading; the settled (kink) entry forecasts the new velocity, 2 s on
    rng = np.random.default_rng(5)
    tau = T - T[-1]
    old = 10.0 * np.array([np.cos(0.5), np.sin(0.5)])
    new = np.array([12.0, 0.0])
    z = np.where(tau[:, None] >= -1.5, tau[:, None] * new, -1.5 * new + (tau[:, None] + 1.5) * old)
    fit = ml.identify_batch([(T, z + 0.05 * rng.standard_normal(z.shape))])[0]
    assert fit.label == "settled" and fit.entries[0].model == "kink"
    mean, _ = ml.predict(fit, [2.0])
    assert np.linalg.norm(mean[0] - 2.0 * new) < 0.2


def test_a_braking_that_settled_is_a_ramp_forecast_at_its_final_speed():
    # 14 m/s slowing at 3 m/s² until τ = −1.0 s, then 14 − 3·1.9 = 8.3 m/s (0.05 m noise): the ramp entry
    # (a speed change that ended), whose forecast goes on at 8.3 m/s, not slowing further
    rng = np.random.default_rng(6)
    tau = T - T[-1]
    t_end = -1.0
    v_end = 14.0 - 3.0 * (t_end - tau[0])
    s = np.where(tau <= t_end, v_end * (tau - t_end) + 1.5 * (tau - t_end) ** 2, v_end * (tau - t_end)) + v_end * t_end
    heading = np.array([np.cos(2.0), np.sin(2.0)])
    fit = ml.identify_batch([(T, s[:, None] * heading + 0.05 * rng.standard_normal((len(T), 2)))])[0]
    assert fit.label == "settled" and fit.entries[0].model == "ramp"
    mean, _ = ml.predict(fit, [2.0])
    assert mean[0] @ heading == pytest.approx(2.0 * v_end, abs=0.2)


def test_the_first_half_of_a_lane_change_is_a_lane_change_not_a_turn():
    # 40 windows ending at a lane change's midpoint (lateral velocity at its peak), 0.3 m noise: a turn
    # fits about as well, and needs strong evidence (TURN_OVER_LANE) to be taken over the lane change —
    # without that rule 14 of these 40 read as turns
    rng = np.random.default_rng(7)
    t = T + 2.0
    tracks = [(t, lane_change(t, start=0.9) + 0.3 * rng.standard_normal((len(t), 2))) for _ in range(40)]
    labels = [f.label for f in ml.identify_batch(tracks)]
    assert labels.count("turn") <= 2 and labels.count("lane_change") >= 28


@pytest.mark.parametrize("model", ml.LIBRARY)
def test_velocity_basis_is_the_derivative_of_the_basis(model):
    # closed-form dB/dτ against central differences of B, at grid values of every kind
    hyper = np.array([0.4, -1.1, 0.5, np.cos(0.3), np.sin(0.3)])
    tau = np.array([-2.7, -1.6, -0.3, 0.0, 1.2])                # away from the kinks at τ_c = −1.1
    d = 1e-5
    num = (ml.basis(model, hyper, tau + d) - ml.basis(model, hyper, tau - d)) / (2 * d)
    assert ml.velocity_basis(model, hyper, tau) == pytest.approx(num, abs=1e-6)


def braking_with_doppler(rng, beta=-3.0, v0=12.0, wander=0.3):
    """A braking car over the 3 s window with a wandering centroid (AR(1), ρ = 0.8, innovations
    ``wander`` [m]) and radial velocities (0.05 m/s) along a fixed mirrored line of sight."""
    heading = np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
    s = v0 * T + beta * T ** 2 / 2
    e = np.zeros((len(T), 2))
    for i in range(1, len(T)):
        e[i] = 0.8 * e[i - 1] + wander * rng.standard_normal(2)
    z = np.array([5.0, 20.0]) + s[:, None] * heading + e
    g = np.tile([np.cos(b := a + rng.uniform(-1.0, 1.0)), np.sin(b)], (len(T), 1))
    y = (v0 + beta * T) * (g @ heading) + 0.05 * rng.standard_normal(len(T))
    y[::7] = np.nan                                                # some samples without Doppler
    return z, g, y


def test_radial_velocity_rows_recover_a_braking_deceleration_behind_a_wandering_centroid():
    # −3 m/s²: with the radial rows y = ĝᵀ dp/dτ the batched fit finds the braking on every track (a few as a
    # braking turn of ≤ 0.03 rad/s) and its deceleration within 0.25 m/s² on average, where the positions alone miss it
    # (turns, a settled track) or misjudge it by up to 1.1 m/s²
    rng = np.random.default_rng(5)
    cars = [braking_with_doppler(rng) for _ in range(12)]
    alone = ml.identify_batch([(T, z) for z, _, _ in cars], radial_share="full")
    both = ml.identify_batch([(T, z, g, y) for z, g, y in cars], radial_share="full")
    def error(f):  # of a braking model: braking, or a braking turn of under 0.05 rad/s; 3 m/s² otherwise
        brakes = f.label == "brake" or (f.label == "turn" and abs(f.rates[1]) < 0.05)
        return abs(f.rates[0] + 3.0) if brakes else 3.0

    err_alone, err_both = np.array([error(f) for f in alone]), np.array([error(f) for f in both])
    assert np.max(err_both) < 0.7 and np.mean(err_both) < 0.25 and np.mean(err_both) < 0.3 * np.mean(err_alone), (
        err_both, err_alone)


def test_radial_velocity_rows_keep_straight_tracks_constant_velocity():
    # straight cars with white position noise and radial velocities (0.1 m/s): CV stays on almost all
    rng = np.random.default_rng(6)
    tracks = []
    for _ in range(60):
        u = np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        v = rng.uniform(5, 15)
        g = np.tile([np.cos(b := a + rng.uniform(-1.0, 1.0)), np.sin(b)], (len(T), 1))
        tracks.append((T, T[:, None] * v * u + 0.4 * rng.standard_normal((len(T), 2)), g,
                       v * (g @ u) + 0.1 * rng.standard_normal(len(T))))
    labels = [f.label for f in ml.identify_batch(tracks, radial_share="ar1")]
    assert labels.count("cv") >= 57, labels


def test_an_anchored_forecast_takes_the_filter_state_and_keeps_the_shape():
    # Eq. (3): a CV selection forecasts exactly p + v·h from the given state; a turn keeps its path's bend
    # about its tangent (the difference to its own forecast is p − S(τ₀) + (v − S′(τ₀))·h); Eq. (4): a
    # braking one takes v into its model and stops where that speed runs out at its deceleration
    t = T
    z_cv = np.c_[10.0 * t, 2.0 * t] + 0.01 * np.sin(7 * t)[:, None]
    f_cv = ml.identify_batch([(t, z_cv)])[0]
    assert f_cv.label == "cv"
    p, v, h = np.array([30.0, 5.0]), np.array([9.0, 3.0]), np.array([0.5, 1.0, 2.0])
    mean, _ = ml.predict_many([f_cv], 0.1 + h[None], (p[None], v[None], np.array([0.1])))
    assert mean[0] == pytest.approx(p + h[:, None] * v, abs=1e-9)
    w = 0.3
    z_turn = 10.0 / w * np.c_[np.sin(w * t), 1 - np.cos(w * t)] + 0.01 * np.cos(5 * t)[:, None]
    f_turn = ml.identify_batch([(t, z_turn)])[0]
    assert f_turn.label == "turn"
    own, _ = ml.predict_many([f_turn], h[None])
    at0, _ = ml.predict_many([f_turn], np.array([[0.0, 1e-5]]))
    s0, v0 = at0[0, 0], (at0[0, 1] - at0[0, 0]) / 1e-5
    mean, _ = ml.predict_many([f_turn], h[None], (p[None], v[None], np.array([0.0])))
    assert mean[0] == pytest.approx(own[0] + (p - s0) + h[:, None] * (v - v0), abs=1e-3)
    nan = np.full((1, 2), np.nan)                                  # not anchored: the fit's own forecast
    assert ml.predict_many([f_turn], h[None], (nan, nan, np.array([0.0])))[0] == pytest.approx(own)
    z_br = np.c_[12.0 * t - 1.5 * t ** 2, 0.0 * t] + 0.01 * np.cos(5 * t)[:, None]
    f_br = ml.identify_batch([(t, z_br)])[0]
    assert f_br.label == "brake" and f_br.rates[0] == pytest.approx(-3.0, abs=0.05)
    vb = np.array([4.5, 0.0])                                      # the filter's: 1.5 s to a standstill at −3 m/s²
    mean, _ = ml.predict_many([f_br], h[None], (p[None], vb[None], np.array([0.0])))
    u, beta = f_br.entries[0].hyper[3:5], f_br.entries[0].theta[4]
    he = np.minimum(h, max(-(u @ vb) / beta, 0.0))
    assert mean[0] == pytest.approx(p + he[:, None] * vb + u * (beta * he ** 2 / 2)[:, None], abs=1e-9)
    assert mean[0, -1] == pytest.approx(p + [4.5 ** 2 / 6, 0.0], abs=0.05)  # at rest after 4.5²/(2·3) m


def test_an_anchored_braking_turn_comes_to_rest_instead_of_reversing():
    # Eq. (4) for a turn with a speed change: 10 m/s at 0.3 rad/s braking at 3 m/s²; from a filter state at
    # 3 m/s the forecast comes to rest after 1 s (its basis alone would run the turn backwards)
    dt = 0.001
    tt = np.arange(0, 2.9 + dt / 2, dt)
    speed, psi = 10.0 - 3.0 * tt, 0.3 * tt
    path = np.cumsum(np.c_[speed * np.cos(psi), speed * np.sin(psi)] * dt, axis=0)
    z = path[::100] + 0.01 * np.cos(5 * T)[:, None]
    fit = ml.identify_batch([(T, z)])[0]
    assert fit.entries[0].model == "turn_accel" and fit.rates[0] == pytest.approx(-3.0, abs=0.3)
    p, v = z[-1], 3.0 * np.array([np.cos(0.87), np.sin(0.87)])
    h = np.array([0.5, 1.0, 1.5, 2.0])
    mean, _ = ml.predict_many([fit], h[None], (p[None], v[None], np.array([0.0])))
    assert mean[0, 2] == pytest.approx(mean[0, 1], abs=1e-9) and mean[0, 3] == pytest.approx(mean[0, 1], abs=1e-9)
    d = mean[0, 1] - p                                               # about 3²/(2·3) = 1.5 m ahead, at rest
    assert 1.2 < np.linalg.norm(d) < 1.6 and d @ v / (np.linalg.norm(d) * 3.0) > 0.9
