"""Mirror Doppler (plugins.mirror.mirror_doppler): closed forms across a known wall, covariance vs Monte Carlo."""
import numpy as np
import pytest

from xnlos_core import WallPosterior
from xnlos_core.errors import InputError
from plugins.mirror.mirror_doppler import observed_direction, unmirror_radial_velocity, unmirror_velocity
from xnlos_core.wall import mirror

# the wall x = 20 m (n = (−1, 0), b = 20: the radar side positive), (φ, b) uncertain
WALL_MEAN = np.array([np.pi, 20.0])
WALL_COV = np.array([[4e-4, 1e-4], [1e-4, 4e-2]])
HIDDEN = np.array([[14.0, -12.0], [10.0, -20.0]])  # behind the corner, on the radar side of the wall
V_HIDDEN = np.array([[0.0, 8.0], [3.0, 1.0]])  # [m/s]


def _virtual(theta=WALL_MEAN):
    return mirror("line", theta, HIDDEN)[0]


def test_velocity_across_a_known_wall_flips_its_normal_component():
    v, cov = unmirror_velocity(_virtual(), V_HIDDEN * [-1, 1], np.zeros((2, 2, 2)), WallPosterior("line", WALL_MEAN,
                                                                                                    np.zeros((2, 2))))
    np.testing.assert_allclose(v, V_HIDDEN, atol=1e-12)
    np.testing.assert_allclose(cov, 0.0, atol=1e-12)


def test_velocity_covariance_matches_monte_carlo_over_wall_samples():
    rng = np.random.default_rng(1)
    wall = WallPosterior("line", WALL_MEAN, WALL_COV)
    vp = V_HIDDEN * [-1, 1]
    vcov = np.array([[[0.04, 0.01], [0.01, 0.09]]] * 2)
    v, cov = unmirror_velocity(_virtual(), vp, vcov, wall)
    thetas = rng.multivariate_normal(WALL_MEAN, WALL_COV, 50_000)
    n = np.stack([np.cos(thetas[:, 0]), np.sin(thetas[:, 0])], -1)  # (S, 2)
    for i in range(2):
        vs = vp[i] + rng.multivariate_normal(np.zeros(2), vcov[i], len(thetas))
        out = vs - 2 * np.sum(n * vs, -1, keepdims=True) * n  # (I − 2nnᵀ) v' per sample
        np.testing.assert_allclose(out.mean(0), v[i], atol=0.01)
        np.testing.assert_allclose(np.cov(out.T), cov[i], rtol=0.04, atol=2e-3)


def test_radial_velocity_gives_the_hidden_velocity_along_the_bounce_to_object_direction():
    wall = WallPosterior("line", WALL_MEAN, np.zeros((2, 2)))
    virt = _virtual()
    v_virtual = V_HIDDEN * [-1, 1]
    r_hat = virt / np.linalg.norm(virt, axis=1, keepdims=True)
    vr = np.sum(r_hat * v_virtual, 1)  # what the radar measures
    w, _ = unmirror_radial_velocity(virt, vr, np.zeros(2), wall)
    q = virt * (20.0 / virt[:, :1])  # where the ray radar → o' meets x = 20
    g_hat = (HIDDEN - q) / np.linalg.norm(HIDDEN - q, axis=1, keepdims=True)
    np.testing.assert_allclose(observed_direction(virt, wall), g_hat, atol=1e-12)
    np.testing.assert_allclose(w, np.sum(V_HIDDEN * g_hat, 1)[:, None] * g_hat, atol=1e-9)


def test_radial_velocity_covariance_matches_monte_carlo():
    rng = np.random.default_rng(2)
    wall = WallPosterior("line", WALL_MEAN, WALL_COV)
    virt = _virtual()
    vr, var = np.array([4.0, -2.5]), np.array([0.01, 0.04])
    az_sd = 0.05  # its share of the covariance is as large as the wall's
    c, s = virt[:, 0] / np.linalg.norm(virt, axis=1), virt[:, 1] / np.linalg.norm(virt, axis=1)
    tangent = np.stack([-s, c], -1) * np.linalg.norm(virt, axis=1, keepdims=True)
    pcov = az_sd**2 * tangent[:, :, None] * tangent[:, None, :]  # azimuth error only
    w, cov = unmirror_radial_velocity(virt, vr, var, wall, point_cov=pcov)
    thetas = rng.multivariate_normal(WALL_MEAN, WALL_COV, 50_000)
    n = np.stack([np.cos(thetas[:, 0]), np.sin(thetas[:, 0])], -1)
    for i in range(2):
        az = np.arctan2(virt[i, 1], virt[i, 0]) + az_sd * rng.standard_normal(len(thetas))
        r_hat = np.stack([np.cos(az), np.sin(az)], -1)
        g = r_hat - 2 * np.sum(n * r_hat, -1, keepdims=True) * n  # unit: a reflection
        out = (vr[i] + np.sqrt(var[i]) * rng.standard_normal(len(thetas)))[:, None] * g
        np.testing.assert_allclose(out.mean(0), w[i], atol=0.01)
        np.testing.assert_allclose(np.cov(out.T), cov[i], rtol=0.05, atol=5e-4)


def test_bad_input_is_an_input_error():
    wall = WallPosterior("line", WALL_MEAN, WALL_COV)
    with pytest.raises(InputError, match="velocity_cov"):
        unmirror_velocity(_virtual(), np.zeros((2, 2)), np.zeros((3, 2, 2)), wall)
    with pytest.raises(InputError, match="radial_var"):
        unmirror_radial_velocity(_virtual(), np.zeros(2), -np.ones(2), wall)
    with pytest.raises(InputError, match="WallPosterior"):
        unmirror_velocity(_virtual(), np.zeros((2, 2)), np.zeros((2, 2, 2)), None)


def test_mirror_reconstructor_fills_the_velocity_only_when_detections_carry_one():
    from plugins.mirror.mirror import MirrorReconstructor
    from xnlos_core import MNLOS, Detections

    wall = WallPosterior("line", WALL_MEAN, WALL_COV)
    virt = _virtual()
    plain = Detections.from_points(virt, MNLOS, 1.0, 0.1, 0.01)
    with_doppler = Detections(*(getattr(plain, f) for f in ("range", "azimuth", "label", "confidence", "range_std",
                                                            "azimuth_std")), velocity=[4.0, -2.5],
                              velocity_var=[0.01, 0.04])
    rec = MirrorReconstructor()
    before, after = rec.reconstruct(plain, [wall]), rec.reconstruct(with_doppler, [wall])
    assert before.velocity is None and before.velocity_cov is None
    np.testing.assert_array_equal(after.mean, before.mean)
    np.testing.assert_array_equal(after.cov, before.cov)
    w, cov = unmirror_radial_velocity(virt, [4.0, -2.5], [0.01, 0.04], wall, point_cov=plain.position_cov())
    np.testing.assert_allclose(after.velocity, w, rtol=1e-12)
    np.testing.assert_allclose(after.velocity_cov, cov, rtol=1e-12)
    # the rows keep their velocity through select / concat
    assert np.array_equal(with_doppler.select([1]).velocity, [-2.5])
    assert Detections.concat(with_doppler, plain).velocity is None


@pytest.mark.parametrize("kwargs, match", [({"velocity_var": [0.1]}, "without Detections.velocity"),
                                           ({"velocity": [1.0], "velocity_var": [-0.1]}, "velocity_var"),
                                           ({"velocity": [1.0, 2.0]}, "Detections.velocity")])
def test_detections_doppler_fields_are_checked(kwargs, match):
    from xnlos_core import Detections

    with pytest.raises(InputError, match=match):
        Detections([10.0], [0.1], [1], [1.0], **kwargs)


def test_velocity_across_an_arc_is_the_rate_of_the_mirrored_position():
    wall = WallPosterior("arc", np.array([np.pi, 20.0, 0.02]), np.diag([1e-4, 1e-2, 1e-5]),
                         param_names=("phi", "b", "kappa"), anchor=np.array([20.0, 0.0]))
    virt, vp, dt = np.array([[26.0, -9.0], [30.0, 4.0]]), np.array([[-3.0, 2.0], [1.0, -4.0]]), 1e-5
    v, cov = unmirror_velocity(virt, vp, np.zeros((2, 2, 2)), wall)
    rate = (mirror("arc", wall.mean, virt + dt * vp, wall.anchor)[0]
            - mirror("arc", wall.mean, virt - dt * vp, wall.anchor)[0]) / (2 * dt)
    np.testing.assert_allclose(v, rate, atol=1e-5)
    assert np.all(np.linalg.eigvalsh(cov) > 0)  # the wall's uncertainty reaches the velocity
