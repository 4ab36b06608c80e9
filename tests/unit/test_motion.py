"""Trajectories (xnlos_core.motion) against their closed forms, and the scene's trajectory key."""
import math

import numpy as np
import pytest

from xnlos_core.errors import ConfigError
from xnlos_core.motion import Bicycle, ConstantAcceleration, ConstantTurn, ConstantVelocity
from xnlos_core.scene import ObjectSpec, load_scene

T = np.linspace(0.0, 20.0, 401)


def _centre_of_turn(start, heading, radius):
    """Centre of the circle a left turn of ``radius`` starting at ``start`` along ``heading`` runs on."""
    return np.asarray(start) + radius * np.array([-math.sin(heading), math.cos(heading)])


@pytest.mark.parametrize("omega", [0.3, -0.5])
def test_constant_turn_runs_on_a_circle_of_radius_v_over_omega(omega):
    v, heading, start = 6.0, 0.7, (10.0, -3.0)
    s = ConstantTurn(speed=v, yaw_rate=omega).state(T, start, heading)
    radius = v / omega  # signed: > 0 turns left
    np.testing.assert_allclose(np.linalg.norm(s.position - _centre_of_turn(start, heading, radius), axis=1),
                               abs(radius), rtol=1e-12)
    np.testing.assert_allclose(s.heading, heading + omega * T, rtol=1e-12)
    np.testing.assert_array_equal(s.yaw_rate, omega)
    np.testing.assert_allclose(np.linalg.norm(s.velocity, axis=1), v, rtol=1e-12)
    # velocity is the time derivative of position
    np.testing.assert_allclose(np.gradient(s.position, T, axis=0)[1:-1], s.velocity[1:-1], atol=2e-3)


@pytest.mark.parametrize("omega", [0.0, 1e-12, -1e-9])
def test_constant_turn_at_zero_yaw_rate_is_a_straight_line(omega):
    s = ConstantTurn(speed=4.0, yaw_rate=omega).state(T, (1.0, 2.0), 0.5)
    expected = np.array([1.0, 2.0]) + 4.0 * T[:, None] * np.array([math.cos(0.5), math.sin(0.5)])
    assert np.all(np.isfinite(s.position))
    np.testing.assert_allclose(s.position, expected, atol=1e-6)


def test_braking_stops_after_v2_over_2a_and_stays():
    v, a, heading = 12.0, -3.0, -1.1
    s = ConstantAcceleration(speed=v, acceleration=a).state(T, (0.0, 0.0), heading)
    travelled = s.position @ np.array([math.cos(heading), math.sin(heading)])
    stop = v / -a
    np.testing.assert_allclose(travelled[T >= stop], v * v / (2 * -a), rtol=1e-12)
    np.testing.assert_allclose(s.velocity[T >= stop], 0.0, atol=1e-12)
    assert np.all(np.diff(travelled) >= 0)  # never reverses
    np.testing.assert_allclose(np.linalg.norm(s.velocity, axis=1), np.maximum(v + a * T, 0.0), atol=1e-12)


def test_bicycle_without_steering_is_a_straight_line():
    s = Bicycle(wheelbase=2.7, steering=0.0, speed=5.0, acceleration=0.5).state(T, (3.0, 4.0), 1.0)
    u = np.array([math.cos(1.0), math.sin(1.0)])
    np.testing.assert_allclose(s.position, np.array([3.0, 4.0]) + (5.0 * T + 0.25 * T**2)[:, None] * u, rtol=1e-12)
    np.testing.assert_allclose(s.heading, 1.0)


@pytest.mark.parametrize("delta", [0.2, -0.4])
def test_bicycle_with_constant_steering_runs_on_a_circle_of_radius_l_over_tan_delta(delta):
    L, start, heading = 2.7, (0.0, 5.0), 0.3
    s = Bicycle(wheelbase=L, steering=delta, speed=3.0, acceleration=0.2).state(T, start, heading)
    radius = L / math.tan(delta)
    np.testing.assert_allclose(np.linalg.norm(s.position - _centre_of_turn(start, heading, radius), axis=1),
                               abs(radius), rtol=1e-12)
    # heading rate v·tan δ / L (the bicycle's kinematics)
    speed = np.linalg.norm(s.velocity, axis=1)
    np.testing.assert_allclose(np.gradient(s.heading, T)[1:-1], (speed * math.tan(delta) / L)[1:-1], rtol=1e-3)
    np.testing.assert_allclose(s.yaw_rate, speed * math.tan(delta) / L, rtol=1e-12)


def test_constant_velocity_object_is_unchanged():
    obj = ObjectSpec(center=(22.0, -14.0), heading=1.5708, velocity=(0.0, 2.0))
    for t in (0.0, 0.1, 2.5):
        np.testing.assert_array_equal(obj.center_at(t), np.asarray(obj.center) + t * np.asarray(obj.velocity))
        assert obj.heading_at(t) == obj.heading
    assert "trajectory" not in obj.model_dump() and "trajectory" not in obj.model_dump_json()
    m = obj.motion([0.0, 0.1, 2.5])
    np.testing.assert_array_equal(m.position[2], obj.center_at(2.5))
    np.testing.assert_array_equal(m.velocity, [[0.0, 2.0]] * 3)
    cv = ObjectSpec(center=(22.0, -14.0), trajectory={"model": "constant_velocity", "velocity": (0.0, 2.0)})
    np.testing.assert_array_equal(cv.center_at(2.5), obj.center_at(2.5))


def test_trajectory_turns_the_box_and_round_trips():
    obj = ObjectSpec(center=(20.0, -10.0), heading=0.5, trajectory={"model": "constant_turn", "speed": 5.0,
                                                                      "yaw_rate": 0.2})
    assert obj.heading_at(2.0) == pytest.approx(0.9)
    pts, nrm, _ = obj.scatterers(2.0)
    np.testing.assert_allclose(pts.mean(axis=0), obj.center_at(2.0), atol=1e-9)
    assert ObjectSpec.model_validate(obj.model_dump()) == obj


def _scene(obj: dict) -> dict:
    return {"objects": [{"name": "car", "center": [20.0, -10.0], **obj}]}


@pytest.mark.parametrize("obj, match", [
    ({"velocity": [1.0, 0.0], "trajectory": {"model": "constant_turn", "speed": 1.0, "yaw_rate": 0.1}},
     "not both"),
    ({"trajectory": {"model": "constant_turn", "speed": -1.0, "yaw_rate": 0.1}}, "trajectory.*speed"),
    ({"trajectory": {"model": "bicycle", "speed": 1.0, "steering": 2.0}}, "trajectory.*steering"),
    ({"trajectory": {"model": "teleport"}}, "trajectory"),
    ({"trajectory": {"model": "constant_acceleration", "speed": 1.0, "acceleration": float("nan")}},
     "acceleration"),
])
def test_bad_trajectory_is_a_config_error_naming_the_key(obj, match):
    with pytest.raises(ConfigError, match=match):
        load_scene(_scene(obj), "scene.toml")
