"""Constant-velocity Kalman tracker of hidden objects with gated Hungarian association.

Per frame at time t [s]:
1. The hidden points are grouped by single linkage (cut at ``cluster_distance`` [m]); each cluster
   gives one measurement z (2,) [m], its centroid, with covariance R (2, 2) [m²] = Σ cov_i / n² from
   the points' ``HiddenPoints.cov`` (independent points) plus ``sigma_floor``² I.
2. Every track (state x = (p_x, p_y, v_x, v_y) [m, m/s], covariance P) predicts to t with the
   white-noise-acceleration model: F = [[I, Δt I], [0, I]], Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]]
   (q = ``accel_psd`` [m²/s³]).
3. Gating: the squared Mahalanobis distance d² = rᵀ S⁻¹ r of the innovation r = z − H x̂ with
   S = H P Hᵀ + R; pairs with d² above the χ²₂ quantile of ``gate_probability`` stay unassigned.
   The remaining pairs are assigned one-to-one by scipy.optimize.linear_sum_assignment on d².
4. Matched tracks take the Kalman update (Joseph form). Unmatched measurements start tentative
   tracks at p = z, v = 0 with P = diag(R, ``initial_speed_sigma``² I).
5. Birth: a tentative track is confirmed once it has ``confirm_hits`` (M) hits within its first
   ``confirm_window`` (N) frames, else deleted. Death: a confirmed track is deleted after
   ``max_misses`` (K) consecutive misses.

Only confirmed tracks are reported; ``predicted`` is the position at t + Δt_frame, the last frame
interval (0 on the first frame). Timestamps must not decrease.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from xnlos_core.interfaces import Tracker
from xnlos_core.types import HiddenPoints, Tracks

from ..lsq import single_linkage
from .frames import frame_time, no_tracks

H = np.hstack([np.eye(2), np.zeros((2, 2))])


class KalmanParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    accel_psd: float = Field(4.0, gt=0, le=1e4, description="power spectral density q [m²/s³] of the white "
                                                            "acceleration noise of the constant-velocity model")
    gate_probability: float = Field(0.999, gt=0, lt=1, description="a measurement is gated in when its squared "
                                                                   "Mahalanobis distance is below this χ²₂ quantile")
    confirm_hits: int = Field(2, ge=1, le=1000, description="M: hits needed to confirm a tentative track")
    confirm_window: int = Field(3, ge=1, le=1000, description="N: frames since birth within which a tentative "
                                                              "track must collect M hits, else it is deleted")
    max_misses: int = Field(3, ge=1, le=10_000, description="K: a confirmed track is deleted after this many "
                                                           "consecutive frames without a match")
    cluster_distance: float = Field(3.0, gt=0, le=1e3, description="single-linkage cut [m] grouping one frame's "
                                                                   "hidden points into objects (a car seen in part spans ≈ 4 m)")
    sigma_floor: float = Field(0.05, gt=0, le=100, description="standard deviation [m] added per axis to each "
                                                              "measurement's covariance (keeps S invertible for exact points)")
    initial_speed_sigma: float = Field(10.0, gt=0, le=1e3, description="prior standard deviation [m/s] per axis of "
                                                                       "a new track's velocity (it starts at 0)")

    @model_validator(mode="after")
    def _window_holds_hits(self):
        if self.confirm_hits > self.confirm_window:
            raise ValueError(f"confirm_hits ({self.confirm_hits}) must be ≤ confirm_window ({self.confirm_window})")
        return self


@dataclass
class _Track:
    id: int
    x: np.ndarray            # (4,) state [m, m, m/s, m/s]
    P: np.ndarray            # (4, 4) covariance
    t: float                 # time [s] of x
    frames: int = 1          # frames since birth, birth frame included
    hits: int = 1
    misses: int = 0
    confirmed: bool = False


def cv_transition(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """F (4, 4) and Q (4, 4) of the white-noise-acceleration model over ``dt`` [s], PSD ``q`` [m²/s³]."""
    eye = np.eye(2)
    F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
    Q = q * np.block([[dt ** 3 / 3 * eye, dt ** 2 / 2 * eye], [dt ** 2 / 2 * eye, dt * eye]])
    return F, Q


def cluster_measurements(points: HiddenPoints, distance: float, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster centroids z (C, 2) [m] and their covariances R (C, 2, 2) [m²] (see module docstring)."""
    if len(points) == 0:
        return np.empty((0, 2)), np.empty((0, 2, 2))
    labels = single_linkage(np.asarray(points.mean, np.float64), distance)
    n = np.bincount(labels).astype(np.float64)
    z = np.stack([np.bincount(labels, points.mean[:, 0]), np.bincount(labels, points.mean[:, 1])], axis=1) / n[:, None]
    R = np.zeros((len(n), 2, 2))
    np.add.at(R, labels, points.cov)
    return z, R / n[:, None, None] ** 2 + floor ** 2 * np.eye(2)


class KalmanTracker(Tracker):
    """Constant-velocity Kalman tracks, Mahalanobis-gated Hungarian association, M-of-N birth, K-miss death."""

    Params = KalmanParams

    def reset(self) -> None:
        """Forget all tracks; ids restart at 0."""
        self._tracks: list[_Track] = []
        self._next_id = 0
        self._t_last: float | None = None
        self._dt_frame = 0.0

    def update(self, points: HiddenPoints, timestamp: float) -> Tracks:
        """Ingest one frame's hidden points at ``timestamp`` [s]; return the confirmed tracks."""
        if not hasattr(self, "_tracks"):
            self.reset()
        t = frame_time("KalmanTracker", points, timestamp, self._t_last)
        p = self.params
        z, R = cluster_measurements(points, p.cluster_distance, p.sigma_floor)
        for tr in self._tracks:
            F, Q = cv_transition(t - tr.t, p.accel_psd)
            tr.x, tr.P, tr.t, tr.frames = F @ tr.x, F @ tr.P @ F.T + Q, t, tr.frames + 1
        rows, cols = self._associate(z, R)
        for i, k in zip(rows, cols):
            self._correct(self._tracks[i], z[k], R[k])
        for i in np.setdiff1d(np.arange(len(self._tracks)), rows):
            self._tracks[i].misses += 1
        for tr in self._tracks:
            tr.confirmed = tr.confirmed or tr.hits >= p.confirm_hits
        self._tracks = [tr for tr in self._tracks if self._alive(tr)]
        for k in np.setdiff1d(np.arange(len(z)), cols):
            P0 = np.zeros((4, 4))
            P0[:2, :2], P0[2:, 2:] = R[k], p.initial_speed_sigma ** 2 * np.eye(2)
            tr = _Track(self._next_id, np.r_[z[k], 0.0, 0.0], P0, t)
            tr.confirmed = p.confirm_hits == 1
            self._tracks.append(tr)
            self._next_id += 1
        if self._t_last is not None:
            self._dt_frame = t - self._t_last
        self._t_last = t
        return self._report(t)

    def _alive(self, tr: _Track) -> bool:
        if tr.confirmed:
            return tr.misses < self.params.max_misses
        return tr.hits + self.params.confirm_window - tr.frames >= self.params.confirm_hits  # M still reachable

    def _associate(self, z: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if not self._tracks or len(z) == 0:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        x = np.array([tr.x for tr in self._tracks])
        P = np.array([tr.P for tr in self._tracks])
        r = z[None, :, :] - x[:, None, :2]                       # (T, C, 2)
        S = P[:, None, :2, :2] + R[None, :, :, :]                # (T, C, 2, 2)
        d2 = np.einsum("tci,tci->tc", r, np.linalg.solve(S, r[..., None])[..., 0])
        gate = chi2.ppf(self.params.gate_probability, df=2)
        big = gate * (min(d2.shape) + 1)  # any gated match beats all out-of-gate ones
        rows, cols = linear_sum_assignment(np.where(d2 <= gate, d2, big))
        ok = d2[rows, cols] <= gate
        return rows[ok], cols[ok]

    def _correct(self, tr: _Track, z: np.ndarray, R: np.ndarray) -> None:
        S = H @ tr.P @ H.T + R
        K = np.linalg.solve(S, H @ tr.P).T
        IKH = np.eye(4) - K @ H
        tr.x = tr.x + K @ (z - H @ tr.x)
        tr.P = IKH @ tr.P @ IKH.T + K @ R @ K.T
        tr.hits, tr.misses = tr.hits + 1, 0

    def _report(self, t: float) -> Tracks:
        trs = [tr for tr in self._tracks if tr.confirmed]
        if not trs:
            return no_tracks(t)
        x = np.array([tr.x for tr in trs])
        pos, vel = x[:, :2], x[:, 2:]
        return Tracks(np.array([tr.id for tr in trs]), pos, vel, pos + vel * self._dt_frame, t)
