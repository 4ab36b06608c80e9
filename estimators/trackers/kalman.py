"""Constant-velocity Kalman tracker of hidden objects with gated Hungarian association.

Per frame at time t [s]:
1. The hidden points are grouped by single linkage (cut at ``cluster_distance`` [m]); each cluster
   gives one measurement z (2,) [m], its centroid (moved behind the seen side by ``depth_ratio``,
   :mod:`estimators.trackers.measurements`), with covariance R (2, 2) [m²] = Σ cov_i / n² from
   the points' ``HiddenPoints.cov`` (independent points) plus (``sigma_floor``² + ``extent_sigma``²) I; and, when the points
   carry velocities and ``use_doppler``, the radial velocity y = ĝᵀv along the mirrored line of sight ĝ
   with variance s (:mod:`estimators.trackers.measurements`).
2. Every track (state x = (p_x, p_y, v_x, v_y) [m, m/s], covariance P) predicts to t with the
   white-noise-acceleration model: F = [[I, Δt I], [0, I]], Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]]
   (q = ``accel_psd`` [m²/s³]).
3. Gating: the squared Mahalanobis distance d² = rᵀ S⁻¹ r of the innovation r = z − H x̂ with
   S = H P Hᵀ + R; pairs with d² above the χ²₂ quantile of ``gate_probability`` stay unassigned.
   The remaining pairs are assigned one-to-one by scipy.optimize.linear_sum_assignment on d².
4. Matched tracks take the Kalman update (Joseph form) with H = [I, 0] and R, or with Doppler the
   extended H = [[I, 0], [0, ĝᵀ]] (3, 4), measurement (z, y) and R ⊕ s — with ``doppler_rows = "wall"``
   one row ĝ_gᵀ per relay wall the object's points were mirrored through (measurements.py: two walls
   give two components of the velocity). Unmatched measurements start
   tentative tracks from the prior p = z, v = 0, P = diag(R, ``initial_speed_sigma``² I), which the
   Doppler row (if any) then updates: a new track starts with its radial velocity.
5. Birth: a tentative track is confirmed once it has ``confirm_hits`` (M) hits within its first
   ``confirm_window`` (N) frames, else deleted. Death: a confirmed track is deleted after
   ``max_misses`` (K) consecutive misses — or, with ``lost_frames`` L > 0, it is first *lost* for up to
   L further frames: it keeps predicting but is not reported, and is offered only the measurements
   the other tracks leave (step 3 runs first over the tracks with fewer than K misses, then over the
   lost ones: a lost track's grown covariance gives it small Mahalanobis distances, which must not
   take a measurement from a track that holds its object). A match revives it — id, state, history —
   where the detector's misses would otherwise end a track and start a new one without velocity (the
   lost-track buffer of ByteTrack, Zhang et al., ECCV 2022). The revived track is tentative again and is
   reported once it has M hits within N frames anew (else deleted): a lone false alarm near a lost
   track's prediction would otherwise bring it back unconfirmed.

Only confirmed tracks with fewer than K misses are reported; ``predicted`` is the position at
t + Δt_frame, the last frame interval (0 on the first frame). Timestamps must not decrease (a repeated
timestamp is a second measurement at the same instant, Δt = 0). A frame without points is valid: tracks coast (predict only).

Forecast (every report, :mod:`estimators.trackers.forecast`): at each of ``horizons`` h [s] the mean
p + v h and the covariance F(h) P F(h)ᵀ + Q(h) (position block) of the object's true position (no
measurement noise: the discs are to hold the object's centre), with the exact 50 %/90 % disc radii of
that Gaussian; model "cv". ``accel_psd`` is calibrated for that (``benchmarks/forecast_calibration.py``):
its 90 % discs hold 85–95 % of straight-driving cars; a turning or braking car breaks the CV model and
is under-covered (the CV baseline). With a ``region`` polygon, the time-to-appearance
(:mod:`estimators.trackers.region`) from the mean path and ``arrival_draws`` seeded path draws.
Subclasses change the motion model per track through :meth:`KalmanTracker._motion`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from xnlos_core.interfaces import Tracker
from xnlos_core.numerics import gated_assignment
from xnlos_core.types import HiddenPoints, Tracks

from . import forecast as fc
from .frames import HORIZONS, HORIZONS_DOC, Horizons, frame_time, no_tracks
from .measurements import Measurements, cluster
from .region import Region, arrival
from estimators.state import FORMAT, StateReader, header

H = np.hstack([np.eye(2), np.zeros((2, 2))])
CV = fc.LinearMotion()
ARRIVAL_HORIZON = 3.0  # [s]
Scale = Annotated[float, Field(gt=0, le=100)]  # a factor on a disc radius
ACCEL_PSD = 0.75  # [m²/s³] calibrated default of accel_psd (benchmarks/forecast_calibration.py)


@lru_cache(maxsize=8)
def chi2_1_ppf(p: float) -> float:
    """The p-quantile of χ² with 1 degree of freedom, the squared (1 + p)/2-quantile of the standard
    normal (statistics.NormalDist: no scipy.stats import, see :func:`chi2_2_ppf`)."""
    from statistics import NormalDist

    return NormalDist().inv_cdf((1.0 + p) / 2.0) ** 2


def chi2_2_ppf(p: float) -> float:
    """The p-quantile of χ² with 2 degrees of freedom: −2 ln(1 − p) (its CDF is 1 − e^(−x/2)), in closed
    form rather than scipy.stats.chi2.ppf, whose import (~0.2 s) every `xnlos` start would pay."""
    return float(-2.0 * np.log1p(-p))


class KalmanParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    accel_psd: float = Field(ACCEL_PSD, gt=0, le=1e4, description="power spectral density q [m²/s³] of the white "
                                                                  "acceleration noise of the constant-velocity model "
                                                                  "(filter and forecast); the default is calibrated by "
                                                                  "benchmarks/forecast_calibration.py (90 % discs hold "
                                                                  "≈ 90 % of straight-driving cars)")
    gate_probability: float = Field(0.999, gt=0, lt=1, description="a measurement is gated in when its squared "
                                                                   "Mahalanobis distance is below this χ²₂ quantile")
    confirm_hits: int = Field(2, ge=1, le=1000, description="M: hits needed to confirm a tentative track")
    confirm_window: int = Field(3, ge=1, le=1000, description="N: frames since birth within which a tentative "
                                                              "track must collect M hits, else it is deleted")
    max_misses: int = Field(3, ge=1, le=10_000, description="K: a confirmed track is no longer reported after "
                                                           "this many consecutive frames without a match (and is "
                                                           "deleted, unless lost_frames keeps it)")
    lost_frames: int = Field(0, ge=0, le=10_000, description="L: frames a confirmed track that has missed K frames "
                                                             "is kept lost (predicted, offered the measurements the "
                                                             "reported tracks leave, not reported) before it is "
                                                             "deleted; a match revives it with its id, state and "
                                                             "history, tentative until M of N hits again. 0: "
                                                             "deleted at K misses")
    cluster_distance: float = Field(5.0, gt=0, le=1e3, description="single-linkage cut [m] grouping one frame's "
                                                                   "hidden points into objects (the scatterers seen on a "
                                                                   "4.5 m car lie up to ≈ 4.8 m apart)")
    sigma_floor: float = Field(0.05, gt=0, le=100, description="standard deviation [m] added per axis to each "
                                                              "measurement's covariance (keeps S invertible for exact points)")
    extent_sigma: float = Field(1.0, ge=0, le=100, description="standard deviation [m] per axis of an object's "
                                                              "cluster centroid about its centre: which scatterers of an "
                                                              "extended object are seen changes from frame to frame "
                                                              "(≈ L/√12 = 1.3 m along a car of length L = 4.5 m)")
    depth_ratio: float = Field(0.2, ge=0, le=1, description="an object's centre lies behind the centroid of its "
                                                          "seen points, along their mirrored line of sight, by this "
                                                          "times their span across it (measurements.py: W/(2L) = 0.2 "
                                                          "for a car seen broadside; val split of the sequence data); "
                                                          "0: the centroid. Needs HiddenPoints.view")
    initial_speed_sigma: float = Field(10.0, gt=0, le=1e3, description="prior standard deviation [m/s] per axis of "
                                                                       "a new track's velocity (it starts at 0)")

    use_doppler: bool = Field(True, description="use the hidden points' radial velocities in the update "
                                                "(ignored when the points carry none)")
    doppler_floor: float = Field(0.1, gt=0, le=100, description="standard deviation [m/s] added to each "
                                                               "point's radial-velocity error")
    doppler_rows: Literal["cluster", "wall"] = Field("cluster", description="Doppler rows of an object's update: "
                                                     "'cluster', one radial velocity along the points' mean line "
                                                     "of sight; 'wall', one per relay wall its points were "
                                                     "mirrored through (measurements.py: two walls see two "
                                                     "components of the velocity)")
    doppler_gate: float | None = Field(None, gt=0, lt=1, description="a matched track leaves out a Doppler row "
                                       "whose squared normalised innovation (y − ĝᵀv)²/(ĝᵀP_vĝ + s) exceeds this "
                                       "χ²₁ quantile (e.g. 0.999); None: every row is used")
    interval_scale: tuple[Scale, Scale] = Field((1.0, 1.0), description="factors on the 50 % and 90 % disc radii "
                                                "of the forecast (a conformal calibration on held-out sequences: "
                                                "benchmarks/interval_calibration.py; 1: the Gaussian's own radii)")
    horizons: Horizons = Field(HORIZONS, description=HORIZONS_DOC)
    region: list[tuple[float, float]] | None = Field(None, description="polygon [[x, y], …] [m] in the ego "
                                                                       "frame (e.g. the ego lane) whose "
                                                                       "time-to-appearance is reported; None: none")
    arrival_step: float = Field(0.1, gt=0, le=1.0, description="time step [s] of the predicted paths "
                                                               "searched for the region entry")
    arrival_draws: int = Field(100, ge=20, le=100_000, description="predictive path draws for the "
                                                                   "arrival interval")
    seed: int = Field(0, ge=0, description="seed of the arrival draws (with the frame index)")

    @field_validator("region")
    @classmethod
    def _region_is_polygon(cls, v):
        if v is not None:
            Region(v)  # InputError (a ValueError) for fewer than 3 vertices, non-finite or zero area
        return v

    @model_validator(mode="after")
    def _window_holds_hits(self):
        if self.confirm_hits > self.confirm_window:
            raise ValueError(f"confirm_hits ({self.confirm_hits}) must be ≤ confirm_window ({self.confirm_window})")
        return self


@dataclass
class KalmanTrack:
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


def solve_psd(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """S⁻¹B for symmetric positive semi-definite S (…, n, n) and B (…, n, k).

    A finite S can be exactly singular: an exact point (zero covariance) with a ``sigma_floor`` whose
    square underflows, or a rank-one point covariance on a zero-variance track axis. Then every S of
    the batch gets a ridge of 10⁻¹² times its mean variance (at least the smallest normal float),
    S + εI: a residual along a zero-variance direction counts as (nearly) infinitely unlikely instead
    of stopping the tracker with numpy's LinAlgError. Non-singular batches are solved exactly as before."""
    try:
        return np.linalg.solve(S, B)
    except np.linalg.LinAlgError:
        n = S.shape[-1]
        eps = np.maximum(1e-12 * np.trace(S, axis1=-2, axis2=-1) / n, np.finfo(np.float64).tiny)
        return np.linalg.solve(S + eps[..., None, None] * np.eye(n), B)


def cluster_measurements(points: HiddenPoints, distance: float, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster centroids z (C, 2) [m] and their covariances R (C, 2, 2) [m²] (see module docstring)."""
    m = cluster(points, distance, floor, use_doppler=False)
    return m.z, m.R


class KalmanTracker(Tracker):
    """Constant-velocity Kalman tracks, Mahalanobis-gated Hungarian association, M-of-N birth, K-miss death."""

    Params = KalmanParams

    def reset(self) -> None:
        """Forget all tracks; ids restart at 0."""
        self._tracks: list[KalmanTrack] = []
        self._next_id = 0
        self._t_last: float | None = None
        self._dt_frame = 0.0
        self._frame = 0
        self._region = None if self.params.region is None else Region(self.params.region)

    def update(self, points: HiddenPoints, timestamp: float) -> Tracks:
        """Ingest one frame's hidden points at ``timestamp`` [s]; return the confirmed tracks."""
        if not hasattr(self, "_tracks"):
            self.reset()
        t = self._frame_time(points, timestamp)
        p = self.params
        meas = cluster(points, p.cluster_distance, float(np.hypot(p.sigma_floor, p.extent_sigma)), p.doppler_floor,
                       p.use_doppler, type(self).__name__, p.depth_ratio, p.doppler_rows)
        z, R = meas.z, meas.R
        for tr in self._tracks:
            dt = t - tr.t
            F = self._motion(tr).transition(dt)
            Q = fc.cv_process_noise(dt, p.accel_psd)
            tr.x, tr.P, tr.t, tr.frames = F @ tr.x, F @ tr.P @ F.T + Q, t, tr.frames + 1
        is_lost = np.array([self._lost(tr) for tr in self._tracks], bool)
        rows, cols = self._associate(z, R, np.flatnonzero(~is_lost))
        lost = np.flatnonzero(is_lost)
        if len(lost):  # the lost tracks are offered what the held ones leave (step 5)
            left = np.setdiff1d(np.arange(len(z)), cols)
            lost_rows, lost_cols = self._associate(z[left], R[left], lost)
            rows, cols = np.r_[rows, lost_rows], np.r_[cols, left[lost_cols]]
        for i, k in zip(rows, cols):
            self._correct(self._tracks[i], meas, k)
        for i in np.setdiff1d(np.arange(len(self._tracks)), rows):
            self._tracks[i].misses += 1
        for tr in self._tracks:
            tr.confirmed = tr.confirmed or tr.hits >= p.confirm_hits
        self._tracks = [tr for tr in self._tracks if self._alive(tr)]
        for k in np.setdiff1d(np.arange(len(z)), cols):
            P0 = np.zeros((4, 4))
            P0[:2, :2], P0[2:, 2:] = R[k], p.initial_speed_sigma ** 2 * np.eye(2)
            tr = self._new_track(self._next_id, np.r_[z[k], 0.0, 0.0], P0, t)
            if meas.doppler[k]:
                self._filter(tr, meas, k, position=False)
            tr.confirmed = p.confirm_hits == 1
            self._tracks.append(tr)
            self._next_id += 1
        if self._t_last is not None:
            self._dt_frame = t - self._t_last
        self._t_last = t
        self._after_update(t)
        self._frame += 1
        return self._report(t)

    def state(self) -> dict:
        """Everything :meth:`update` carries to the next frame, JSON-able (:meth:`Tracker.state`):
        every track (tentative ones too) with x (4,), P (4, 4), t [s], counters; the next id, the last
        time [s], the last frame interval [s] and the frame counter (it seeds the arrival draws)."""
        if not hasattr(self, "_tracks"):
            self.reset()
        return {"tracker": type(self).__name__, "format": FORMAT, "next_id": self._next_id,
                "t_last": self._t_last, "dt_frame": self._dt_frame, "frame": self._frame,
                "tracks": [self._track_state(tr) for tr in self._tracks]}

    def load_state(self, state: dict) -> None:
        """Restore :meth:`state` (InputError naming the key for anything else; the tracker is then reset)."""
        self.reset()
        r = header(state, type(self).__name__)
        try:
            tracks = [self._track_from(StateReader(d, f"{r.where}: tracks[{i}]"))
                      for i, d in enumerate(r.items("tracks"))]
            self._next_id, self._t_last = r.integer("next_id", 0), r.number("t_last", optional=True)
            self._dt_frame, self._frame = r.number("dt_frame"), r.integer("frame", 0)
        except BaseException:
            self.reset()
            raise
        self._tracks = tracks

    def _track_state(self, tr: KalmanTrack) -> dict:
        return {"id": tr.id, "x": tr.x.tolist(), "P": tr.P.tolist(), "t": float(tr.t), "frames": tr.frames,
                "hits": tr.hits, "misses": tr.misses, "confirmed": bool(tr.confirmed)}

    def _track_from(self, r: StateReader) -> KalmanTrack:
        return KalmanTrack(r.integer("id", 0), r.array("x", (4,)), r.array("P", (4, 4)), r.number("t"),
                      r.integer("frames", 0), r.integer("hits", 0), r.integer("misses", 0), r.flag("confirmed"))

    # hooks for subclasses (the sindy tracker): time checks, track records, per-track motion model
    def _frame_time(self, points, timestamp) -> float:
        return frame_time(type(self).__name__, points, timestamp, self._t_last)

    def _new_track(self, track_id: int, x: np.ndarray, P: np.ndarray, t: float) -> KalmanTrack:
        return KalmanTrack(track_id, x, P, t)

    def _motion(self, tr: KalmanTrack) -> fc.LinearMotion:
        """The motion model that track ``tr`` predicts and forecasts with (CV here)."""
        return CV

    def _forecast_psd(self, tr: KalmanTrack) -> float:
        """Process-noise PSD q [m²/s³] of track ``tr``'s forecast and arrival draws (``accel_psd`` here)."""
        return self.params.accel_psd

    def _interval_scale(self, tr: KalmanTrack) -> tuple[float, float]:
        """Factors on track ``tr``'s 50 % and 90 % disc radii (``interval_scale`` here)."""
        return self.params.interval_scale

    def _spread(self, tr: KalmanTrack) -> float:
        """Scale of the members' spread in the forecast, Eq. (1) of :mod:`estimators.trackers.forecast`."""
        return 1.0

    def _forecast(self, tr: KalmanTrack, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Track ``tr``'s forecast mean (K, 2) [m] and covariance (K, 2, 2) [m²] at horizons h (K,) [s]
        (:func:`estimators.trackers.forecast.forecast` of its motion model here)."""
        return fc.forecast(self._motion(tr), tr.x, tr.P, h, self._forecast_psd(tr), self._spread(tr))

    def _forecasts(self, trs: list, h: np.ndarray) -> list:
        """[(mean, covariance)] of :meth:`_forecast` for the tracks ``trs`` (a subclass may batch them)."""
        return [self._forecast(tr, h) for tr in trs]

    def _label(self, tr: KalmanTrack) -> str:
        """The motion model reported for track ``tr`` (its motion's label here)."""
        return self._motion(tr).label

    def _after_update(self, t: float) -> None:
        """Called once per frame after association, updates, births and deaths."""

    def _alive(self, tr: KalmanTrack) -> bool:
        if tr.confirmed:
            return tr.misses < self.params.max_misses + self.params.lost_frames
        return tr.hits + self.params.confirm_window - tr.frames >= self.params.confirm_hits  # M still reachable

    def _lost(self, tr: KalmanTrack) -> bool:
        """Whether ``tr`` is lost: confirmed, with ``max_misses`` misses or more (module docstring, 5)."""
        return tr.confirmed and tr.misses >= self.params.max_misses

    def _associate(self, z: np.ndarray, R: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gated Hungarian assignment (module docstring, 3) of the tracks ``which`` (indices into the track
        list) to the measurements z (C, 2), R (C, 2, 2): matched track indices and measurement indices."""
        if len(which) == 0 or len(z) == 0:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        x = np.array([self._tracks[i].x for i in which])
        P = np.array([self._tracks[i].P for i in which])
        r = z[None, :, :] - x[:, None, :2]                       # (T, C, 2)
        S = P[:, None, :2, :2] + R[None, :, :, :]                # (T, C, 2, 2)
        d2 = np.einsum("tci,tci->tc", r, solve_psd(S, r[..., None])[..., 0])
        rows, cols = gated_assignment(d2, chi2_2_ppf(self.params.gate_probability))  # ties: the lower index
        return which[rows], cols

    def _correct(self, tr: KalmanTrack, meas: Measurements, k: int) -> None:
        gate = self.params.doppler_gate
        if self._lost(tr):  # revived: tentative again, confirmed anew by M of N (module docstring, 5)
            tr.confirmed, tr.hits, tr.frames = False, 0, 1
        self._filter(tr, meas, k, position=True, gate=None if gate is None else chi2_1_ppf(gate))
        tr.hits, tr.misses = tr.hits + 1, 0

    @staticmethod
    def _filter(tr: KalmanTrack, meas: Measurements, k: int, position: bool, gate: float | None = None) -> None:
        """Joseph-form Kalman update of ``tr`` with measurement ``k``: its position row(s) when
        ``position``, its Doppler row y = ĝᵀv when it has one (H = [[I, 0], [0, ĝᵀ]]); a Doppler row whose
        squared normalised innovation exceeds ``gate`` (a χ²₁ quantile, None: no gate) is left out."""
        rows, z, r = [], [], []
        if position:
            rows.append(H), z.append(meas.z[k]), r.append(np.diag(meas.R[k]))
        for j in np.flatnonzero(np.isfinite(meas.rows_s[k])):  # the Doppler row(s): one, or one per relay wall
            g = meas.rows_g[k, j]
            if gate is not None and (meas.rows_y[k, j] - g @ tr.x[2:]) ** 2 > gate * (g @ tr.P[2:, 2:] @ g + meas.rows_s[k, j]):
                continue
            rows.append(np.r_[0.0, 0.0, g][None]), z.append(meas.rows_y[k, j:j + 1])
            r.append(meas.rows_s[k, j:j + 1])
        if not rows:
            return
        Hx, zx = np.vstack(rows), np.concatenate(z)
        Rx = np.diag(np.concatenate(r))
        if position:
            Rx[:2, :2] = meas.R[k]
        S = Hx @ tr.P @ Hx.T + Rx
        K = solve_psd(S, Hx @ tr.P).T
        IKH = np.eye(4) - K @ Hx
        tr.x = tr.x + K @ (zx - Hx @ tr.x)
        tr.P = IKH @ tr.P @ IKH.T + K @ Rx @ K.T

    def _report(self, t: float) -> Tracks:
        trs = [tr for tr in self._tracks if tr.confirmed and not self._lost(tr)]
        h = np.asarray(self.params.horizons, dtype=np.float64)
        if not trs:
            e = no_tracks(t)
            extra = {"arrival": np.empty(0), "arrival_interval": np.empty((0, 2))} if self._region else {}
            return Tracks(e.track_id, e.position, e.velocity, e.predicted, t, h, np.empty((0, len(h), 2)),
                          np.empty((0, len(h))), np.empty((0, len(h))), (), **extra)
        x = np.array([tr.x for tr in trs])
        pos, vel = x[:, :2], x[:, 2:]
        fcs = self._forecasts(trs, h)
        mean = np.array([m for m, _ in fcs])
        r50, r90 = fc.radii(np.array([c for _, c in fcs]))
        scale = np.array([self._interval_scale(tr) for tr in trs])  # (T, 2)
        r50, r90 = r50 * scale[:, :1], r90 * scale[:, 1:]
        labels = tuple(self._label(tr) for tr in trs)
        pred = np.array([self._motion(tr).transition(self._dt_frame)[:2] @ tr.x for tr in trs])
        extra = self._arrivals(trs, t) if self._region else {}
        return Tracks(np.array([tr.id for tr in trs]), pos, vel, pred, t, h, mean, r50, r90, labels, **extra)

    def _arrivals(self, trs: list[KalmanTrack], t: float) -> dict:
        """Time-to-appearance of each track in the region (module docstring; seeded by seed and frame)."""
        p = self.params
        n = int(round(ARRIVAL_HORIZON / p.arrival_step)) + 1
        rng = np.random.default_rng([p.seed, self._frame])
        out, interval = np.empty(len(trs)), np.empty((len(trs), 2))
        for i, tr in enumerate(trs):
            motion = self._motion(tr)
            mean = fc.mean_path(motion, tr.x, p.arrival_step, n)
            draws = fc.draw_paths(motion, tr.x, tr.P, p.arrival_step, n, self._forecast_psd(tr), p.arrival_draws, rng)
            out[i], interval[i] = arrival(self._region, mean, draws, p.arrival_step, t)
        return {"arrival": out, "arrival_interval": interval}
