"""Range to failure: bisection of the distance behind the corner, and seeded bootstrap intervals of
the ranges and their ratios (the cross-modality study, :mod:`xnlos_core.app.crossmodal.study`).

Bisection (:func:`bisect_range`): given a trial's success as a function of distance d [m] (one
seed, the study's existing score), it first tests the sweep's two ends; a failure at ``lower``
means the range is below the sweep ("below"), a success at ``upper`` that it is beyond it
("above"): both are bounds, not measurements. Otherwise it halves the bracket [lo, hi] (success
at lo, failure at hi) at the geometric midpoint √(lo·hi) — ranges span orders of magnitude, so the
bracket shrinks by the same factor whatever the scale — rounded to 1 mm so that the distances (and
the cells saved under them) are the same on every machine, until hi/lo ≤ 1 + ``rel_tol``. The
range is lo, the largest distance seen to succeed. It assumes success is monotone in d (true of
the expected signal; a noisy trial may succeed again beyond its first failure, and bisection then
reports one of its transitions, the one its bracket holds).

Row range and bootstrap (:func:`median_interval`, :func:`ratio_interval`): a seed whose bisection
ended at a bound is CENSORED — its range is only known to be below the lower bound or above the
upper one (:func:`censored_values` writes them 0 and inf, which sort right). The row's range is the
lower median over seeds, a measurement as long as it falls on a bracketed seed (fewer than half
the seeds censored on either side); a mean would mix the bounds in. Its interval is the percentile
bootstrap over resampled seeds (the resampling Generator seeded by the caller, the study's
``seed``); an interval end that lands on a censored value is that bound. A ratio of two rows is the
ratio of their medians, the two sets of seeds resampled independently.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Literal

import numpy as np

from xnlos_core.errors import InputError

Status = Literal["bracketed", "above", "below"]
STEP = 1e-3  # [m] bisection distances are rounded to this


@dataclass(frozen=True)
class BisectResult:
    """One seed's range to failure: ``range`` [m] the largest distance seen to succeed (None when the
    sweep's lower end already fails); ``lo``, ``hi`` [m] the final bracket (success at lo, failure at
    hi; None on the side the sweep's bound was reached); ``status`` "bracketed" | "above" (still
    succeeds at the upper end) | "below" (fails at the lower end); ``evaluations`` the (d, success)
    pairs in the order tested."""

    range: float | None
    lo: float | None
    hi: float | None
    status: Status
    evaluations: tuple[tuple[float, bool], ...]

    def as_dict(self) -> dict:
        return {"range": self.range, "lo": self.lo, "hi": self.hi, "status": self.status,
                "evaluations": [[d, ok] for d, ok in self.evaluations]}


def bisect_range(success: Callable[[float], bool], lower: float, upper: float, *, rel_tol: float = 0.03,
                 max_iter: int = 60) -> BisectResult:
    """Bisect ``success`` (distance [m] → bool) between ``lower`` and ``upper`` [m] (module docstring)."""
    if not (math.isfinite(lower) and math.isfinite(upper) and 0 < lower < upper):
        raise InputError(f"bisect_range(lower, upper): expected 0 < lower < upper [m], got {lower}, {upper}")
    if not rel_tol > 0:
        raise InputError(f"bisect_range(rel_tol): expected a positive relative bracket width, got {rel_tol}")
    seen: list[tuple[float, bool]] = []

    def test(d: float) -> bool:
        ok = bool(success(d))
        seen.append((d, ok))
        return ok

    if not test(lower):
        return BisectResult(None, None, lower, "below", tuple(seen))
    if test(upper):
        return BisectResult(upper, upper, None, "above", tuple(seen))
    lo, hi = lower, upper
    for _ in range(max_iter):
        if hi <= lo * (1 + rel_tol):
            break
        mid = round(math.sqrt(lo * hi) / STEP) * STEP
        if not lo < mid < hi:  # the 1 mm grid cannot split the bracket further
            break
        if test(mid):
            lo = mid
        else:
            hi = mid
    return BisectResult(lo, lo, hi, "bracketed", tuple(seen))


@dataclass(frozen=True)
class Interval:
    """A statistic's ``value`` and its bootstrap interval [``low``, ``high``] at ``level``. A
    censored value (module docstring) shows as 0 (below the sweep) or inf (above it)."""

    value: float
    low: float
    high: float
    level: float

    def as_dict(self) -> dict:
        return {"value": self.value, "low": self.low, "high": self.high, "level": self.level}


def censored_values(runs) -> np.ndarray:
    """Per-seed ranges [m] of :class:`BisectResult` dicts as numbers that sort right: a bracketed
    range as itself, "below" (failed at the lower bound) as 0, "above" (still in range at the upper
    bound) as inf — every bracketed range lies between the two bounds, so the order is exact."""
    out = []
    for r in runs:
        st = r["status"] if isinstance(r, dict) else r.status
        rng = r["range"] if isinstance(r, dict) else r.range
        out.append(0.0 if st == "below" else math.inf if st == "above" else float(rng))
    return np.asarray(out, float)


def _check(name: str, values) -> np.ndarray:
    v = np.asarray(values, float).reshape(-1)
    if not len(v) or np.any(np.isnan(v)) or np.any(v < 0):
        raise InputError(f"{name}: expected at least one range ≥ 0 [m] (0: below the sweep, inf: above it), "
                         f"got {values!r}")
    return v


def lower_median(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """The ⌈n/2⌉-th smallest value along ``axis`` (the lower median: always one of the values, so a
    censored value never enters an average)."""
    n = x.shape[axis]
    return np.take(np.sort(x, axis=axis), (n - 1) // 2, axis=axis)


def _percentiles(stat: np.ndarray, level: float) -> tuple[float, float]:
    """Percentile interval of bootstrap replicates that may hold inf (and NaN, dropped: 0/0 ratios of
    two resamples both censored below)."""
    s = stat[~np.isnan(stat)]
    if not len(s):
        return math.nan, math.nan
    lo, hi = np.quantile(s, [(1 - level) / 2, (1 + level) / 2], method="inverted_cdf")
    return float(lo), float(hi)


def median_interval(values, *, seed: int, level: float = 0.95, resamples: int = 2000) -> Interval:
    """Lower median of the per-seed ranges ``values`` (n,) [m] (censored as in
    :func:`censored_values`) and its percentile-bootstrap interval over resampled seeds, numpy
    Generator seeded by ``seed``.

    Written here rather than with ``scipy.stats.bootstrap``: the ranges are censored at the sweep's
    bounds (0 and inf), which scipy's bootstrap does not take; the median stays a measurement while
    fewer than half the seeds are censored, and an interval end that reaches a censored value is
    reported as that bound (0 or inf)."""
    v = _check("median_interval(values)", values)
    m = float(lower_median(v))
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(v), size=(resamples, len(v)))
    lo, hi = _percentiles(lower_median(v[idx]), level)
    return Interval(m, lo, hi, level)


def ratio_interval(a, b, *, seed: int, level: float = 0.95, resamples: int = 2000) -> Interval:
    """Ratio of lower medians med(a) / med(b) of two sets of per-seed ranges [m] (censored as in
    :func:`censored_values`), and its percentile-bootstrap interval with ``a`` and ``b``
    resampled independently (numpy Generator seeded by ``seed``; see :func:`median_interval` for
    why by hand). An end at 0 or inf is a bound reached by censoring."""
    a = _check("ratio_interval(a)", a)
    b = _check("ratio_interval(b)", b)
    rng = np.random.default_rng(seed)
    ia = rng.integers(0, len(a), size=(resamples, len(a)))
    ib = rng.integers(0, len(b), size=(resamples, len(b)))
    with np.errstate(divide="ignore", invalid="ignore"):
        value = float(np.divide(lower_median(a), lower_median(b)))
        stat = lower_median(a[ia]) / lower_median(b[ib])
    lo, hi = _percentiles(stat, level)
    return Interval(value, lo, hi, level)
