"""Per-frame motion truth (sims.scene_truth) against closed forms."""
import numpy as np
import pytest

from xnlos_core.errors import InputError
from xnlos_core.scene import ObjectSpec, Scene, WallSpec
from sims.scene_truth import scene_truth


def _scene():
    # a wall along x = 20 m (normal (−1, 0)); a car turning at 0.1 rad/s, a parked box, a CV point
    return Scene(walls=[WallSpec(name="facade", start=(20.0, -30.0), end=(20.0, 30.0)),
                        WallSpec(name="fence", start=(0.0, 40.0), end=(10.0, 40.0), relay=False)],
                 objects=[ObjectSpec(name="car", center=(12.0, -15.0), heading=np.pi / 2,
                                     trajectory={"model": "constant_turn", "speed": 5.0, "yaw_rate": 0.1}),
                          ObjectSpec(name="parked", center=(15.0, 5.0)),
                          ObjectSpec(name="walker", shape="point", center=(10.0, 0.0), velocity=(1.0, 0.5))])


def test_objects_and_their_mirror_images_across_a_known_wall():
    truth = scene_truth(_scene(), 2.0)
    assert truth.names == ("car", "parked", "walker") and len(truth.walls) == 1  # the fence relays nothing
    heading = np.pi / 2 + 0.2
    np.testing.assert_allclose(truth.velocity[0], 5.0 * np.array([np.cos(heading), np.sin(heading)]), atol=1e-12)
    np.testing.assert_allclose(truth.heading, [heading, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(truth.position[2], [12.0, 1.0])
    np.testing.assert_array_equal(truth.velocity[1:], [[0.0, 0.0], [1.0, 0.5]])
    # across x = 20: x → 40 − x and vx → −vx
    np.testing.assert_allclose(truth.mirrored_position[:, 0], np.c_[40.0 - truth.position[:, 0],
                                                                    truth.position[:, 1]], atol=1e-12)
    np.testing.assert_allclose(truth.mirrored_velocity[:, 0], truth.velocity * [-1.0, 1.0], atol=1e-12)


def test_mirrored_velocity_is_the_rate_of_the_mirrored_position():
    scene, dt = _scene(), 1e-4
    a, b = scene_truth(scene, 3.0 - dt), scene_truth(scene, 3.0 + dt)
    rate = (b.mirrored_position - a.mirrored_position) / (2 * dt)
    np.testing.assert_allclose(rate, scene_truth(scene, 3.0).mirrored_velocity, atol=1e-6)


def test_bad_input_is_an_input_error():
    with pytest.raises(InputError, match="finite time"):
        scene_truth(_scene(), float("nan"))
    with pytest.raises(InputError, match=r"walls\[0\]"):
        scene_truth(_scene(), 0.0, walls=[(0.0, 1.0)])


def test_image_model_ground_truth_carries_the_hidden_and_mirrored_velocities():
    from sims.image import ImageForwardModel
    from xnlos_core.radar import RadarConfig

    wall = WallSpec(name="facade", start=(20.0, -30.0), end=(20.0, 30.0), reflectivity=0.6, backscatter_db=-80)
    car = ObjectSpec(name="car", shape="point", center=(12.0, -8.0), heading=0.3,
                     trajectory={"model": "constant_turn", "speed": 4.0, "yaw_rate": 0.2})
    frame = ImageForwardModel({"noise": False}).simulate(Scene(walls=[wall], objects=[car]), RadarConfig(),
                                                         np.random.default_rng(0), timestamp=1.5)
    gt = frame.ground_truth
    assert len(gt.mnlos_points) >= 1
    truth = scene_truth(Scene(walls=[wall], objects=[car]), 1.5)
    np.testing.assert_allclose(gt.hidden_velocity, np.broadcast_to(truth.velocity[0], gt.hidden_velocity.shape),
                               atol=1e-12)
    np.testing.assert_allclose(gt.mnlos_velocity, gt.hidden_velocity * [-1.0, 1.0], atol=1e-12)
    kept = gt.above_snr(-1e9)
    np.testing.assert_array_equal(kept.mnlos_velocity, gt.mnlos_velocity)


def test_motion_kind_follows_the_trajectory_model():
    from xnlos_core.motion import Bicycle, ConstantAcceleration, ConstantTurn
    from sims.scene_truth import is_moving, motion_kind

    parked = ObjectSpec(name="p", center=(5.0, 5.0))
    assert not is_moving(parked) and motion_kind(parked, 6.0) == "static"
    assert motion_kind(ObjectSpec(name="a", center=(5.0, 5.0), velocity=(0.0, 8.0)), 6.0) == "straight"
    # Braking 10 m/s at 3 m/s² stops at 3.3 s: a 10 m/s speed loss over 6 s.
    brake = ObjectSpec(name="b", center=(5.0, 5.0), trajectory=ConstantAcceleration(speed=10.0, acceleration=-3.0))
    assert is_moving(brake) and motion_kind(brake, 6.0) == "braking"
    # ω = 0.05 rad/s turns 0.3 rad over 6 s (turning) but only 0.05 rad over 1 s (below TURN_MIN_RAD).
    turn = ObjectSpec(name="c", center=(5.0, 5.0), trajectory=ConstantTurn(speed=5.0, yaw_rate=0.05))
    assert motion_kind(turn, 6.0) == "turning" and motion_kind(turn, 1.0) == "straight"
    # Bicycle: heading change v·t·tan δ / L = 5·6·tan(0.01)/1.1 ≈ 0.27 rad.
    bike = ObjectSpec(name="d", center=(5.0, 5.0), trajectory=Bicycle(wheelbase=1.1, steering=0.01, speed=5.0))
    assert motion_kind(bike, 6.0) == "turning"
    with pytest.raises(InputError, match="duration"):
        motion_kind(bike, float("nan"))
