"""Numerical extremes of the probabilistic wall estimators: a clear error or a finite, honest
(wide where the data are weak) posterior."""
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from estimators.casadi_map import CasadiMapWallEstimator
from estimators.emcee_wall import EmceeWallEstimator
from xnlos_core import Detections, InsufficientDataError
from xnlos_core.geometry import cartesian_to_polar

FAST_EMCEE = {"n_steps": 400, "burn": 100}


def polar_detections(points, range_std, azimuth_std, rng=None):
    """Detections at points with stated errors; with ``rng`` the errors are also drawn."""
    r, a = cartesian_to_polar(np.asarray(points, float))
    k = len(r)
    if rng is not None:
        r = np.abs(r + range_std * rng.standard_normal(k))
        a = a + azimuth_std * rng.standard_normal(k)
    return Detections(r, a, np.zeros(k, np.int8), np.ones(k), np.full(k, range_std), np.full(k, azimuth_std))


def estimators():
    return [CasadiMapWallEstimator(), EmceeWallEstimator(FAST_EMCEE)]


def check_finite(w, max_sd=None):
    assert np.all(np.isfinite(w.mean)) and np.all(np.isfinite(w.cov))
    assert np.linalg.eigvalsh(w.cov).min() >= -1e-12 * max(1.0, np.abs(w.cov).max())
    if w.samples is not None:
        assert np.all(np.isfinite(w.samples))
    if max_sd is not None:
        assert np.all(np.sqrt(np.diag(w.cov)) < max_sd)


def run(est, det):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # short test chains
        return est.estimate(det)


def test_two_los_points_give_a_finite_wide_line():
    det = polar_detections([[20.0, -1.5], [20.0, 1.5]], 0.07, 0.02)
    for est in estimators():
        (w,) = run(est, det)
        assert w.model == "line" and w.n_points == 2
        check_finite(w)
        sd = np.sqrt(np.diag(w.cov))
        # two points 3 m apart with 7 cm range errors: φ uncertain to a few degrees
        assert 0.01 < sd[0] < 0.5 and 0.03 < sd[1] < 10.0, sd


def test_coincident_points_are_a_clear_error():
    det = polar_detections([[20.0, 1.0]] * 5, 0.07, 0.02)
    for est in estimators():
        with pytest.raises(InsufficientDataError, match="coincide"):
            est.estimate(det)


def test_one_los_point_is_a_clear_error():
    for est in estimators():
        with pytest.raises(InsufficientDataError, match="at least 2"):
            est.estimate(polar_detections([[20.0, 1.0]], 0.07, 0.02))


def test_exactly_colinear_points_keep_the_stated_noise():
    pts = np.stack([np.full(10, 15.0), np.linspace(-4, 4, 10)], 1)  # no residual at all
    for est in estimators():
        (w,) = run(est, polar_detections(pts, 0.05, 0.01))
        check_finite(w)
        sd_b = np.sqrt(w.cov[1, 1])
        assert sd_b > 0.005  # the stated 5 cm errors, not a zero-width posterior
        assert w.offset == pytest.approx(15.0, abs=0.2 * sd_b)  # (emcee: Monte-Carlo error)


def test_wall_seen_edge_on():
    # Every point on one ray from the radar: the wall line passes through the radar (b ≈ 0),
    # its position across the ray rests on the azimuth errors only.
    pts = np.stack([np.linspace(10, 30, 12), np.zeros(12)], 1)
    det = polar_detections(pts, 0.07, 0.02, np.random.default_rng(4))
    for est in estimators():
        (w,) = run(est, det)
        check_finite(w)
        assert abs(abs(w.normal[1]) - 1) < 0.05 and w.offset < 1.0
        assert np.sqrt(w.cov[1, 1]) > 0.05  # honest: cross-range errors are r·σ_θ ≈ 0.2–0.6 m


def test_wall_one_kilometre_away():
    rng = np.random.default_rng(0)
    y = np.linspace(-20, 20, 21)
    pts = np.stack([1000.0 + 0.05 * y, y], 1)
    r, a = cartesian_to_polar(pts)
    det = Detections(r + rng.normal(0, 0.07, 21), a + rng.normal(0, 0.002, 21), np.zeros(21, np.int8),
                     np.ones(21), np.full(21, 0.07), np.full(21, 0.002))
    for est in estimators():
        (w,) = run(est, det)
        check_finite(w)
        n_true = np.array([-1.0, 0.05]) / np.hypot(1.0, 0.05)
        assert np.degrees(np.arccos(min(1.0, w.normal @ n_true))) < 3 * np.degrees(np.sqrt(w.cov[0, 0])) + 0.05
        assert w.offset == pytest.approx(-n_true @ pts[10], abs=max(0.5, 4 * np.sqrt(w.cov[1, 1])))


@pytest.mark.parametrize("roughness", [0.02, 0.0])
def test_micrometre_noise(roughness):
    rng = np.random.default_rng(1)
    pts = np.stack([np.full(12, 25.0), np.linspace(-5, 5, 12)], 1) + rng.normal(0, 1e-6, (12, 2))
    det = polar_detections(pts, 1e-6, 1e-6 / 25.0)
    for est in (CasadiMapWallEstimator({"wall_roughness": roughness}),
                EmceeWallEstimator({**FAST_EMCEE, "wall_roughness": roughness})):
        (w,) = run(est, det)
        check_finite(w)
        sd_b = np.sqrt(w.cov[1, 1])
        if roughness:  # the wall's own 2 cm roughness, not the detector's 1 µm, limits the fit
            assert 1e-3 < sd_b < 0.05
        else:
            assert 1e-8 < sd_b < 1e-5 and abs(w.offset - 25.0) < 1e-5


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dist=st.floats(0.5, 2000.0), incidence=st.floats(-1.4, 1.4), azimuth=st.floats(-1.0, 1.0),
       n=st.integers(2, 25), length=st.floats(0.01, 30.0), range_std=st.floats(1e-6, 1.0),
       azimuth_std=st.floats(1e-6, 0.1), seed=st.integers(0, 2**16))
def test_random_geometry_is_finite_or_a_clear_error(dist, incidence, azimuth, n, length, range_std,
                                                    azimuth_std, seed):
    rng = np.random.default_rng(seed)
    p0 = dist * np.array([np.cos(azimuth), np.sin(azimuth)])
    c, s = np.cos(incidence), np.sin(incidence)
    to_radar = -p0 / dist
    nrm = np.array([c * to_radar[0] - s * to_radar[1], s * to_radar[0] + c * to_radar[1]])
    u = np.array([-nrm[1], nrm[0]])
    pts = p0 + np.linspace(-length / 2, length / 2, n)[:, None] * u
    r, a = cartesian_to_polar(pts)
    r = np.abs(r + range_std * rng.standard_normal(n))
    a = np.angle(np.exp(1j * (a + azimuth_std * rng.standard_normal(n))))
    det = Detections(r, a, np.zeros(n, np.int8), np.ones(n), np.full(n, range_std), np.full(n, azimuth_std))
    try:
        walls = CasadiMapWallEstimator({"cluster_distance": 1e3}).estimate(det)
    except InsufficientDataError as exc:
        assert "coincide" in str(exc) or "at least 2" in str(exc)
        return
    for w in walls:
        check_finite(w)
        assert w.info["solver_status"]


ALL_ESTIMATORS = ("lsq", "casadi_map", "emcee")


def _estimator(name):
    from xnlos_core.registry import get_registry

    return get_registry().create("wall_estimator", name, FAST_EMCEE if name == "emcee" else {})


@pytest.mark.parametrize("name", ALL_ESTIMATORS)
def test_points_beyond_a_million_metres_are_a_clear_error(name):
    # 1e300-m point sets crashed all three estimators inside scipy (linkage: "the
    # condensed distance matrix must contain only finite values").
    from xnlos_core import InputError

    y = np.linspace(-3, 3, 6)
    for far in (1e300, 2e6):
        det = polar_detections(np.c_[np.full(6, far), y * far], 0.05, 0.005)
        with pytest.raises(InputError, match=r"LOS detection 0 lies at .*≤ 1e\+06 m"):
            run(_estimator(name), det)


@pytest.mark.parametrize("name", ALL_ESTIMATORS)
def test_position_errors_beyond_a_million_metres_are_a_clear_error(name):
    from xnlos_core import InputError

    det = polar_detections(np.c_[np.full(6, 8.0), np.linspace(-3, 3, 6)], 1e160, 0.005)
    with pytest.raises(InputError, match=r"position error of LOS detection 0 is inf m \(range_std 1e\+160"):
        run(_estimator(name), det)
    # Found by the fuzz suite (casadi_map): finite errors of 1e5 … 1e154 m made the Hessian non-finite.
    rs = [1.3150e53, 6.6427e133, 2.6735e74, 1.1865e32, 9.9909e153, 1.0461e36]
    r, a = cartesian_to_polar(np.array([[5.94, -3.77], [5.88, -3.08], [6.03, -2.64], [6.01, -1.44], [5.97, -0.89],
                                        [6.0, -0.44]]))
    det = Detections(r, a, np.zeros(6, np.int8), np.ones(6), rs, np.full(6, 0.005))
    with pytest.raises(InputError, match=r"position error of LOS detection 0 is 1.315e\+53 m .* exceed 1e\+06 m"):
        run(_estimator(name), det)


@pytest.mark.parametrize("name", ALL_ESTIMATORS)
def test_non_finite_points_cannot_reach_an_estimator(name):
    from xnlos_core import InputError

    with pytest.raises(InputError, match="NaN or infinite"):
        polar_detections([[8.0, np.nan], [8.0, 1.0]], 0.05, 0.005)
    det = polar_detections([[8.0, -1.0], [8.0, 0.0], [8.0, 1.0]], 0.05, 0.005)
    with pytest.raises(ValueError, match="read-only"):
        det.range[0] = np.inf  # validated arrays are read-only: no corruption after the check
    (w,) = run(_estimator(name), det)
    check_finite(w)


@pytest.mark.parametrize("name", ALL_ESTIMATORS)
def test_a_wall_at_the_coordinate_bound_is_finite(name):
    # Just inside 1e6 m, the largest coordinate accepted, with errors up to the 1e6-m bound: finite numbers.
    for range_std in (0.05, 0.9e6):
        det = polar_detections(np.c_[np.full(9, 0.999e6), np.linspace(-8, 8, 9)], range_std, 1e-7)
        (w,) = run(_estimator(name), det)
        check_finite(w)
        if range_std < 1:  # with 1e6-m range errors the data say little about b: finite is all
            assert w.offset == pytest.approx(0.999e6, rel=1e-6)


@pytest.mark.parametrize("name", ALL_ESTIMATORS)
def test_stated_errors_far_beyond_the_points_spread(name):
    # Found by tests/test_fuzz_stages.py (lsq, case 796): two LOS points 2.6 µm apart with 1e150-m
    # range errors made the (φ, b) covariance σ²/Σt² overflow, and WallPosterior refused its inf.
    from estimators.lsq import fit_line
    from xnlos_core import InputError

    pts = np.array([[5.3195702504717297e-07, 2.2044942112221658e-06], [-4.9367819161480194e-07, 2.2905021169838597e-06]])
    r, a = cartesian_to_polar(pts)
    det = Detections(r, a, np.zeros(2, np.int8), np.ones(2), [2.533681660412863e150, 2.110085718768139e147],
                     [0.005, 0.005])
    with pytest.raises(InputError, match="largest position standard deviation"):
        run(_estimator(name), det)
    # fit_line itself (public, given the covariances directly) refuses to return an infinite covariance
    with pytest.raises(InsufficientDataError, match="covariance overflows"):
        fit_line(pts, np.eye(2)[None].repeat(2, 0) * 1e300)


def test_emcee_on_a_blob_whose_map_leaves_the_support_is_a_clear_error():
    # Found by tests/test_fuzz_stages.py (emcee, case 6086): nine LOS points within 0.6 mm of the
    # radar. IPOPT's MAP turned ≥ 90° from the TLS line, outside the sampler's support, and emcee
    # raised a bare ValueError ("Initial state has a large condition number").
    pts = np.array([[2.6709842817221525e-04, 4.4382918458732791e-05], [6.6193499597254281e-05, 2.5670146477869163e-04],
                    [1.3096358330089858e-04, 3.8977203734151887e-05], [-2.8448779267700226e-04, -9.8973445567192804e-05],
                    [6.8044033748190495e-05, 6.8894549206060317e-05], [-1.3545164855301584e-04, 2.1897173030350502e-04],
                    [2.6537689987098280e-04, -2.9591640451331864e-04], [3.6570515711415335e-05, 1.0308891958959924e-04],
                    [2.4497223234772817e-04, -3.0503936854529753e-04]])
    az = [2.5253818587084143e-12, 1.0918204620729659e-10, 1.1677066344300853, 2.0014306423796018e-07,
          1.6080438077999854e-07, 2.9078707989593550e-01, 2.3920272978733361e-07, 3.7103972840044097e-11,
          2.0599552802074648e-10]
    r, a = cartesian_to_polar(pts)
    det = Detections(r, a, np.zeros(9, np.int8), np.ones(9), np.full(9, 0.05), az)
    est = EmceeWallEstimator({"n_walkers": 8, "n_steps": 40, "burn": 10, "min_ess": 0.0})
    with pytest.raises(InsufficientDataError, match="outside the sampler's support.*do not determine a wall direction"):
        run(est, det)
