"""Nearest-neighbour constant-velocity tracker of hidden objects.

Per frame at time t [s]:
1. The hidden points are grouped by single linkage (cut at ``cluster_distance`` [m]); each
   cluster's centroid is one measurement z (a car's several scatterers make one measurement).
2. Every live track predicts p̂ = p + v·(t − t_last). Measurements are assigned one-to-one by
   scipy.optimize.linear_sum_assignment on the Euclidean distances |p̂ − z|; pairs farther apart
   than ``gate`` [m] stay unassigned.
3. Matched tracks update with an α–β filter (residual r = z − p̂, Δt = t − t_last):
   p = p̂ + α r, v = v + (β/Δt) r. The second measurement of a track initialises the velocity by
   the finite difference v = (z − p_prev)/Δt. Unmatched measurements start new tracks (v = 0).
4. Unmatched tracks coast (p̂ kept) and are deleted after ``max_misses`` consecutive misses.

The reported ``predicted`` position is at t + Δt_frame, the last frame interval (0 on the first
frame). Timestamps must not decrease. Forecast: the CV mean p + v·h at each of ``horizons`` h [s],
model "cv"; the α–β filter keeps no covariance, so the interval radii are NaN.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.interfaces import Tracker
from xnlos_core.numerics import gated_assignment
from xnlos_core.types import HiddenPoints, Tracks

from ..lsq import single_linkage
from .frames import HORIZONS, HORIZONS_DOC, Horizons, frame_time
from estimators.state import FORMAT, StateReader, header


class NearestParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    gate: float = Field(3.0, gt=0, le=1e3, description="largest predicted-to-measured distance [m] of a match")
    max_misses: int = Field(3, ge=1, le=10_000, description="a track is deleted after this many consecutive "
                                                           "frames without a match")
    cluster_distance: float = Field(3.0, gt=0, le=1e3, description="single-linkage cut [m] grouping one "
                                                                   "frame's hidden points into objects (a car seen in part spans ≈ 4 m)")
    alpha: float = Field(0.5, gt=0, le=1, description="α–β filter position gain")
    beta: float = Field(0.17, ge=0, le=2, description="α–β filter velocity gain (Kalata's optimal pair "
                                                      "for α = 0.5: β = 2(2 − α) − 4√(1 − α) ≈ 0.17)")
    horizons: Horizons = Field(HORIZONS, description=HORIZONS_DOC)


@dataclass
class _Track:
    id: int
    position: np.ndarray
    velocity: np.ndarray
    t: float
    hits: int = 1
    misses: int = 0

    def predict(self, t: float) -> np.ndarray:
        return self.position + self.velocity * (t - self.t)


def cluster_centroids(points: np.ndarray, distance: float) -> np.ndarray:
    """Centroids (C, 2) [m] of the single-linkage clusters of ``points`` (N, 2)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return np.empty((0, 2))
    labels = single_linkage(pts, distance)
    counts = np.bincount(labels)
    sums = np.stack([np.bincount(labels, pts[:, 0]), np.bincount(labels, pts[:, 1])], axis=1)
    return sums / counts[:, None]


class NearestTracker(Tracker):
    """Constant-velocity tracks of clustered hidden points, Hungarian association within a gate."""

    Params = NearestParams

    def reset(self) -> None:
        """Forget all tracks; ids restart at 0."""
        self._tracks: list[_Track] = []
        self._next_id = 0
        self._t_last: float | None = None
        self._dt_frame = 0.0

    def update(self, points: HiddenPoints, timestamp: float) -> Tracks:
        """Ingest one frame's hidden points at ``timestamp`` [s]; return the live tracks."""
        if not hasattr(self, "_tracks"):
            self.reset()
        t = frame_time("NearestTracker", points, timestamp, self._t_last)
        z = cluster_centroids(points.mean, self.params.cluster_distance)
        pred = np.array([tr.predict(t) for tr in self._tracks]).reshape(-1, 2)
        matched_tr, matched_z = self._associate(pred, z)
        p = self.params
        for i, k in zip(matched_tr, matched_z):
            tr = self._tracks[i]
            dt = t - tr.t
            if tr.hits == 1 and dt > 0:
                tr.velocity = (z[k] - tr.position) / dt
                tr.position = z[k].copy()
            else:
                r = z[k] - pred[i]
                tr.position = pred[i] + p.alpha * r
                if dt > 0:
                    tr.velocity = tr.velocity + (p.beta / dt) * r
            tr.t, tr.hits, tr.misses = t, tr.hits + 1, 0
        unmatched = np.setdiff1d(np.arange(len(self._tracks)), matched_tr)
        for i in unmatched:
            self._tracks[i].misses += 1
        self._tracks = [tr for tr in self._tracks if tr.misses < p.max_misses]
        for k in np.setdiff1d(np.arange(len(z)), matched_z):
            self._tracks.append(_Track(self._next_id, z[k].copy(), np.zeros(2), t))
            self._next_id += 1
        if self._t_last is not None:
            self._dt_frame = t - self._t_last
        self._t_last = t
        return self._report(t)

    def state(self) -> dict:
        """Everything :meth:`update` carries to the next frame, JSON-able (:meth:`Tracker.state`):
        every track's position, velocity, time [s] and counters, the next id, the last time [s] and
        the last frame interval [s]."""
        if not hasattr(self, "_tracks"):
            self.reset()
        return {"tracker": type(self).__name__, "format": FORMAT, "next_id": self._next_id,
                "t_last": self._t_last, "dt_frame": self._dt_frame,
                "tracks": [{"id": tr.id, "position": tr.position.tolist(), "velocity": tr.velocity.tolist(),
                            "t": float(tr.t), "hits": tr.hits, "misses": tr.misses} for tr in self._tracks]}

    def load_state(self, state: dict) -> None:
        """Restore :meth:`state` (InputError naming the key for anything else; the tracker is then reset)."""
        self.reset()
        r = header(state, type(self).__name__)
        try:
            tracks = []
            for i, d in enumerate(r.items("tracks")):
                t = StateReader(d, f"{r.where}: tracks[{i}]")
                tracks.append(_Track(t.integer("id", 0), t.array("position", (2,)), t.array("velocity", (2,)),
                                     t.number("t"), t.integer("hits", 0), t.integer("misses", 0)))
            self._next_id, self._t_last = r.integer("next_id", 0), r.number("t_last", optional=True)
            self._dt_frame = r.number("dt_frame")
        except BaseException:
            self.reset()
            raise
        self._tracks = tracks

    def _associate(self, pred: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if len(pred) == 0 or len(z) == 0:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        d = np.hypot(*(pred[:, None, :] - z[None, :, :]).transpose(2, 0, 1))
        return gated_assignment(d, self.params.gate)  # ties up to rounding: the lower index (xnlos_core.numerics)

    def _report(self, t: float) -> Tracks:
        trs = self._tracks
        h = np.asarray(self.params.horizons, dtype=np.float64)
        pos = np.array([tr.predict(t) for tr in trs]).reshape(-1, 2)
        vel = np.array([tr.velocity for tr in trs]).reshape(-1, 2)
        nan = np.full((len(trs), len(h)), np.nan)
        ids = np.array([tr.id for tr in trs], dtype=np.int64)
        return Tracks(ids, pos, vel, pos + vel * self._dt_frame, t, h,
                      pos[:, None, :] + vel[:, None, :] * h[:, None], nan, nan, ("cv",) * len(trs))
