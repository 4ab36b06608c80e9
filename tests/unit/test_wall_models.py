"""Wall models (line, arc): geometry, Eq. 7 across an arc, the likelihood in numpy and casadi,
and the 'arc' WallPosterior."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from estimators.calibration import wall_point
from estimators.likelihood import LikelihoodConfig, WallLikelihood
from estimators.map_solver import hessian
from xnlos_core import InputError, WallPosterior
from xnlos_core.geometry import mirror_reflect
from xnlos_core.wall import canonical, flip_normal, mirror, nearest_points, ray_hits, signed_distance

pytestmark = pytest.mark.kernels  # numerically sensitive: `make test-kernels` runs it under several BLAS kernels


def _arc(phi, b, kappa, anchor):
    return np.array([phi, b, kappa]), np.asarray(anchor, float)


@settings(max_examples=60, deadline=None)
@given(phi=st.floats(-np.pi, np.pi), r0=st.floats(5.0, 500.0), kappa=st.floats(-0.1, 0.1),
       s=st.floats(-8.0, 8.0), h=st.floats(-2.0, 2.0))
def test_arc_signed_distance_is_distance_along_the_normal(phi, r0, kappa, s, h):
    n = np.array([np.cos(phi), np.sin(phi)])
    anchor = -r0 * n  # tangent point at distance r0 from the radar
    theta = np.array([phi, r0, kappa])
    p, nrm = wall_point(theta, anchor, np.array([s]))
    x = p + h * nrm
    assert signed_distance("arc", theta, x, anchor)[0] == pytest.approx(h, abs=1e-9 * (1 + r0))
    assert np.allclose(nearest_points("arc", theta, x, anchor)[0], p, atol=1e-8 * (1 + r0))


def test_arc_with_zero_curvature_is_the_line():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-40, 40, (50, 2))
    theta_l = np.array([0.7, 12.0])
    theta_a = np.array([0.7, 12.0, 0.0])
    anchor = np.array([3.0, -4.0])
    assert np.allclose(signed_distance("arc", theta_a, pts, anchor), signed_distance("line", theta_l, pts))
    n = np.array([np.cos(0.7), np.sin(0.7)])
    far = pts[pts @ n + 12.0 < 0]
    o_arc, hit = mirror("arc", theta_a, far, anchor)
    assert np.allclose(o_arc, mirror_reflect(far, n, 12.0), atol=1e-9)
    assert np.allclose(mirror("line", theta_l, far)[0], mirror_reflect(far, n, 12.0))


def test_mirror_across_arc_uses_the_local_tangent():
    # Circle of radius 20 centred at (40, 0): the arc bulges towards the radar (κ > 0) at x = 20.
    theta, anchor = _arc(np.pi, 20.0, 1 / 20, [20.0, 0.0])
    virt = np.array([[30.0, 15.0]])
    t, nq = ray_hits("arc", theta, virt, anchor)
    q = t[0] * virt[0]
    assert np.linalg.norm(q - [40.0, 0.0]) == pytest.approx(20.0, abs=1e-9)  # on the circle
    assert np.allclose(nq[0], (q - [40.0, 0.0]) / 20.0)  # outward normal at q
    o, hit = mirror("arc", theta, virt, anchor)
    assert hit.all()
    assert np.allclose(o[0], mirror_reflect(virt[0], nq[0], -nq[0] @ q))
    # Batched over parameter samples: one row per sample.
    batch = np.stack([theta, theta + [0.0, 0.1, 0.0]])
    ob, _ = mirror("arc", batch, virt, anchor)
    assert ob.shape == (2, 1, 2) and np.allclose(ob[0], o)


def test_ray_missing_an_arc_falls_back_to_the_tangent_line():
    theta, anchor = _arc(np.pi, 20.0, 1 / 5, [20.0, 0.0])  # small circle centred at (25, 0)
    virt = np.array([[10.0, 40.0]])  # this ray passes far from the circle
    o, hit = mirror("arc", theta, virt, anchor)
    assert not hit[0]
    assert np.allclose(o[0], mirror_reflect(virt[0], [-1.0, 0.0], 20.0))


@pytest.mark.parametrize("model,eps,scale", [("line", 0.1, True), ("arc", 0.1, True), ("arc", 0.0, False),
                                             ("line", 0.0, False)])
def test_numpy_and_casadi_posteriors_agree(model, eps, scale):
    rng = np.random.default_rng(1)
    pts = np.stack([20 + rng.normal(0, 0.2, 11), np.linspace(-6, 6, 11)], 1)
    cov = np.tile(np.diag([0.01, 0.09]), (11, 1, 1))
    cfg = LikelihoodConfig(outlier_fraction=eps, estimate_noise_scale=scale)
    lik = WallLikelihood(model, pts, cov, cfg, phi_ref=np.pi)
    theta = np.array([np.pi + 0.01, 20.1] + ([0.01] if model == "arc" else []) + ([0.2] if scale else []))
    f, grad, h, ll = hessian(lik, theta)
    assert -f == pytest.approx(lik.log_prob(theta[None])[0], rel=1e-10, abs=1e-9)
    assert ll == pytest.approx(lik.log_likelihood(theta[None])[0], rel=1e-10, abs=1e-9)
    num = np.array([(lik.log_prob((theta + e)[None])[0] - lik.log_prob((theta - e)[None])[0]) / 2e-6
                    for e in 1e-6 * np.eye(len(theta))])
    assert np.allclose(-grad, num, rtol=1e-4, atol=1e-4)


def test_likelihood_support_and_errors():
    pts = np.array([[10.0, -1.0], [10.0, 1.0], [10.0, 2.0]])
    cov = np.tile(np.eye(2) * 0.01, (3, 1, 1))
    lik = WallLikelihood("line", pts, cov, LikelihoodConfig(), phi_ref=np.pi)
    lp = lik.log_prob(np.array([[np.pi, 10.0, 0.0], [0.0, -10.0, 0.0], [np.pi, 30.0, 0.0]]))
    assert np.isfinite(lp[0]) and lp[1] == -np.inf and lp[2] == -np.inf  # flipped normal; far wall
    with pytest.raises(InputError, match="wall_roughness = 0"):
        WallLikelihood("line", pts, np.zeros((3, 2, 2)), LikelihoodConfig(wall_roughness=0.0))
    with pytest.raises(InputError, match="wall model"):
        WallLikelihood("spline", pts, cov, LikelihoodConfig())


def test_arc_posterior_is_canonical_and_keeps_the_wall():
    anchor = np.array([20.0, 3.0])
    w = WallPosterior.arc([1.0, 0.0], -20.0, -0.05, anchor=anchor, cov=np.diag([1e-4, 1e-2, 1e-5]) + 1e-6)
    assert w.model == "arc" and w.param_names == ("phi", "b", "kappa")
    assert w.offset == pytest.approx(20.0) and np.allclose(w.normal, [-1.0, 0.0])
    assert w.curvature == pytest.approx(0.05)  # n flipped → κ flipped: the same circle
    assert np.allclose(w.tangent_point, [20.0, 3.0])
    assert w.cov[0, 1] == pytest.approx(-1e-6) and w.cov[1, 2] == pytest.approx(1e-6)
    flipped = mirror("arc", np.array([0.0, -20.0, -0.05]), [[30.0, 5.0]], anchor)[0]
    assert np.allclose(mirror("arc", w.mean, [[30.0, 5.0]], w.anchor)[0], flipped)
    with pytest.raises(InputError, match="'arc' has 3 parameters"):
        WallPosterior("arc", [0.0, 1.0], np.eye(2))
    with pytest.raises(InputError, match="anchor"):
        WallPosterior.arc([1.0, 0.0], 5.0, 0.0, anchor=[1.0, 2.0, 3.0])
    line = WallPosterior.line([1.0, 0.0], -5.0)
    assert line.curvature == 0.0 and np.allclose(line.tangent_point, [5.0, 0.0])


@pytest.mark.parametrize("model, theta", [("line", [0.3, -12.0]), ("arc", [2.9, -15.0, 0.02])])
def test_the_flipped_normal_is_the_same_wall_and_canonical_undoes_it(model, theta):
    anchor = np.array([10.0, 4.0])
    pts = np.array([[20.0, 5.0], [30.0, -8.0], [25.0, 1.0]])
    cov = np.diag(np.arange(1.0, len(theta) + 1)) + 0.1
    samples = np.array(theta) + 0.01 * np.arange(2 * len(theta)).reshape(2, -1)
    flipped, fcov, fsamples = flip_normal(theta, cov, samples)
    assert np.allclose(signed_distance(model, flipped, pts, anchor), -signed_distance(model, theta, pts, anchor))
    assert np.allclose(mirror(model, flipped, pts, anchor)[0], mirror(model, theta, pts, anchor)[0])
    assert np.allclose(np.diag(fcov), np.diag(cov)) and fcov[0, 1] == -cov[0, 1]
    assert np.allclose(fsamples[:, 1:], -samples[:, 1:])
    c_theta, c_cov, c_samples = canonical(theta, cov, samples)  # b < 0 here: canonical flips it
    assert c_theta[1] > 0 and -np.pi < c_theta[0] <= np.pi
    assert np.allclose(np.cos(c_theta[0]), np.cos(flipped[0])) and np.allclose(c_theta[1:], flipped[1:])
    assert np.allclose(c_cov, fcov) and np.allclose(np.cos(c_samples[:, 0]), np.cos(fsamples[:, 0]))
    wall = WallPosterior(model, theta, cov, param_names=("phi", "b", "kappa")[:len(theta)],
                         anchor=anchor if model == "arc" else None)
    assert wall.mean[1] == pytest.approx(c_theta[1]) and np.allclose(wall.cov, fcov)
