"""The sindy tracker's manoeuvre library: batched identification of many tracks' motion over a small
library of manoeuvres, and its forecast.

Every library entry is linear in its parameters θ once a few shape parameters are fixed on a grid,
so one batched least-squares solve per entry (numpy einsum + ``numpy.linalg.solve`` over all tracks
and grid values at once) identifies every due track of a frame. Times τ = t − t_ref [s] (τ ≤ 0 in the
window, t_ref its last sample), positions p(τ) = B(τ) θ with B (2, P). The entries — constant velocity
(``cv``), a constant acceleration along the path's line (``line``: braking, speeding up, reversing),
a turn with or without a speed change (``turn``, ``turn_accel``), a lane change (``lane``) and a settled
speed change or velocity step (``ramp``, ``kink``) — compete by a likelihood-ratio test against CV and
then by BIC (Eq. 1), from the positions and, where a track has them, its radial velocities (Eq. 2); the
selected entry forecasts with the entries' BIC-weighted spread about it, from the fit's own path or
anchored at a filter's state (Eqs. 3–4). Equation numbers run across the package.

Which file holds what:

* :mod:`~estimators.trackers.library.entries`: the library's names, sizes, grids and limits
  (``LIBRARY``, ``OMEGA_GRID``, ``LANE_*``, ``KINK_TIMES``, ``CV_SURE``, ``CV_BENT``, ``MIN_WEIGHT`` …),
  the road users' :class:`Envelope`, a fitted :class:`Entry` and a track's :class:`LibraryFit`.
* :mod:`~estimators.trackers.library.bases`: each entry's basis B(τ), its derivative and its forecast
  path (the entries' equations), and the grids of their shape parameters.
* :mod:`~estimators.trackers.library.fit`: the batched least squares of every entry and grid value over
  the tracks sampled at the same times (and why it is hand-written on numpy rather than with pysindy).
* :mod:`~estimators.trackers.library.doppler`: the radial-velocity rows stacked under the position
  rows and the refit with them.
* :mod:`~estimators.trackers.library.selection`: the test and BIC of Eqs. (1)–(2), the labels (brake,
  reverse, …), the envelope, and :func:`demote`.
* :mod:`~estimators.trackers.library.identify`: :func:`identify_batch`, the entry point.
* :mod:`~estimators.trackers.library.predict`: :func:`predict` and :func:`predict_many` (Eqs. 3–4).

:mod:`estimators.trackers.motion_library` re-exports this package's names (the library's former single
module).
"""
from __future__ import annotations

from .bases import basis, forecast_basis, forecast_velocity_basis, hyper_grid, readonly, velocity_basis
from .doppler import MIN_RADIAL, RADIAL_SHARES, fit_doppler, radial_rows
from .entries import (BETA_MAX, CV_BENT, CV_SURE, KINK_TIMES, LANE_ANGLES, LANE_CENTRES, LANE_MAX, LANE_SCALES,
                      LIBRARY, MIN_BEFORE, MIN_SAMPLES, MIN_WEIGHT, N_LINEAR, N_PARAMS, OMEGA_GRID, TURN_OVER_LANE,
                      VECTORS, Entry, Envelope, LibraryFit)
from .fit import FULL, fit_group, pick, shared_designs
from .identify import identify_batch, line_direction, lr_threshold
from .predict import predict, predict_many
from .selection import criteria, demote, select_fit

__all__ = [
    # entries: names, sizes, grids, limits and the result types
    "LIBRARY", "N_PARAMS", "VECTORS", "N_LINEAR", "OMEGA_GRID", "LANE_CENTRES", "LANE_ANGLES", "KINK_TIMES",
    "LANE_SCALES", "LANE_MAX", "BETA_MAX", "MIN_SAMPLES", "MIN_BEFORE", "TURN_OVER_LANE", "CV_SURE", "CV_BENT",
    "MIN_WEIGHT", "Envelope", "Entry", "LibraryFit",
    # bases
    "basis", "velocity_basis", "forecast_basis", "forecast_velocity_basis", "hyper_grid", "readonly",
    # fit
    "FULL", "shared_designs", "pick", "fit_group",
    # doppler
    "RADIAL_SHARES", "MIN_RADIAL", "radial_rows", "fit_doppler",
    # selection
    "criteria", "select_fit", "demote",
    # identify
    "identify_batch", "line_direction", "lr_threshold",
    # predict
    "predict", "predict_many",
]
