"""Ensemble-SINDy motion identification: CV for a straight track, turn terms for a constant turn,
calibrated prediction intervals."""
import numpy as np
import pytest

from estimators.trackers.sindy_model import identify_motion
from xnlos_core import InputError, InsufficientDataError

T = np.arange(40) * 0.1  # 4 s at 10 Hz


def turn(t, omega, speed, heading=0.0):
    """Constant-turn path [m] starting at the origin: turn rate omega [rad/s], speed [m/s]."""
    if omega == 0:
        return np.c_[speed * np.cos(heading) * t, speed * np.sin(heading) * t]
    return np.c_[speed / omega * (np.sin(omega * t + heading) - np.sin(heading)),
                 speed / omega * (np.cos(heading) - np.cos(omega * t + heading))]


def test_straight_track_gives_constant_velocity():
    rng = np.random.default_rng(0)
    z = turn(T, 0.0, 9.0, 0.4) + 0.1 * rng.standard_normal((len(T), 2))
    for sigma in (0.1, None):
        model = identify_motion(T, z, sigma, n_models=10)
        assert model.terms() == [] and not model.ensemble.any()
    assert model.sigma == pytest.approx(0.1, rel=0.3)


def test_constant_turn_gives_turn_terms_and_predicts_2s():
    rng = np.random.default_rng(1)
    z = turn(T, 0.3, 10.0) + 0.1 * rng.standard_normal((len(T), 2))
    model = identify_motion(T, z, 0.1, n_models=10)
    assert model.terms() == ["vx'=vy", "vy'=vx"]
    assert model.coefficients[1, 0] == pytest.approx(0.3, abs=0.03)    # ω
    assert model.coefficients[0, 1] == pytest.approx(-0.3, abs=0.03)   # −ω
    pred = model.predict([1.0, 2.0, 3.0])
    truth = turn(T[-1] + np.array([1.0, 2.0, 3.0]), 0.3, 10.0)
    assert np.linalg.norm(pred.mean[1] - truth[1]) < 0.6  # a CV extrapolation misses by ≈ 7 m
    assert np.all(np.diff(pred.radius90) > 0) and np.all(pred.radius50 < pred.radius90)


def test_interval_coverage_near_nominal():
    rng = np.random.default_rng(5)
    n, c50, c90 = 20, 0, 0
    for i in range(n):
        omega = rng.uniform(-0.4, 0.4) if i % 2 else 0.0
        speed, heading = rng.uniform(5, 15), rng.uniform(0, 2 * np.pi)
        z = turn(T, omega, speed, heading) + 0.1 * rng.standard_normal((len(T), 2))
        pred = identify_motion(T, z, 0.1, n_models=5, seed=i).predict([2.0])
        err = np.linalg.norm(pred.mean[0] - turn(T[-1:] + 2.0, omega, speed, heading)[0])
        c50, c90 = c50 + (err <= pred.radius50[0]), c90 + (err <= pred.radius90[0])
    assert c90 / n >= 0.8, (c50 / n, c90 / n)
    assert 0.3 <= c50 / n <= 0.9


def test_errors():
    with pytest.raises(InsufficientDataError, match="≥ 8 samples"):
        identify_motion(T[:5], np.zeros((5, 2)))
    with pytest.raises(InputError, match="strictly increasing"):
        identify_motion(T[::-1], np.zeros((40, 2)))
    with pytest.raises(InputError, match="xy"):
        identify_motion(T, np.zeros((39, 2)))
    with pytest.raises(InsufficientDataError, match="identically zero"):
        identify_motion(T, turn(T, 0.0, 5.0), 0.1)
    model = identify_motion(T, turn(T, 0.0, 5.0, heading=1.0), 0.1, n_models=5)
    with pytest.raises(InputError, match=r"within \[0, 3\] s"):
        model.predict([4.0])


def test_noiseless_constant_turn_coefficients_within_1e3():
    # Acceptance (issue 28): the closed-form constant turn of xnlos_core.motion, no noise.
    from xnlos_core.motion import ConstantTurn

    xy = ConstantTurn(speed=10.0, yaw_rate=0.3).state(T, (5.0, 2.0), 0.7).position
    model = identify_motion(T, xy, 1e-3, n_models=5)
    assert model.terms() == ["vx'=vy", "vy'=vx"]
    assert np.allclose(model.coefficients, [[0.0, -0.3], [0.3, 0.0]], atol=1e-3)
    assert model.evidence > 100


def test_flow_jacobian_matches_finite_differences_and_expm():
    # The refit's exact Jacobian (one augmented exponential, Van Loan) against central differences of
    # positions computed by scipy's expm per time — on the integer grid (repeated products) and off it.
    from scipy.linalg import expm

    from estimators.trackers.sindy_model import _jacobian, _positions, _system

    mask = np.array([[True, True], [True, False]])
    theta = np.array([1.0, -2.0, 8.0, 3.0, -0.2, -0.3, 0.25])
    xi = np.zeros((2, 2))
    xi[mask] = theta[4:]

    def direct(th, dts):
        x = np.zeros((2, 2))
        x[mask] = th[4:]
        return np.array([expm(_system(x) * d)[:2] @ th[:4] for d in dts])

    for dts in (-0.1 * np.array([29, 20, 7, 3, 0]), np.array([0.37, 1.0, 2.9])):
        assert np.allclose(_positions(theta, mask, dts), direct(theta, dts), atol=1e-10)
        fd = np.stack([(direct(theta + e, dts) - direct(theta - e, dts)).ravel() / 2e-6
                       for e in 1e-6 * np.eye(len(theta))], axis=1)
        assert np.allclose(_jacobian(theta, mask, dts), fd, atol=1e-6)
