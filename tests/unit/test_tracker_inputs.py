"""Every registered tracker refuses absurd hidden points and timestamps at its boundary with an
InputError naming the input (estimators/trackers/frames.py), and the Kalman family solves a singular
but finite innovation covariance instead of raising numpy's LinAlgError."""
import numpy as np
import pytest

from estimators.trackers.frames import MAX_POSITION, MAX_STD, MAX_TIMESTAMP, MIN_FRAME_INTERVAL
from xnlos_core import HiddenPoints, InputError
from xnlos_core.registry import get_registry

TRACKERS = get_registry().names("tracker")


def hidden(points, cov=None, velocity=None, velocity_cov=None):
    pts = np.asarray(points, float).reshape(-1, 2)
    k = len(pts)
    cov = np.tile(0.01 * np.eye(2), (k, 1, 1)) if cov is None else np.asarray(cov, float).reshape(k, 2, 2)
    return HiddenPoints(pts, cov, np.arange(k), np.zeros(k, np.int64), velocity, velocity_cov)


def tracker(name, **params):
    return get_registry().create("tracker", name, params)


@pytest.mark.parametrize("name", TRACKERS)
def test_points_beyond_the_scene_bound_are_refused(name):
    """1e300 m made scipy's linkage raise a bare ValueError; anything beyond ±10 km is refused."""
    for x in (1e300, -2 * MAX_POSITION, MAX_POSITION * (1 + 1e-12)):
        with pytest.raises(InputError, match=r"points\.mean\[1\] = .* lies beyond ±10000 m"):
            tracker(name).update(hidden([[5.0, 5.0], [x, 0.0]]), 0.0)
    out = tracker(name, confirm_hits=1).update(hidden([[MAX_POSITION, -MAX_POSITION]]), 0.0) \
        if name != "nearest" else tracker(name).update(hidden([[MAX_POSITION, -MAX_POSITION]]), 0.0)
    assert np.all(np.isfinite(out.position))


@pytest.mark.parametrize("name", TRACKERS)
def test_huge_singular_covariance_is_refused(name):
    """A singular 1e300 m² covariance made the Kalman solve raise LinAlgError."""
    with pytest.raises(InputError, match=r"points\.cov\[0\] has a standard deviation of 1\.41421e\+150 m"):
        tracker(name).update(hidden([[1.0, 2.0]], [[1e300, 1e300], [1e300, 1e300]]), 0.0)
    big = (2 * MAX_STD) ** 2
    with pytest.raises(InputError, match=r"expected ≤ 1e\+06 m"):
        tracker(name).update(hidden([[1.0, 2.0]], np.diag([big, 0.0])), 0.0)


@pytest.mark.parametrize("name", TRACKERS)
def test_covariances_must_be_symmetric_psd(name):
    with pytest.raises(InputError, match=r"points\.cov\[0\] = .* is not symmetric"):
        tracker(name).update(hidden([[1.0, 2.0]], [[1.0, 0.5], [0.0, 1.0]]), 0.0)
    with pytest.raises(InputError, match=r"points\.cov\[0\] = .* has eigenvalues .*positive semi-definite"):
        tracker(name).update(hidden([[1.0, 2.0]], [[1.0, 2.0], [2.0, 1.0]]), 0.0)
    with pytest.raises(InputError, match=r"points\.velocity_cov\[0\] = .* positive semi-definite"):
        tracker(name).update(hidden([[1.0, 2.0]], velocity=[[1.0, 0.0]], velocity_cov=[-np.eye(2)]), 0.0)


@pytest.mark.parametrize("name", TRACKERS)
def test_absurd_velocities_are_refused(name):
    with pytest.raises(InputError, match=r"points\.velocity\[0\] = .* expected finite and ≤ 1000 m/s"):
        tracker(name).update(hidden([[1.0, 2.0]], velocity=[[1e300, 0.0]], velocity_cov=[np.eye(2)]), 0.0)


@pytest.mark.parametrize("name", TRACKERS)
def test_absurd_timestamps_are_refused(name):
    for t in (1e300, -2 * MAX_TIMESTAMP):
        with pytest.raises(InputError, match=r"timestamp .* lies beyond ±1e\+10 s"):
            tracker(name).update(hidden([[1.0, 2.0]]), t)
    tr = tracker(name)
    tr.update(hidden([[1.0, 2.0]]), 1.0)
    with pytest.raises(InputError, match=r"frames must be at least 1e-06 s apart"):
        tr.update(hidden([[1.0, 2.0]]), 1.0 + MIN_FRAME_INTERVAL / 10)
    out = tr.update(hidden([[1.0, 2.0]]), 1.0 + 2 * MIN_FRAME_INTERVAL)  # 2 µs apart: valid, finite
    assert np.all(np.isfinite(out.position)) and np.all(np.isfinite(out.velocity))
    # epoch seconds work
    tr = tracker(name)
    for k in range(3):
        out = tr.update(hidden([[10.0 + k, 2.0]]), 1.7e9 + 0.1 * k)
    assert np.all(np.isfinite(out.position))


@pytest.mark.parametrize("name", [n for n in TRACKERS if n != "nearest"])
def test_singular_finite_innovation_covariance_is_solved(name):
    """Exact points (zero covariance) with a floor whose square underflows, seen twice at one instant
    (kalman takes a repeated timestamp as a second measurement, Δt = 0: no process noise), make the
    innovation covariance S exactly singular; the tracker regularises it instead of raising numpy's
    LinAlgError, and reports finite tracks."""
    repeat = name == "kalman"  # sindy refuses Δt = 0: there S stays regular, checked for finiteness alone
    times = [0.0, 0.0, 0.0, 0.1] if repeat else [0.0, 0.1, 0.2, 0.3]
    tr = tracker(name, sigma_floor=1e-300, extent_sigma=0.0, confirm_hits=1)
    for t in times:
        out = tr.update(hidden([[3.0, 1.0]], np.zeros((1, 2, 2))), t)
        assert np.all(np.isfinite(out.position)) and np.all(np.isfinite(out.velocity))
    assert out.track_id.tolist() == [0]
    rank_one = np.array([[1e6, 1e6], [1e6, 1e6]])  # finite, singular, within the bounds
    tr = tracker(name, sigma_floor=1e-300, extent_sigma=0.0, confirm_hits=1)
    for t in times:
        out = tr.update(hidden([[3.0, 1.0], [30.0, 1.0]], np.stack([rank_one, np.zeros((2, 2))])), t)
        for f in ("position", "velocity", "forecast", "radius90"):
            assert np.all(np.isfinite(getattr(out, f))), f
