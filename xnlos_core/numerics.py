"""Discrete choices that do not hinge on rounding: variance floors and tie rules.

Why: a model order, a support or a detection count must be the same on every machine. Two BLAS
kernels (``OPENBLAS_CORETYPE``), thread counts or processor families round differently in the last
bits. Where a criterion compares candidates whose difference is of that size, the choice follows
the kernel, not the data. Two mechanisms close that door:

* **Variance floors** (:func:`variance_floor`). A noiseless fit leaves a residual sum of squares at
  rounding level, and ``log(RSS)`` of rounding noise spans tens of nats: enough to pick any
  candidate. Every profiled-out variance is floored at ``(√ε · scale)²`` per sample, ε the float64
  machine epsilon (≈ 2.2e-16) and ``scale`` the magnitude of the data (metres, metres per second):
  ≈ 1.5e-8 of the data's size, far above the rounding of any computation in the project
  (ε times a condition number of at most ~1e6) and far below any sensor's noise.
* **Ties towards the simpler candidate** (:func:`simplest_within`). Candidates whose criterion lies
  within a stated tolerance of the best one count as tied; the simplest of them wins (fewest
  parameters, then the first in the caller's order). A discrete outcome can then change only where
  the criterion's margin is below that tolerance, and there the rule, not the rounding, decides.

Tolerances (stated here, used across stages):

* :data:`CRITERION_TOL` = 1e-6 nats, absolute, plus 1e-9 of the criterion's magnitude: a
  log-likelihood over n ≤ 1e5 samples rounds at ~1e-11 relative.
* :data:`PEAK_RTOL` = 1e-6: two map cells whose powers agree to 1e-6 (≈ 4e-6 dB) are one plateau.
  Float32 network outputs round at 6e-8 relative, so this is ≈ 16 float32 ulps.
* :data:`COST_RTOL` = 1e-9: association costs (distances) agreeing to 1e-9 of their scale tie.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

EPS = float(np.finfo(np.float64).eps)
SQRT_EPS = float(np.sqrt(EPS))
CRITERION_TOL = 1e-6
CRITERION_RTOL = 1e-9
PEAK_RTOL = 1e-6
COST_RTOL = 1e-9


def data_scale(*arrays) -> float:
    """The magnitude of the data: the largest finite |value| over ``arrays`` (same unit), at least
    the smallest normal float so a floor built from it is positive."""
    top = 0.0
    for a in arrays:
        a = np.asarray(a, dtype=np.float64)
        fin = a[np.isfinite(a)]
        if fin.size:
            top = max(top, float(np.abs(fin).max()))
    return max(top, float(np.finfo(np.float64).tiny))


def variance_floor(scale: float, n: int = 1) -> float:
    """The floor of a residual sum of squares over ``n`` samples of data of magnitude ``scale``:
    n · (√ε · scale)² [unit²] (module docstring). ``n = 1`` gives the per-sample variance floor."""
    return max(int(n), 1) * EPS * float(scale) ** 2


def criterion_tolerance(values) -> float:
    """The tie tolerance [nats or the criterion's unit] for criteria ``values``:
    CRITERION_TOL + CRITERION_RTOL · max |value| over the finite ones."""
    v = np.asarray(values, dtype=np.float64)
    fin = v[np.isfinite(v)]
    return CRITERION_TOL + CRITERION_RTOL * (float(np.abs(fin).max()) if fin.size else 0.0)


def simplest_within(values: Sequence[float], complexity: Sequence[float], *, larger_is_better: bool = False,
                    tol: float | None = None) -> int:
    """Index of the winning candidate: among those whose criterion is within ``tol`` of the best
    (default :func:`criterion_tolerance`), the one of least ``complexity`` (number of parameters,
    support size), the first in order among equals. Non-finite criteria never win unless all are.

    values (K,): the criterion (smaller is better, e.g. BIC; ``larger_is_better`` for a
    log-evidence). complexity (K,): how many free parameters each candidate has."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1 or v.size == 0 or len(complexity) != v.size:
        raise ValueError(f"simplest_within: need K ≥ 1 values and K complexities, got {v.shape} "
                         f"and {len(complexity)}")
    s = -v if larger_is_better else v
    fin = np.isfinite(s)
    if not fin.any():
        return 0
    tol = criterion_tolerance(v) if tol is None else float(tol)
    best = float(s[fin].min())
    tied = np.flatnonzero(fin & (s <= best + tol))
    c = np.asarray(complexity, dtype=np.float64)[tied]
    return int(tied[np.flatnonzero(c == c.min())[0]])


def margin(values: Sequence[float], chosen: int, *, larger_is_better: bool = False) -> float:
    """How far the runner-up is from the chosen candidate's criterion (≥ 0 when ``chosen`` is the
    best; +inf with one candidate): the figure a discrete choice's stability is judged by."""
    v = np.asarray(values, dtype=np.float64)
    s = -v if larger_is_better else v
    rest = np.delete(s, chosen)
    rest = rest[np.isfinite(rest)]
    return float(rest.min() - s[chosen]) if rest.size else float("inf")


def snap(values, rtol: float = COST_RTOL) -> np.ndarray:
    """``values`` rounded to a grid of rtol · max |value|, so values equal up to rounding become equal
    and a deterministic tie rule (the first index) decides between them. Non-finite values pass."""
    v = np.asarray(values, dtype=np.float64)
    step = rtol * data_scale(v)
    out = v.copy()
    fin = np.isfinite(v)
    out[fin] = np.round(v[fin] / step) * step
    return out


def gated_assignment(cost, gate: float) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one assignment of rows to columns of ``cost`` (R, C) minimising the total cost over the
    pairs with cost ≤ ``gate`` (scipy.optimize.linear_sum_assignment): as many gated pairs as possible,
    then the least total cost. Costs are first :func:`snap`-ped to COST_RTOL of the gate, so two
    candidate pairings whose costs agree up to rounding tie exactly and scipy's deterministic order
    (the lower index) decides on every machine. Returns (rows (K,), cols (K,)) of the gated pairs."""
    from scipy.optimize import linear_sum_assignment

    c = np.asarray(cost, dtype=np.float64)
    if c.size == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    inside = c <= gate
    step = COST_RTOL * max(abs(float(gate)), float(np.finfo(np.float64).tiny))
    snapped = np.where(inside, np.round(np.where(inside, c, 0.0) / step) * step, 0.0)
    big = float(gate) * (min(c.shape) + 1)  # any gated pair beats all out-of-gate ones
    rows, cols = linear_sum_assignment(np.where(inside, snapped, big))
    ok = inside[rows, cols]
    return rows[ok].astype(np.int64), cols[ok].astype(np.int64)


def first_best(values, tol: float, *, larger_is_better: bool = False) -> int:
    """Index of the first of ``values`` (K,) within ``tol`` of the best (the smallest, or the largest
    with ``larger_is_better``): an argmin/argmax whose answer does not follow rounding when several
    values tie (a point on both sides of a corner, equal distances). Non-finite values never win
    unless all are."""
    v = np.asarray(values, dtype=np.float64)
    s = -v if larger_is_better else v
    fin = np.isfinite(s)
    if not fin.any():
        return 0
    return int(np.flatnonzero(fin & (s <= s[fin].min() + tol))[0])
