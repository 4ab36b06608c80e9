"""Input checks shared by the trackers: one frame's hidden points and its timestamp, and the
forecast horizons parameter.

Every tracker's ``update`` goes through :func:`frame_time` first, so each refuses the same inputs
with the same messages (InputError naming the tracker, the input, its value and what is allowed):

* hidden points (``HiddenPoints.mean``) beyond ±``MAX_POSITION`` [m] in x or y — the scene bound
  (:data:`xnlos_core.scene.MAX_COORD`, 10 km): a hidden object is in the scene, and mirrored points
  lie within a few times the radar's reach (≤ 1 km), so anything farther is an upstream fault;
* position covariances (``HiddenPoints.cov``) that are not symmetric positive semi-definite, or whose
  standard deviation along their major axis exceeds ``MAX_STD`` [m] (10⁶ m, the wall estimators'
  bound on a LOS point's error, :data:`estimators.lsq.MAX_COORDINATE`: such a point says nothing about
  where its object is, and sums and squares of such variances overflow the filter);
* hidden velocities (``HiddenPoints.velocity``) faster than ``MAX_SPEED`` [m/s]
  (:data:`xnlos_core.motion.MAX_SPEED`, 1000 m/s) and velocity covariances as the position ones (not
  symmetric PSD, or σ above ``MAX_STD`` m/s);
* timestamps that are not finite, beyond ±``MAX_TIMESTAMP`` [s] (10¹⁰ s ≈ 317 years: Unix epoch
  seconds fit), that run back, or that follow the previous frame by less than
  ``MIN_FRAME_INTERVAL`` (1 µs: shorter than one chirp, so not two radar frames; a constant-velocity
  update dividing by it makes velocities that overflow the forecast). An equal timestamp (Δt = 0)
  stays allowed here; the sindy tracker refuses it itself.

NaN and inf cannot reach a tracker at all: :class:`xnlos_core.types.HiddenPoints` refuses them when
it is built and its arrays are read-only.
"""
from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field

from xnlos_core.errors import InputError
from xnlos_core.motion import MAX_SPEED
from xnlos_core.scene import MAX_COORD
from xnlos_core.types import HiddenPoints, Tracks

from ..lsq import MAX_COORDINATE

# The ``horizons`` parameter of every tracker: 1–64 forecast horizons [s], each within [0, 3] s
Horizons = Annotated[tuple[Annotated[float, Field(ge=0.0, le=3.0)], ...], Field(min_length=1, max_length=64)]
HORIZONS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
HORIZONS_DOC = "forecast horizons [s] ahead of each frame, each within [0, 3] s"

MAX_POSITION = MAX_COORD        # [m] largest |x|, |y| of a hidden point (module docstring)
MAX_STD = MAX_COORDINATE        # [m] or [m/s] largest standard deviation of a hidden point's position or velocity
MAX_TIMESTAMP = 1e10            # [s] largest |timestamp|
MIN_FRAME_INTERVAL = 1e-6       # [s] least Δt > 0 between two frames
SYMMETRY_RTOL = 1e-9            # |C01 − C10| allowed, relative to the larger variance
PSD_RTOL = 1e-9                 # least eigenvalue allowed: −PSD_RTOL × the largest


def frame_time(owner: str, points, timestamp, t_last: float | None) -> float:
    """``timestamp`` as a float [s] after checking ``points`` (HiddenPoints whose positions,
    velocities and covariances lie within the bounds of the module docstring) and the timestamp
    (finite, within ±MAX_TIMESTAMP, not before ``t_last``, and either equal to it or at least
    MIN_FRAME_INTERVAL after it). InputError naming ``owner``'s update, the input and its value."""
    if not isinstance(points, HiddenPoints):
        raise InputError(f"{owner}.update: expected HiddenPoints, got {type(points).__name__}")
    try:
        t = float(timestamp)
    except (TypeError, ValueError):
        raise InputError(f"{owner}.update: timestamp must be a number of seconds, got {timestamp!r}") from None
    if not np.isfinite(t):
        raise InputError(f"{owner}.update: timestamp must be finite, got {timestamp}")
    if abs(t) > MAX_TIMESTAMP:
        raise InputError(f"{owner}.update: timestamp {t:.6g} s lies beyond ±{MAX_TIMESTAMP:g} s (≈ 317 years); "
                         "expected seconds of a run or of the Unix epoch")
    if t_last is not None and t < t_last:
        raise InputError(f"{owner}.update: timestamp {t} s is before the previous frame's "
                         f"{t_last} s; timestamps must not decrease (call reset() to start over)")
    if t_last is not None and 0 < t - t_last < MIN_FRAME_INTERVAL:
        raise InputError(f"{owner}.update: timestamp {t!r} s follows the previous frame's {t_last!r} s by "
                         f"{t - t_last:.3g} s; frames must be at least {MIN_FRAME_INTERVAL:g} s apart "
                         "(or share a timestamp where the tracker allows it)")
    check_points(owner, points)
    return t


def check_points(owner: str, points: HiddenPoints) -> None:
    """InputError unless ``points`` lie within the bounds of the module docstring (positions,
    position covariances, velocities, velocity covariances)."""
    m = np.asarray(points.mean)
    far = np.flatnonzero(~(np.abs(m).max(axis=1) <= MAX_POSITION)) if len(m) else []  # NaN too (a bypassed type)
    if len(far):
        i = int(far[0])
        raise InputError(f"{owner}.update: points.mean[{i}] = {m[i].tolist()} m lies beyond ±{MAX_POSITION:g} m; "
                         f"expected finite |x|, |y| ≤ {MAX_POSITION:g} m (the scene bound, xnlos_core.scene.MAX_COORD); "
                         f"{len(far)} of {len(m)} hidden point(s) are not")
    check_covariances(f"{owner}.update: points.cov", points.cov, "m")
    if points.velocity is not None:
        v = np.asarray(points.velocity)
        speed = np.hypot(v[:, 0], v[:, 1]) if len(v) else np.empty(0)
        fast = np.flatnonzero(~(speed <= MAX_SPEED))
        if len(fast):
            i = int(fast[0])
            raise InputError(f"{owner}.update: points.velocity[{i}] = {v[i].tolist()} m/s has speed "
                             f"{speed[i]:.6g} m/s; expected finite and ≤ {MAX_SPEED:g} m/s (xnlos_core.motion.MAX_SPEED)")
        check_covariances(f"{owner}.update: points.velocity_cov", points.velocity_cov, "m/s")


def check_covariances(name: str, cov, unit: str) -> None:
    """InputError naming ``name`` unless every (2, 2) matrix of the finite ``cov`` (M, 2, 2) is
    symmetric (to SYMMETRY_RTOL), positive semi-definite (least eigenvalue ≥ −PSD_RTOL × the
    largest) and has σ = √λ_max ≤ MAX_STD [``unit``]."""
    c = np.asarray(cov, dtype=np.float64)
    if not len(c):
        return
    bad = np.flatnonzero(~np.all(np.isfinite(c), axis=(1, 2)))
    if len(bad):
        i = int(bad[0])
        raise InputError(f"{name}[{i}] = {c[i].tolist()}: expected finite values [{unit}²] ({len(bad)} of {len(c)} "
                         "hold NaN or inf)")
    scale = np.maximum(np.abs(c[:, 0, 0]), np.abs(c[:, 1, 1]))
    asym = np.flatnonzero(np.abs(c[:, 0, 1] - c[:, 1, 0]) > SYMMETRY_RTOL * scale)
    if len(asym):
        i = int(asym[0])
        raise InputError(f"{name}[{i}] = {c[i].tolist()} is not symmetric; expected a covariance matrix "
                         f"[{unit}²] ({len(asym)} of {len(c)} are not)")
    with np.errstate(over="ignore", invalid="ignore"):
        lam = np.linalg.eigvalsh(0.5 * (c + np.swapaxes(c, -1, -2)))  # LAPACK scales: no overflow for finite c
    neg = np.flatnonzero(lam[:, 0] < -PSD_RTOL * np.maximum(lam[:, 1], 0.0))
    if len(neg):
        i = int(neg[0])
        raise InputError(f"{name}[{i}] = {c[i].tolist()} has eigenvalues {lam[i].tolist()} [{unit}²]; expected "
                         f"a positive semi-definite covariance ({len(neg)} of {len(c)} are not)")
    big = np.flatnonzero(lam[:, 1] > MAX_STD ** 2)
    if len(big):
        i = int(big[0])
        raise InputError(f"{name}[{i}] has a standard deviation of {np.sqrt(lam[i, 1]):.6g} {unit} along its "
                         f"major axis; expected ≤ {MAX_STD:g} {unit} ({len(big)} of {len(c)} exceed it: such a "
                         "point says nothing about its object)")


def no_tracks(t: float) -> Tracks:
    """The empty Tracks at time ``t`` [s]."""
    e = np.empty((0, 2))
    return Tracks(np.empty(0, np.int64), e, e, e, t)
