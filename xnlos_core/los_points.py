"""Line-of-sight detections → points a tracker takes, for pipelines without a reconstructor.

A tracker (:class:`xnlos_core.interfaces.Tracker`) takes one frame's points with covariances and,
where known, the component of their velocity along a line of sight. A reconstructor gives it
hidden points (mNLOS detections mirrored across a relay wall); a road user in plain view is
already where its detection says, so without a reconstructor the pipeline hands the tracker its
line-of-sight detections directly, as :func:`detection_points` converts them:

* position p = (r cos θ, r sin θ) [m] (:func:`xnlos_core.geometry.polar_to_cartesian`);
* covariance by first-order propagation of the polar errors, Σ = J·diag(σ_r², σ_θ²)·Jᵀ [m²] with
  J = ∂p/∂(r, θ) = [[cos θ, −r sin θ], [sin θ, r cos θ]]: σ_r along the line of sight, r·σ_θ across it;
* radial velocity v_r [m/s] (Doppler, positive receding) as the observed velocity component
  w = v_r·û along the line of sight û = (cos θ, sin θ), with covariance σ_v²·ûûᵀ [m²/s²]: the
  convention of a reconstructor's hidden points (the measurement row ĝ = û, y = v_r of
  :mod:`estimators.trackers.measurements`);
* view direction û (the radar sees the object from the origin: its centre lies behind the points);
* source_index the detection's row; wall_index 0 (no wall).

mNLOS detections are left out: they are virtual images behind a relay wall, not where an object is.
LOS and unclassified ones (a plain CFAR labels every peak unclassified) are taken.
"""
from __future__ import annotations

import numpy as np

from .geometry import polar_to_cartesian
from .types import MNLOS, Detections, HiddenPoints


def detection_points(detections: Detections) -> HiddenPoints:
    """The line-of-sight points of ``detections`` (every row not labelled mNLOS) as
    :class:`HiddenPoints` (module doc): mean (M, 2) [m], cov (M, 2, 2) [m²], source_index (M,) the
    detection rows, wall_index zeros, view (M, 2) unit line-of-sight directions, and velocity (M, 2)
    [m/s] / velocity_cov (M, 2, 2) [m²/s²] when the detections carry radial velocity."""
    rows = np.flatnonzero(detections.label != MNLOS)
    r = np.asarray(detections.range, np.float64)[rows]
    th = np.asarray(detections.azimuth, np.float64)[rows]
    sr = np.asarray(detections.range_std, np.float64)[rows]
    sa = np.asarray(detections.azimuth_std, np.float64)[rows]
    c, s = np.cos(th), np.sin(th)
    u = np.stack([c, s], axis=1)                      # along the line of sight
    n = np.stack([-s, c], axis=1)                     # across it
    cov = (sr**2)[:, None, None] * u[:, :, None] * u[:, None, :] + \
        ((r * sa) ** 2)[:, None, None] * n[:, :, None] * n[:, None, :]
    velocity = velocity_cov = None
    if detections.velocity is not None:
        v = np.asarray(detections.velocity, np.float64)[rows]
        var = np.asarray(detections.velocity_var, np.float64)[rows]
        velocity = v[:, None] * u
        velocity_cov = var[:, None, None] * u[:, :, None] * u[:, None, :]
    return HiddenPoints(polar_to_cartesian(r, th).reshape(-1, 2), cov.reshape(-1, 2, 2), rows.astype(np.int64),
                        np.zeros(len(rows), np.int64), velocity=velocity, velocity_cov=velocity_cov,
                        view=u.reshape(-1, 2))
