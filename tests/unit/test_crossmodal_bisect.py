"""Bisection to failure and bootstrap intervals of the cross-modality study
(xnlos_core/app/crossmodal/bisect.py) on synthetic cases with a known answer."""
import numpy as np
import pytest
from scipy.stats import norm

from xnlos_core.app.crossmodal.bisect import bisect_range, censored_values, median_interval, ratio_interval
from xnlos_core.errors import InputError


@pytest.mark.parametrize("threshold", [0.73, 17.3, 121.0])
def test_bisection_finds_a_known_threshold_of_a_monotone_success(threshold):
    r = bisect_range(lambda d: d <= threshold, 0.5, 150.0, rel_tol=0.01)
    assert r.status == "bracketed" and r.lo <= threshold < r.hi and r.hi <= r.lo * 1.01 + 1e-3
    assert r.range == r.lo
    assert [d for d, _ in r.evaluations[:2]] == [0.5, 150.0]
    # every tested distance is on the 1 mm grid (reproducible cells)
    assert all(abs(d * 1000 - round(d * 1000)) < 1e-6 for d, _ in r.evaluations)
    assert len(r.evaluations) <= 2 + int(np.ceil(np.log2(np.log(300) / np.log(1.01)))) + 1


def test_bisection_reports_the_sweeps_bounds():
    up = bisect_range(lambda d: True, 1.0, 60.0)
    assert up.status == "above" and up.range == 60.0 and up.hi is None and len(up.evaluations) == 2
    down = bisect_range(lambda d: False, 1.0, 60.0)
    assert down.status == "below" and down.range is None and down.hi == 1.0 and len(down.evaluations) == 1
    with pytest.raises(InputError, match="lower"):
        bisect_range(lambda d: True, 5.0, 1.0)


def test_bootstrap_interval_contains_the_truth():
    """Synthetic seeds whose sample median is the truth (normal quantiles around it, odd n): the
    interval holds the truth; the ratio of two such sets holds the true ratio."""
    q = norm.ppf((np.arange(41) + 0.5) / 41)
    x = 10.0 + q
    iv = median_interval(x, seed=3)
    assert iv.low < 10.0 < iv.high and iv.value == pytest.approx(10.0)
    assert median_interval(x, seed=3) == iv  # seeded: the same interval again
    a, b = 20.0 + q, 4.0 + 0.2 * q[::-1]
    r = ratio_interval(a, b, seed=5)
    assert r.low < 5.0 < r.high and r.value == pytest.approx(5.0)


def test_coverage_of_the_bootstrap_interval_is_near_its_level():
    """Over 200 synthetic studies of 15 seeds, the 90 % interval of the median covers the true median
    (of an exponential, 8·ln 2) in roughly 90 % of them."""
    rng = np.random.default_rng(11)
    truth = 8.0 * np.log(2)
    hits = 0
    for k in range(200):
        iv = median_interval(rng.exponential(8.0, 15), seed=k, level=0.9, resamples=500)
        hits += iv.low <= truth <= iv.high
    assert 0.8 <= hits / 200 <= 0.99


def test_censored_seeds():
    """Seeds at the sweep's bounds sort right (0 below, inf above); the median stays a measurement
    while it falls on a bracketed seed, and an interval end on a censored seed is that bound."""
    runs = [bisect_range(lambda d, t=t: d <= t, 0.5, 150.0) for t in (0.2, 0.3, 2.0, 3.0, 4.0, 5.0, 500.0)]
    v = censored_values(runs)
    assert v[0] == v[1] == 0 and np.isinf(v[-1]) and 1.9 < v[2] <= 2.0
    iv = median_interval(v, seed=1, resamples=500)
    assert iv.value == v[3] and iv.low == 0 and np.isfinite(iv.value)
    assert median_interval([0.0, 0.0, 0.0, 2.0], seed=1).value == 0  # the median is a bound
    assert np.isinf(ratio_interval([np.inf] * 3, [2.0] * 3, seed=0).value)


def test_degenerate_samples():
    iv = median_interval([4.0, 4.0, 4.0], seed=0)
    assert (iv.value, iv.low, iv.high) == (4.0, 4.0, 4.0)
    assert ratio_interval([8.0], [2.0], seed=0).value == 4.0
    with pytest.raises(InputError):
        median_interval([1.0, float("nan")], seed=0)
